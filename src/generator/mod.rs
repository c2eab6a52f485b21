//! The generator G: an MLP on coordinates (paper §3).
//!
//! `G(p) = tanh(MLP([encode(p / K), z(p * latent_scale)]))` where `K` is a learnable period scale
//! per axis, `encode` is the periodic sin/cos encoding of [`crate::encoding`] and `z` is the latent
//! random field of [`crate::latent`]. The MLP has `hidden_layers` linear layers of `width` units,
//! each followed by ReLU, then one linear layer to `channels` outputs.
//!
//! Three evaluators share one set of weights ([`GeneratorWeights`]):
//! - [`Generator`], a burn module: differentiable (training) and runs on any burn device (flex, wgpu).
//! - [`fused::FusedGenerator`], a fused CPU loop for fast synthesis, whose gradient
//!   [`backward`] writes out by hand for training on the CPU.
//! - [`kernel::KernelGenerator`], one CubeCL kernel for fast synthesis on GPUs (wgpu, CUDA).

pub mod backward;
pub mod fused;
pub mod import;
pub use import::import_pytorch;
#[cfg(any(feature = "wgpu", feature = "cuda"))]
pub mod kernel;
/// Builds without a GPU feature have no generator kernel.
#[cfg(not(any(feature = "wgpu", feature = "cuda")))]
pub mod kernel {
    use crate::latent::LatentField;

    #[derive(Debug)]
    pub enum KernelGenerator {}

    impl KernelGenerator {
        pub fn new(_: &super::GeneratorWeights, _: &burn::tensor::Device) -> Option<Self> {
            None
        }

        pub fn with_launch_points(self, _: usize) -> Self {
            match self {}
        }

        pub fn render(
            &self,
            _: &LatentField,
            _: &[f32],
            _: &[Vec<f32>],
            _: impl FnMut(usize, usize) -> Vec<f32>,
        ) -> Vec<f32> {
            match *self {}
        }

        pub fn largest_device_allocation(&self) -> u64 {
            match *self {}
        }
    }
}

use burn::module::Param;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;

use crate::checkpoint::Checkpoint;
use crate::encoding;
use crate::input_error;

/// The widest hidden layer a generator may have.
pub const MAX_WIDTH: usize = 4096;
/// The most hidden layers a generator may have.
pub const MAX_HIDDEN_LAYERS: usize = 256;
/// The most parameters a generator may have: 2^26 (256 MiB of floats; the paper's has 150k).
pub const MAX_PARAMETERS: usize = 1 << 26;

/// Shape and constants of a generator. Stored in every checkpoint.
#[derive(Config, Debug, PartialEq)]
pub struct GeneratorConfig {
    /// Spatial axes of the coordinates: 2 for images, 3 for volumes.
    #[config(default = 2)]
    pub dims: usize,
    /// Output channels (3 for RGB; more for stacked material maps).
    #[config(default = 3)]
    pub channels: usize,
    /// Octaves L of the periodic encoding (frequencies `2^j * pi`, j < L).
    #[config(default = 5)]
    pub octaves: usize,
    /// Channels of the latent random field (5 in the paper).
    #[config(default = 5)]
    pub latent_dim: usize,
    /// Linear + ReLU layers before the output layer.
    #[config(default = 10)]
    pub hidden_layers: usize,
    /// Units per hidden layer.
    #[config(default = 128)]
    pub width: usize,
    /// Softmax temperature of the latent field's corner blend (paper eq. 4).
    #[config(default = 0.2)]
    pub sigma: f32,
    /// Latent lattice units per coordinate unit (the authors look the field up at `p / 2`).
    #[config(default = 0.5)]
    pub latent_scale: f32,
    /// Exemplar pixels per 2 coordinate units: the training crop, measured in pixels of the
    /// exemplar as the user gave it (before any `--resize`). One exemplar pixel is `2 / crop`
    /// units; synthesis at zoom 1 paints at that scale.
    #[config(default = 128)]
    pub crop: usize,
    /// Guidance channels appended to the MLP's input after the latent channels (conditional
    /// IPFN, paper eq. 5): 0 for a plain model, 1 for a guided one.
    #[config(default = 0)]
    pub guidance: usize,
}

impl GeneratorConfig {
    /// Width of the MLP's input: encoding, latent and guidance channels.
    pub fn input_width(&self) -> usize {
        encoding::channels(self.dims, self.octaves) + self.latent_dim + self.guidance
    }

    /// `(inputs, outputs)` of every linear layer, output layer last.
    pub fn layer_shapes(&self) -> Vec<(usize, usize)> {
        let mut shapes = Vec::with_capacity(self.hidden_layers + 1);
        let mut inputs = self.input_width();
        for _ in 0..self.hidden_layers {
            shapes.push((inputs, self.width));
            inputs = self.width;
        }
        shapes.push((inputs, self.channels));
        shapes
    }

    /// Multiply-adds per generated point (for FLOP counts).
    pub fn macs_per_point(&self) -> usize {
        self.layer_shapes().iter().map(|(i, o)| i * o).sum()
    }

    /// Checks that the numbers describe a model this build can run.
    /// Checks every field against its range, before anything is allocated from it: a model
    /// file's or a config's claims are bounded ([`MAX_WIDTH`], [`MAX_HIDDEN_LAYERS`],
    /// [`MAX_PARAMETERS`]).
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |what: &str| Err(input_error!("invalid generator config: {what}"));
        if !(2..=3).contains(&self.dims) {
            return bad(&format!("dims = {}, expected 2 or 3", self.dims));
        }
        if self.channels == 0 || self.channels > 64 {
            return bad(&format!("channels = {}, expected 1 to 64", self.channels));
        }
        if self.octaves == 0 || self.octaves > 20 {
            return bad(&format!("octaves = {}, expected 1 to 20", self.octaves));
        }
        if self.latent_dim > crate::latent::MAX_LATENT_DIM {
            return bad(&format!(
                "latent_dim = {}, at most {}",
                self.latent_dim,
                crate::latent::MAX_LATENT_DIM
            ));
        }
        if self.guidance > 1 {
            return bad(&format!("guidance = {}, expected 0 or 1", self.guidance));
        }
        if self.width == 0 || self.hidden_layers == 0 {
            return bad("width and hidden_layers must be at least 1");
        }
        if self.width > MAX_WIDTH || self.hidden_layers > MAX_HIDDEN_LAYERS {
            return bad(&format!(
                "width = {}, hidden_layers = {}: at most {MAX_WIDTH} and {MAX_HIDDEN_LAYERS}",
                self.width, self.hidden_layers
            ));
        }
        let parameters: usize = self.layer_shapes().iter().map(|(i, o)| (i + 1) * o).sum();
        if parameters > MAX_PARAMETERS {
            return bad(&format!(
                "{parameters} parameters (width {} x {} layers), at most {MAX_PARAMETERS}",
                self.width, self.hidden_layers
            ));
        }
        if !(self.sigma > 0.0 && self.latent_scale > 0.0) || self.crop == 0 {
            return bad("sigma, latent_scale and crop must be positive");
        }
        if !(self.sigma.is_finite() && self.latent_scale.is_finite()) {
            return bad("sigma and latent_scale must be finite");
        }
        Ok(())
    }

    /// A generator with PyTorch-style random initialisation and K = 1 on `device`.
    pub fn init(&self, device: &Device) -> Generator {
        let layers = self
            .layer_shapes()
            .into_iter()
            .map(|(i, o)| LinearConfig::new(i, o).init(device))
            .collect();
        Generator {
            k: Param::from_tensor(Tensor::ones([self.dims], device)),
            layers,
            octaves: self.octaves,
        }
    }
}

/// The generator as a burn module.
#[derive(Module, Debug)]
pub struct Generator {
    /// Learnable period scale K, one per axis (`q = p / K`).
    pub k: Param<Tensor<1>>,
    /// Hidden layers (ReLU after each) then the output layer (tanh after it).
    pub layers: Vec<Linear>,
    /// Octaves of the periodic encoding.
    pub octaves: usize,
}

impl Generator {
    /// Evaluates G at `n` points.
    ///
    /// # Shapes
    /// - `p`: `[n, dims]` coordinates
    /// - `latent`: `[n, latent_dim + guidance]` latent field values at those points, then the
    ///   guidance value of a guided model
    /// - output: `[n, channels]` in [-1, 1]
    pub fn forward(&self, p: Tensor<2>, latent: Tensor<2>) -> Tensor<2> {
        let [_, dims] = p.dims();
        let q = p / self.k.val().reshape([1, dims]); // [n, dims]
        let enc = encoding::encode(q, self.octaves); // [n, 2 * L * dims]
        let mut x = Tensor::cat(vec![enc, latent], 1); // [n, input_width]
        let last = self.layers.len() - 1;
        for (i, layer) in self.layers.iter().enumerate() {
            x = layer.forward(x); // [n, width] or [n, channels]
            if i < last {
                x = relu(x);
            }
        }
        x.tanh()
    }

    /// Host copy of the weights.
    pub fn weights(&self) -> GeneratorWeights {
        let read = |t: Tensor<2>| {
            t.try_into_vec_as::<f32>()
                .expect("generator weights are readable as f32")
        };
        GeneratorWeights {
            k: self
                .k
                .val()
                .try_into_vec_as::<f32>()
                .expect("K is readable as f32"),
            octaves: self.octaves,
            layers: self
                .layers
                .iter()
                .map(|l| {
                    let [inputs, outputs] = l.weight.val().dims();
                    LayerWeights {
                        inputs,
                        outputs,
                        weight: read(l.weight.val()),
                        bias: l
                            .bias
                            .as_ref()
                            .map(|b| {
                                b.val()
                                    .try_into_vec_as::<f32>()
                                    .expect("bias is readable as f32")
                            })
                            .unwrap_or_else(|| vec![0.0; outputs]),
                    }
                })
                .collect(),
        }
    }

    /// A generator on `device` holding `weights`.
    pub fn from_weights(weights: &GeneratorWeights, device: &Device) -> Self {
        let tensor2 = |v: &[f32], shape: [usize; 2]| {
            Tensor::<2>::from_data(TensorData::new(v.to_vec(), shape), device)
        };
        let tensor1 =
            |v: &[f32]| Tensor::<1>::from_data(TensorData::new(v.to_vec(), [v.len()]), device);
        let layers = weights
            .layers
            .iter()
            .map(|l| {
                let mut linear = LinearConfig::new(l.inputs, l.outputs).init(device);
                linear.weight = Param::from_tensor(tensor2(&l.weight, [l.inputs, l.outputs]));
                linear.bias = Some(Param::from_tensor(tensor1(&l.bias)));
                linear
            })
            .collect();
        Generator {
            k: Param::from_tensor(tensor1(&weights.k)),
            layers,
            octaves: weights.octaves,
        }
    }
}

/// One linear layer's parameters on the host.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerWeights {
    pub inputs: usize,
    pub outputs: usize,
    /// `[inputs, outputs]`, row-major (burn's `Linear` layout: `y = x W + b`).
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

/// A host copy of a generator's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratorWeights {
    /// Period scale per axis.
    pub k: Vec<f32>,
    pub octaves: usize,
    pub layers: Vec<LayerWeights>,
}

/// Checkpoint metadata key holding the [`GeneratorConfig`] as JSON.
pub const CONFIG_KEY: &str = "generator_config";

impl GeneratorWeights {
    /// Random weights for `config`, drawn from `seed` (the same weights on every run): PyTorch's
    /// default uniform init, `±1 / sqrt(inputs)` for every weight and bias, and K at 1.
    pub fn random(config: &GeneratorConfig, seed: u64) -> Self {
        let mut weights = config.init(&Device::flex()).weights();
        for (l, layer) in weights.layers.iter_mut().enumerate() {
            let bound = (layer.inputs as f32).sqrt().recip();
            let values = layer.weight.iter_mut().chain(&mut layer.bias);
            for (i, v) in values.enumerate() {
                let unit = crate::latent::unit_uniform(seed, &[l as u64, i as u64]);
                *v = (2.0 * unit - 1.0) * bound;
            }
        }
        weights
    }

    /// Stores config and weights under the `generator.*` names.
    pub fn write_to(&self, config: &GeneratorConfig, checkpoint: &mut Checkpoint) {
        self.write_named("generator", config, checkpoint);
    }

    /// Stores config and weights under the `PREFIX.*` names (a training state holds the
    /// trained weights beside the averaged ones that `generator.*` names).
    pub fn write_named(&self, prefix: &str, config: &GeneratorConfig, checkpoint: &mut Checkpoint) {
        checkpoint.metadata.insert(
            CONFIG_KEY.into(),
            serde_json::to_string(config).expect("config serialises"),
        );
        checkpoint.insert(format!("{prefix}.k"), vec![self.k.len()], self.k.clone());
        for (i, l) in self.layers.iter().enumerate() {
            checkpoint.insert(
                format!("{prefix}.layers.{i}.weight"),
                vec![l.inputs, l.outputs],
                l.weight.clone(),
            );
            checkpoint.insert(
                format!("{prefix}.layers.{i}.bias"),
                vec![l.outputs],
                l.bias.clone(),
            );
        }
    }

    /// Reads config and weights, checking every tensor against the config's shapes.
    pub fn read_from(checkpoint: &Checkpoint) -> crate::Result<(GeneratorConfig, Self)> {
        Self::read_named("generator", checkpoint)
    }

    /// [`GeneratorWeights::read_from`] for the weights stored under `PREFIX.*`.
    pub fn read_named(
        prefix: &str,
        checkpoint: &Checkpoint,
    ) -> crate::Result<(GeneratorConfig, Self)> {
        let path = checkpoint.source.display();
        let unreadable =
            |e: serde_json::Error| input_error!("{path}: unreadable generator config: {e}");
        let mut json: serde_json::Value =
            serde_json::from_str(checkpoint.meta(CONFIG_KEY)?).map_err(unreadable)?;
        // Fields added after format version 1 was first written take their defaults.
        if let Some(fields) = json.as_object_mut() {
            fields
                .entry("guidance")
                .or_insert(serde_json::Value::from(0));
        }
        let config: GeneratorConfig = serde_json::from_value(json).map_err(unreadable)?;
        config.validate().map_err(|e| input_error!("{path}: {e}"))?;
        let k = checkpoint
            .tensor(&format!("{prefix}.k"), &[config.dims])?
            .to_vec();
        let mut layers = Vec::new();
        for (i, (inputs, outputs)) in config.layer_shapes().into_iter().enumerate() {
            layers.push(LayerWeights {
                inputs,
                outputs,
                weight: checkpoint
                    .tensor(&format!("{prefix}.layers.{i}.weight"), &[inputs, outputs])?
                    .to_vec(),
                bias: checkpoint
                    .tensor(&format!("{prefix}.layers.{i}.bias"), &[outputs])?
                    .to_vec(),
            });
        }
        let extra = format!("{prefix}.layers.{}.weight", config.hidden_layers + 1);
        if checkpoint.tensors.contains_key(&extra) {
            return Err(input_error!(
                "{path}: has more layers than its config says: the checkpoint is for another model shape"
            ));
        }
        Ok((
            config.clone(),
            GeneratorWeights {
                k,
                octaves: config.octaves,
                layers,
            },
        ))
    }
}
