#!/usr/bin/env node
// Independent reference for ipfn's SIFID features: runs the *Keras* model from the nsfwjs
// tarball with TensorFlow.js (which reads and dequantizes the weights itself, so none of
// convert.js or ipfn's code is involved), cut at activation_5 (Conv2d_4a_3x3 + BN + ReLU), on
// fixed crops of the shipped exemplars. Writes one .npy of features per input into OUT_DIR;
// reference.py turns them into tests/data/sifid/expected.json. See README.md here.
//
//   npm ci && node reference.js nsfwjs-4.4.0.tgz /tmp/sifid-ref
'use strict';
const fs = require('fs');
const os = require('os');
const path = require('path');
const { execFileSync } = require('child_process');
const tf = require('@tensorflow/tfjs');
const { PNG } = require('pngjs');

// The fixed inputs: name, file (relative to the repository root), top-left x, y, size.
const INPUTS = [
  ['honeycomb_a', 'exemplars/honeycomb.png', 0, 0, 128],
  ['honeycomb_b', 'exemplars/honeycomb.png', 128, 96, 128],
  ['bricks', 'exemplars/bricks.png', 0, 0, 128],
];

function npy(file, shape, data) {
  // NumPy .npy v1.0, little-endian float32, C order.
  let header = `{'descr': '<f4', 'fortran_order': False, 'shape': (${shape.join(', ')}${shape.length === 1 ? ',' : ''}), }`;
  const total = 10 + header.length + 1;
  header += ' '.repeat((64 - (total % 64)) % 64) + '\n';
  const head = Buffer.alloc(10);
  head.write('\x93NUMPY', 0, 'latin1');
  head[6] = 1; head[7] = 0;
  head.writeUInt16LE(header.length, 8);
  fs.writeFileSync(file, Buffer.concat([head, Buffer.from(header, 'latin1'), Buffer.from(data.buffer, data.byteOffset, data.byteLength)]));
}

async function main() {
  const [tarball, outDir] = process.argv.slice(2);
  if (!tarball || !outDir) throw new Error('usage: reference.js nsfwjs-4.4.0.tgz OUT_DIR');
  fs.mkdirSync(outDir, { recursive: true });
  const root = path.resolve(__dirname, '../..');
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'sifid-ref-'));
  execFileSync('tar', ['xzf', path.resolve(tarball), '-C', dir]);
  const modelDir = path.join(dir, 'package/dist/models/inception_v3');
  const model = require(path.join(modelDir, 'model.min.js'));
  const manifest = model.weightsManifest[0];
  const bytes = Buffer.concat(manifest.paths.map((p) => Buffer.from(require(path.join(modelDir, p + '.min.js')), 'base64')));
  // The Keras graph cut after activation_5, for any input size (the stem is fully convolutional).
  const topology = JSON.parse(JSON.stringify(model.modelTopology));
  const config = topology.model_config.config;
  const last = config.layers.findIndex((l) => l.name === 'activation_5');
  config.layers = config.layers.slice(0, last + 1);
  config.layers[0].config.batch_input_shape = [null, null, null, 3];
  config.output_layers = [['activation_5', 0, 0]];
  const stem = await tf.loadLayersModel(tf.io.fromMemory({
    modelTopology: topology,
    weightSpecs: manifest.weights,
    weightData: bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength),
  }), { strict: false });
  for (const [name, file, x0, y0, size] of INPUTS) {
    const png = PNG.sync.read(fs.readFileSync(path.join(root, file)));
    const rgb = new Float32Array(size * size * 3);
    for (let y = 0; y < size; y++) for (let x = 0; x < size; x++) for (let c = 0; c < 3; c++) {
      rgb[(y * size + x) * 3 + c] = png.data[((y0 + y) * png.width + x0 + x) * 4 + c] / 255;
    }
    // SinGAN's normalisation: [0, 1] -> [-1, 1], no resize.
    const input = tf.tensor4d(rgb, [1, size, size, 3]).mul(2).sub(1);
    const features = stem.predict(input);
    const [, h, w, c] = features.shape;
    npy(path.join(outDir, `${name}.npy`), [h * w, c], features.dataSync());
    console.error(`${name}: ${file} [${y0}:${y0 + size}, ${x0}:${x0 + size}] -> ${h}x${w}x${c}`);
  }
  fs.rmSync(dir, { recursive: true, force: true });
}

main().catch((e) => { console.error(e); process.exit(1); });
