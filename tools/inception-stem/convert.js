#!/usr/bin/env node
// Converts the InceptionV3 stem (Keras ImageNet weights, as shipped by the npm package
// nsfwjs@4.4.0, MIT) into assets/inception_v3_stem.safetensors, which `ipfn eval` embeds.
//
//   npm pack nsfwjs@4.4.0
//   node tools/inception-stem/convert.js nsfwjs-4.4.0.tgz assets/inception_v3_stem.safetensors
//
// The stem is SinGAN's SIFID feature extractor (blocks 0 and 1 of its InceptionV3): conv2d_1..5,
// each followed by batch_normalization_1..5 and ReLU, with max_pooling2d_1 after conv2d_3.
// Weights in the package are uint8 with a per-tensor min and scale; they are dequantized exactly
// as tfjs does (q * scale + min, rounded to f32). Kernels go from Keras HWIO to OIHW.
// The output is byte-for-byte deterministic; tests/integration/metrics.rs re-derives it and compares.
'use strict';
const fs = require('fs');
const os = require('os');
const path = require('path');
const crypto = require('crypto');
const { execFileSync } = require('child_process');

const PACKAGE = 'nsfwjs';
const VERSION = '4.4.0';
const MODEL_DIR = 'package/dist/models/inception_v3';
// Conv layers of the stem and what the topology must say about them.
const STEM = [
  { conv: 'conv2d_1', bn: 'batch_normalization_1', filters: 32, kernel: 3, stride: 2, padding: 'valid' },
  { conv: 'conv2d_2', bn: 'batch_normalization_2', filters: 32, kernel: 3, stride: 1, padding: 'valid' },
  { conv: 'conv2d_3', bn: 'batch_normalization_3', filters: 64, kernel: 3, stride: 1, padding: 'same' },
  { conv: 'conv2d_4', bn: 'batch_normalization_4', filters: 80, kernel: 1, stride: 1, padding: 'valid' },
  { conv: 'conv2d_5', bn: 'batch_normalization_5', filters: 192, kernel: 3, stride: 1, padding: 'valid' },
];

function fail(msg) {
  console.error(`convert.js: ${msg}`);
  process.exit(2);
}

const [tarball, out] = process.argv.slice(2);
if (!tarball || !out) fail('usage: convert.js nsfwjs-4.4.0.tgz OUT.safetensors');
const tgz = fs.readFileSync(tarball);
const sha256 = crypto.createHash('sha256').update(tgz).digest('hex');

const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'inception-stem-'));
try {
  execFileSync('tar', ['xzf', path.resolve(tarball), '-C', dir]);
  const pkg = JSON.parse(fs.readFileSync(path.join(dir, 'package/package.json'), 'utf8'));
  if (pkg.name !== PACKAGE || pkg.version !== VERSION) {
    fail(`${tarball} is ${pkg.name}@${pkg.version}, expected ${PACKAGE}@${VERSION}`);
  }
  const license = fs.readFileSync(path.join(dir, 'package/LICENSE'), 'utf8').split('\n').slice(0, 3).join(' ').replace(/\s+/g, ' ').trim();
  const model = require(path.join(dir, MODEL_DIR, 'model.min.js'));
  const layers = new Map(model.modelTopology.model_config.config.layers.map((l) => [l.name, l]));

  // Check the topology, so a different model is refused rather than silently converted.
  let previous = 'input_1';
  for (const s of STEM) {
    const conv = layers.get(s.conv);
    const bn = layers.get(s.bn);
    const c = conv && conv.config;
    const ok = c && conv.class_name === 'Conv2D' && c.filters === s.filters && c.kernel_size.every((k) => k === s.kernel) &&
      c.strides.every((k) => k === s.stride) && c.padding === s.padding && c.use_bias === false &&
      c.trainable === false && c.dilation_rate.every((d) => d === 1);
    if (!ok) fail(`${s.conv} is not the expected frozen ${s.kernel}x${s.kernel} conv`);
    const inbound = conv.inbound_nodes[0][0][0];
    if (inbound !== previous) fail(`${s.conv} reads ${inbound}, expected ${previous}`);
    const b = bn && bn.config;
    if (!b || b.epsilon !== 0.001 || b.scale !== false || b.center !== true || b.trainable !== false) {
      fail(`${s.bn} is not a frozen batch norm with eps 0.001 and scale=False`);
    }
    const act = 'activation_' + s.conv.split('_')[1];
    if (layers.get(act).config.activation !== 'relu') fail(`${act} is not a ReLU`);
    previous = act;
    if (s.conv === 'conv2d_3') {
      const pool = layers.get('max_pooling2d_1').config;
      if (pool.pool_size.join() !== '3,3' || pool.strides.join() !== '2,2' || pool.padding !== 'valid') fail('max_pooling2d_1 is not 3x3 stride 2');
      previous = 'max_pooling2d_1';
    }
  }

  // Concatenate the shards and dequantize each weight in manifest order.
  const manifest = model.weightsManifest;
  if (manifest.length !== 1) fail('expected one weight group');
  const bytes = Buffer.concat(manifest[0].paths.map((p) => Buffer.from(require(path.join(dir, MODEL_DIR, p + '.min.js')), 'base64')));
  const weights = new Map();
  let offset = 0;
  for (const w of manifest[0].weights) {
    const n = w.shape.reduce((a, b) => a * b, 1);
    const q = w.quantization;
    if (w.dtype !== 'float32' || !q || q.dtype !== 'uint8') fail(`${w.name}: expected uint8-quantized float32`);
    const values = new Float32Array(n);
    for (let i = 0; i < n; i++) values[i] = bytes[offset + i] * q.scale + q.min;
    weights.set(w.name, { shape: w.shape, values });
    offset += n;
  }
  if (offset !== bytes.length) fail(`weight bytes ${bytes.length} do not match the manifest (${offset})`);

  // Tensors in the order they are written.
  const tensors = [];
  STEM.forEach((s, i) => {
    const k = weights.get(`${s.conv}/kernel`);
    const [kh, kw, ci, co] = k.shape;
    const oihw = new Float32Array(k.values.length);
    for (let y = 0; y < kh; y++) for (let x = 0; x < kw; x++) for (let a = 0; a < ci; a++) for (let o = 0; o < co; o++) {
      oihw[((o * ci + a) * kh + y) * kw + x] = k.values[((y * kw + x) * ci + a) * co + o];
    }
    tensors.push([`conv${i + 1}.weight`, [co, ci, kh, kw], oihw]);
    for (const [ours, keras] of [['beta', 'beta'], ['mean', 'moving_mean'], ['variance', 'moving_variance']]) {
      const t = weights.get(`${s.bn}/${keras}`);
      tensors.push([`bn${i + 1}.${ours}`, t.shape, t.values]);
    }
  });

  // safetensors: u64 LE header length, JSON header (padded to 8 bytes), then the data.
  const header = {
    __metadata__: {
      format: 'ipfn-inception-stem',
      source: `npm ${PACKAGE}@${VERSION}, ${MODEL_DIR} (Keras 2.2.4 ImageNet InceptionV3, frozen stem)`,
      tarball_sha256: sha256,
      license: `${license} (MIT)`,
      layers: STEM.map((s) => `${s.conv}+${s.bn}`).join(','),
      padding: STEM.map((s) => s.padding).join(','),
      batch_norm_epsilon: '0.001',
      converter: 'tools/inception-stem/convert.js',
    },
  };
  let at = 0;
  for (const [name, shape, values] of tensors) {
    header[name] = { dtype: 'F32', shape, data_offsets: [at, at + values.length * 4] };
    at += values.length * 4;
  }
  let json = Buffer.from(JSON.stringify(header), 'utf8');
  const pad = (8 - (json.length % 8)) % 8;
  json = Buffer.concat([json, Buffer.alloc(pad, 0x20)]);
  const len = Buffer.alloc(8);
  len.writeBigUInt64LE(BigInt(json.length));
  const data = Buffer.concat(tensors.map(([, , v]) => Buffer.from(v.buffer, v.byteOffset, v.byteLength)));
  const tmp = out + '.tmp';
  fs.writeFileSync(tmp, Buffer.concat([len, json, data]));
  fs.renameSync(tmp, out);
  console.error(`wrote ${out}: ${tensors.length} tensors, ${data.length} bytes of f32, from ${PACKAGE}@${VERSION} (sha256 ${sha256})`);
} finally {
  fs.rmSync(dir, { recursive: true, force: true });
}
