//! Import of a generator trained by the authors' PyTorch code (nintendops/IPFN, `netG.pth`).

use std::collections::HashMap;
use std::path::Path;

use burn::store::pytorch::PytorchReader;

use super::{GeneratorConfig, GeneratorWeights, LayerWeights};
use crate::error::Result;
use crate::input_error;

/// The float tensors of a `.pth` file, read by name.
struct PthTensors<'a> {
    file: std::path::Display<'a>,
    tensors: HashMap<String, burn::store::pytorch_reader::Tensor>,
}

impl PthTensors<'_> {
    fn contains(&self, name: &str) -> bool {
        self.tensors.contains_key(name)
    }

    /// The tensor `name` as float32: its shape and values.
    fn read(&self, name: &str) -> Result<(Vec<usize>, Vec<f32>)> {
        let file = &self.file;
        let t = self.tensors.get(name).ok_or_else(|| {
            input_error!("{file}: no tensor '{name}': not an IPFN generator (netG) checkpoint")
        })?;
        let bytes = t
            .read()
            .map_err(|e| input_error!("{file}: tensor '{name}' is unreadable: {e}"))?;
        let values: Vec<f32> = match t.dtype() {
            burn::store::pytorch_reader::DType::F32 => bytes
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect(),
            burn::store::pytorch_reader::DType::F64 => bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
                .collect(),
            other => {
                return Err(input_error!(
                    "{file}: tensor '{name}' is {other:?}, expected float32"
                ));
            }
        };
        Ok((t.shape().to_vec(), values))
    }

    /// A 1x1 convolution `{prefix}.weight` `[out, in, 1, 1]` (and its bias) as a linear layer
    /// `[in, out]`.
    fn linear(&self, prefix: &str) -> Result<LayerWeights> {
        let (shape, w) = self.read(&format!("{prefix}.weight"))?;
        let (_, bias) = self.read(&format!("{prefix}.bias"))?;
        if shape.len() != 4 || shape[2] != 1 || shape[3] != 1 || bias.len() != shape[0] {
            return Err(input_error!(
                "{}: {prefix} has shape {shape:?}, expected a 1x1 convolution [out, in, 1, 1]",
                self.file
            ));
        }
        let (outputs, inputs) = (shape[0], shape[1]);
        let mut weight = vec![0f32; inputs * outputs];
        for o in 0..outputs {
            for i in 0..inputs {
                weight[i * outputs + o] = w[o * inputs + i];
            }
        }
        Ok(LayerWeights {
            inputs,
            outputs,
            weight,
            bias,
        })
    }
}

/// Converts a generator saved by the authors' PyTorch code (nintendops/IPFN, `netG.pth`) into
/// our config and weights. `octaves` and `crop` are not stored in their file: pass the values
/// it was trained with (their defaults are 5 and 128).
///
/// Their state dict holds `K` `[dims]`, `mlp.blocks.{i}.layer.{weight,bias}` (1x1 convolutions,
/// weight `[out, in, 1, 1]`, ReLU after each) and `mlp.last_conv.layer.*` (the output layer, tanh
/// after it; their last block may repeat it under `mlp.blocks.{n}`).
pub fn import_pytorch(
    path: &Path,
    octaves: usize,
    crop: usize,
) -> Result<(GeneratorConfig, GeneratorWeights)> {
    let file = path.display();
    let reader = PytorchReader::new(path).map_err(|e| match std::fs::metadata(path) {
        Err(_) => input_error!("{file}: no such file"),
        Ok(_) => input_error!("{file}: not a readable PyTorch checkpoint: {e}"),
    })?;
    let pth = PthTensors {
        file: path.display(),
        tensors: reader.into_tensors(),
    };
    let (_, k) = pth.read("K")?;
    let output = pth.linear("mlp.last_conv.layer")?;
    let mut layers = Vec::new();
    while pth.contains(&format!("mlp.blocks.{}.layer.weight", layers.len())) {
        layers.push(pth.linear(&format!("mlp.blocks.{}.layer", layers.len()))?);
    }
    if layers.last() == Some(&output) {
        layers.pop(); // the output layer stored twice
    }
    if layers.is_empty() {
        return Err(input_error!(
            "{file}: no hidden layers (mlp.blocks.*): not an IPFN generator checkpoint"
        ));
    }
    let dims = k.len();
    let encoding = crate::encoding::channels(dims, octaves);
    let width = layers[0].outputs;
    if layers[0].inputs <= encoding {
        return Err(input_error!(
            "{file}: first layer takes {} inputs, fewer than the {encoding} encoding channels of {octaves} octaves; pass the right --octaves",
            layers[0].inputs
        ));
    }
    let config = GeneratorConfig::new()
        .with_dims(dims)
        .with_channels(output.outputs)
        .with_octaves(octaves)
        .with_latent_dim(layers[0].inputs - encoding)
        .with_hidden_layers(layers.len())
        .with_width(width)
        .with_crop(crop);
    config.validate().map_err(|e| input_error!("{file}: {e}"))?;
    layers.push(output);
    let expected = config.layer_shapes();
    for (i, (l, &(inputs, outputs))) in layers.iter().zip(&expected).enumerate() {
        if (l.inputs, l.outputs) != (inputs, outputs) {
            return Err(input_error!(
                "{file}: layer {i} is {}x{}, expected {inputs}x{outputs}: not a plain IPFN MLP",
                l.inputs,
                l.outputs
            ));
        }
    }
    Ok((config, GeneratorWeights { k, octaves, layers }))
}
