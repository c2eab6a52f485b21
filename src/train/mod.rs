//! Training (paper §3.3): WGAN-GP between random crops of the exemplar and generated crops.
//!
//! Each iteration runs `critic_steps` critic updates (fresh real crops, fresh fakes, the exact
//! gradient penalty of [`crate::critic`]) and then `generator_steps` generator updates. Every
//! random draw (weight init, crop positions, shifts, latent fields, interpolation weights) is a
//! hash of `(seed, purpose, iteration, step, sample)`, so a resumed run continues bit for bit.

pub mod adam;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::{Module, ModuleMapper, Param};
use burn::optim::GradientsParams;
use burn::prelude::*;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::checkpoint::{self, Checkpoint};
use crate::critic::volume::{VolumeCritic, VolumeCriticConfig};
use crate::critic::{Critic, CriticConfig};
use crate::error::{Error, Result};
use crate::generator::fused::{CHUNK_POINTS, FusedGenerator, Scratch};
use crate::generator::{Generator, GeneratorConfig, GeneratorWeights};
use crate::guidance::Guide;
use crate::input_error;
use crate::io::{Exemplar, write_png};
use crate::latent::{DeviceLattice, LatentField, derive_seed, mix64};
use crate::maps::{MapFiles, MapSet};
use crate::synth::Synth;
use adam::Adam;

/// Every training setting. Read from TOML (unknown keys are rejected), overridden by flags,
/// saved as `config.toml` in the run folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// Iterations to train (each: `critic_steps` critic then `generator_steps` generator updates).
    pub iterations: u64,
    /// Crops per step.
    pub batch: usize,
    /// Crop size in pixels (a multiple of 16; a crop spans 2 coordinate units).
    pub crop: usize,
    /// Random shift of the generated crops, uniform in [-shift, shift] coordinate units per axis.
    pub shift: f32,
    pub critic_steps: usize,
    pub generator_steps: usize,
    /// Adam learning rate and betas, for both networks.
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    /// Weight of the gradient penalty.
    pub gp_lambda: f64,
    /// Seed of every random draw.
    pub seed: u64,
    /// Scale the exemplar by this factor first (Lanczos-3, anti-aliased); 1 keeps it as it is.
    pub resize: f64,
    /// Write a checkpoint (and update `latest.ipfn`) every this many iterations.
    pub checkpoint_every: u64,
    /// Write a preview image every this many iterations.
    pub preview_every: u64,
    /// Plain log line every this many iterations (when stderr is not a terminal).
    pub log_every: u64,
    /// Generator: encoding octaves, latent channels, depth, width, blend sigma, latent scale.
    pub octaves: usize,
    pub latent_dim: usize,
    pub hidden_layers: usize,
    pub width: usize,
    pub sigma: f32,
    pub latent_scale: f32,
    /// Critic: output channels of its stride-2 convolutions.
    pub critic_widths: Vec<usize>,
    /// Directional guidance (conditional IPFN): `x`, `y`, `-x`, `-y` or `a,b,c` for
    /// `g = a·X + b·Y + c` over the exemplar's normalised coordinates. Unset: no guidance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guide: Option<String>,
    /// Solid texture (Henzler et al. 2020): a generator of 3 coordinates whose random
    /// axis-aligned slices the 2D critic compares with crops of the 2D exemplar.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub solid: bool,
    /// Set by `train` when the exemplar is a volume (`.npy`): a 3D generator against the 3D
    /// critic, on cubic crops of `crop` voxels.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub volume: bool,
    /// Volumes: the signed distances are multiplied by this and clamped to [-1, 1] (the
    /// authors' truncated SDF).
    #[serde(skip_serializing_if = "is_default_sdf_scale")]
    pub sdf_scale: f32,
    /// Volumes: density control (the paper's Fig. 7). The generator and the critic also get the
    /// crop's density, the mean |sdf| of its truncated SDF; `synth --density` then sets it.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub density: bool,
}

fn is_default_sdf_scale(v: &f32) -> bool {
    *v == DEFAULT_SDF_SCALE
}

/// The authors' `sdf_scale`.
pub const DEFAULT_SDF_SCALE: f32 = 10.0;

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            iterations: 5000,
            batch: 4,
            crop: 128,
            shift: 4.0,
            critic_steps: 5,
            generator_steps: 5,
            lr: 1e-4,
            beta1: 0.5,
            beta2: 0.9,
            gp_lambda: 10.0,
            seed: 0,
            resize: 1.0,
            checkpoint_every: 100,
            preview_every: 100,
            log_every: 10,
            octaves: 5,
            latent_dim: 5,
            hidden_layers: 10,
            width: 128,
            sigma: 0.2,
            latent_scale: 0.5,
            critic_widths: vec![64, 128, 256, 512],
            guide: None,
            solid: false,
            volume: false,
            sdf_scale: DEFAULT_SDF_SCALE,
            density: false,
        }
    }
}

impl TrainConfig {
    /// Parses TOML; `source` names the file in errors.
    pub fn from_toml(text: &str, source: &Path) -> Result<Self> {
        toml::from_str(text).map_err(|e| {
            let msg = e.message().replace('\n', " ");
            input_error!("{}: {msg}", source.display())
        })
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serialises")
    }

    pub fn generator_config(&self, channels: usize) -> GeneratorConfig {
        GeneratorConfig::new()
            .with_dims(self.dims())
            .with_channels(channels)
            .with_octaves(self.octaves)
            .with_latent_dim(self.latent_dim)
            .with_hidden_layers(self.hidden_layers)
            .with_width(self.width)
            .with_sigma(self.sigma)
            .with_latent_scale(self.latent_scale)
            // The model's pixel is the exemplar's pixel as the user gave it, before --resize,
            // so `synth` at zoom 1 paints the pattern at the exemplar's own scale.
            .with_crop(((self.crop as f64) / self.resize).round().max(1.0) as usize)
            .with_guidance(self.conditioned() as usize)
    }

    /// Whether the generator takes one more input after the latent (and the critic one more
    /// channel): the guidance `g` of a guided run, or the density of a density-controlled one.
    pub fn conditioned(&self) -> bool {
        self.guide.is_some() || self.density
    }

    /// Coordinate axes of the generator: 3 for a solid texture or a volume, else 2.
    pub fn dims(&self) -> usize {
        if self.solid || self.volume { 3 } else { 2 }
    }

    /// The 3D critic of a volume run.
    pub fn volume_critic_config(&self) -> VolumeCriticConfig {
        VolumeCriticConfig::new(1 + self.density as usize, self.crop)
            .with_widths(self.critic_widths.clone())
    }

    /// The critic sees the image's channels and, for a guided run, the guidance channel.
    pub fn critic_config(&self, channels: usize) -> CriticConfig {
        CriticConfig::new(channels + self.guide.is_some() as usize, self.crop)
            .with_widths(self.critic_widths.clone())
    }

    /// The guidance line, if the run is guided.
    pub fn guide(&self) -> Result<Option<Guide>> {
        self.guide.as_deref().map(str::parse).transpose()
    }

    /// Checks the numbers, and that the exemplar is large enough for the crop.
    pub fn validate(&self, exemplar: &Exemplar, exemplar_path: &Path) -> Result<()> {
        let positive = [
            ("iterations", self.iterations as usize),
            ("batch", self.batch),
            ("critic_steps", self.critic_steps),
            ("generator_steps", self.generator_steps),
            ("checkpoint_every", self.checkpoint_every as usize),
            ("preview_every", self.preview_every as usize),
            ("log_every", self.log_every as usize),
        ];
        for (name, v) in positive {
            if v == 0 {
                return Err(input_error!("{name} = 0: must be at least 1"));
            }
        }
        if !(self.lr > 0.0 && self.gp_lambda >= 0.0 && self.shift >= 0.0 && self.resize > 0.0) {
            return Err(input_error!(
                "lr and resize must be positive, gp_lambda and shift not negative"
            ));
        }
        self.guide()?;
        if self.density && !self.volume {
            return Err(input_error!(
                "--density is for volumes (.npy); for images, --guide conditions on a direction"
            ));
        }
        if self.solid && self.guide.is_some() {
            return Err(input_error!(
                "--solid and --guide cannot be combined: guidance is defined over a 2D exemplar's frame"
            ));
        }
        if self.volume {
            if self.solid || self.guide.is_some() || self.resize != 1.0 {
                return Err(input_error!(
                    "{}: a volume exemplar takes neither --solid, --guide nor --resize",
                    exemplar_path.display()
                ));
            }
            if !self.sdf_scale.is_finite() || self.sdf_scale <= 0.0 {
                return Err(input_error!("sdf_scale must be positive"));
            }
            self.volume_critic_config().validate()?;
            self.generator_config(exemplar.channels).validate()?;
            let smallest = exemplar.depth.min(exemplar.height).min(exemplar.width);
            if smallest < self.crop {
                return Err(input_error!(
                    "{}: the volume is {}x{}x{} voxels, smaller than the {} voxel crop; use a smaller --crop (a multiple of 16, e.g. {})",
                    exemplar_path.display(),
                    exemplar.width,
                    exemplar.height,
                    exemplar.depth,
                    self.crop,
                    (smallest / 16 * 16).max(16)
                ));
            }
            return Ok(());
        }
        self.critic_config(exemplar.channels).validate()?;
        self.generator_config(exemplar.channels).validate()?;
        if exemplar.width < self.crop || exemplar.height < self.crop {
            return Err(input_error!(
                "{}: the exemplar is {}x{}, smaller than the {} pixel crop; use a smaller --crop (a multiple of 16, e.g. {}) or --resize",
                exemplar_path.display(),
                exemplar.width,
                exemplar.height,
                self.crop,
                (exemplar.width.min(exemplar.height) / 16 * 16).max(16)
            ));
        }
        Ok(())
    }
}

/// Purposes of random draws, so no two share a stream.
mod stream {
    pub const INIT_GENERATOR: u64 = 1;
    pub const INIT_CRITIC: u64 = 2;
    pub const REAL_CROP: u64 = 3;
    pub const SHIFT: u64 = 4;
    pub const LATENT: u64 = 5;
    pub const ALPHA: u64 = 6;
    pub const CRITIC_FAKE: u64 = 7;
    pub const GENERATOR_FAKE: u64 = 8;
    pub const PREVIEW: u64 = 9;
    pub const GUIDE: u64 = 10;
    pub const SLICE_AXIS: u64 = 11;
}

/// Uniform in [0, 1) from a seed and counters.
fn uniform(seed: u64, counters: &[u64]) -> f32 {
    (derive_seed(seed, counters) >> 40) as f32 / 16_777_216.0
}

/// Re-initialises every float parameter except the generator's K with PyTorch's default
/// uniform(-1/sqrt(fan_in), 1/sqrt(fan_in)), from hashed draws.
fn initialise<M: Module>(module: M, seed: u64, stream: u64) -> M {
    struct Init {
        seed: u64,
        stream: u64,
        path: Vec<String>,
        fan_in: usize,
    }
    impl ModuleMapper for Init {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let name = self.path.last().cloned().unwrap_or_default();
            if name == "k" {
                return param;
            }
            let (id, tensor, mapper) = param.consume();
            let shape = tensor.dims();
            if name == "weight" {
                // Linear weights are [in, out]; convolution weights [out, in, kh, kw].
                self.fan_in = if D == 2 {
                    shape[0]
                } else {
                    shape[1..].iter().product()
                };
            }
            let bound = 1.0 / (self.fan_in.max(1) as f32).sqrt();
            let key = self.path.iter().fold(self.seed, |h, p| {
                mix64(h ^ p.bytes().fold(0u64, |a, b| mix64(a ^ b as u64)))
            });
            let n: usize = shape.iter().product();
            let values: Vec<f32> = (0..n as u64)
                .map(|i| (uniform(key, &[self.stream, i]) * 2.0 - 1.0) * bound)
                .collect();
            let fresh = Tensor::<D>::from_data(TensorData::new(values, shape), &tensor.device());
            let fresh = if tensor.is_require_grad() {
                fresh.require_grad()
            } else {
                fresh
            };
            Param::from_mapped_value(id, fresh, mapper)
        }
    }
    module.map(&mut Init {
        seed,
        stream,
        path: Vec::new(),
        fan_in: 1,
    })
}

/// Losses of one iteration (from its last critic and generator steps).
#[derive(Debug, Clone, Default)]
pub struct IterationStats {
    pub iteration: u64,
    /// Critic's Wasserstein estimate: mean D(real) - mean D(fake).
    pub wasserstein: f32,
    pub penalty: f32,
    pub generator_loss: f32,
    /// The learned period K per axis, in axis order (rows, columns; depth first for volumes).
    pub k: Vec<f32>,
    pub iterations_per_second: f32,
    /// Where the iteration's time went.
    pub times: StepTimes,
}

/// Seconds spent in each part of an iteration (summed over its steps).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimes {
    /// Real crops and the critic's fake crops (generator forward without gradient).
    pub critic_data: f64,
    /// Critic on real and fake crops, and the exact gradient penalty.
    pub critic_forward: f64,
    pub critic_backward: f64,
    pub critic_update: f64,
    /// Generator forward with gradient, and the critic on its output.
    pub generator_forward: f64,
    pub generator_backward: f64,
    pub generator_update: f64,
}

/// Points per generator evaluation when training on flex (see [`Trainer::fake_values`]).
pub const FLEX_TRAIN_CHUNK: usize = 4096;

/// A training run: networks, optimisers, exemplar and run folder.
pub struct Trainer {
    pub config: TrainConfig,
    exemplar: Exemplar,
    source: ExemplarSource,
    /// The maps of a map-set exemplar (stored in every model file, so synth writes one file each).
    maps: Option<MapSet>,
    /// The guidance line of a guided run (`config.guide`, parsed once).
    guide: Option<Guide>,
    run_dir: PathBuf,
    device: Device,
    generator: Generator,
    critic: RunCritic,
    adam_generator: Adam,
    adam_critic: Adam,
    /// Iterations completed.
    pub iteration: u64,
}

/// Checkpoint metadata keys of the training state.
const TRAIN_CONFIG_KEY: &str = "train_config";
const ITERATION_KEY: &str = "iteration";
const EXEMPLAR_KEY: &str = "exemplar";
const FINGERPRINT_KEY: &str = "exemplar_fingerprint";
const CRITIC_CONFIG_KEY: &str = "critic_config";

/// Loads the exemplar and applies the config's resize.
pub fn load_exemplar(path: &Path, resize: f64) -> Result<Exemplar> {
    apply_resize(crate::io::read_exemplar(path)?, resize)
}

fn apply_resize(exemplar: Exemplar, resize: f64) -> Result<Exemplar> {
    if resize == 1.0 {
        return Ok(exemplar);
    }
    let w = (exemplar.width as f64 * resize).round().max(1.0) as usize;
    let h = (exemplar.height as f64 * resize).round().max(1.0) as usize;
    Ok(exemplar.resized(w, h))
}

/// What a run learns from: one image, or a set of aligned material maps.
#[derive(Debug, Clone, PartialEq)]
pub enum ExemplarSource {
    Image(PathBuf),
    Maps(MapFiles),
    /// A signed-distance volume (`.npy`).
    Volume(PathBuf),
}

impl From<&Path> for ExemplarSource {
    fn from(p: &Path) -> Self {
        p.to_path_buf().into()
    }
}

impl From<&PathBuf> for ExemplarSource {
    fn from(p: &PathBuf) -> Self {
        p.clone().into()
    }
}

impl From<PathBuf> for ExemplarSource {
    /// A `.npy` file is a volume; anything else an image.
    fn from(p: PathBuf) -> Self {
        let npy = crate::io::extension(&p) == "npy";
        if npy { Self::Volume(p) } else { Self::Image(p) }
    }
}

impl From<MapFiles> for ExemplarSource {
    fn from(m: MapFiles) -> Self {
        Self::Maps(m)
    }
}

impl ExemplarSource {
    /// Reads the exemplar (stacking a map set's channels; a volume as a truncated SDF) and
    /// applies the config's resize.
    pub fn load(&self, config: &TrainConfig) -> Result<(Exemplar, Option<MapSet>)> {
        let resize = config.resize;
        match self {
            Self::Image(path) => Ok((load_exemplar(path, resize)?, None)),
            Self::Volume(path) => Ok((
                crate::io::read_sdf_volume(path, config.sdf_scale)?.into_exemplar(),
                None,
            )),
            Self::Maps(files) => {
                let (exemplar, set) = files.load()?;
                Ok((apply_resize(exemplar, resize)?, Some(set)))
            }
        }
    }

    /// The file that names the exemplar in messages (a set's first map).
    pub fn main_path(&self) -> &Path {
        match self {
            Self::Image(path) | Self::Volume(path) => path,
            Self::Maps(files) => &files.files[0],
        }
    }

    /// For the run's checkpoint: absolute paths, so `--resume` works from any folder. A single
    /// image is its path; a map set is JSON.
    fn to_meta(&self) -> String {
        let absolute = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        match self {
            Self::Image(path) | Self::Volume(path) => absolute(path).to_string_lossy().into_owned(),
            Self::Maps(files) => serde_json::to_string(&MapFiles {
                files: files.files.iter().map(absolute).collect(),
                ..files.clone()
            })
            .expect("the map files serialise"),
        }
    }

    fn from_meta(meta: &str, checkpoint: &Path) -> Result<Self> {
        if meta.starts_with('{') {
            serde_json::from_str(meta).map(Self::Maps).map_err(|e| {
                input_error!(
                    "{}: unreadable exemplar map list ({e})",
                    checkpoint.display()
                )
            })
        } else {
            Ok(PathBuf::from(meta).into())
        }
    }
}

/// The critic's input: image crops (or a solid's slices), or volume cubes.
#[derive(Clone)]
pub enum Batch {
    /// `[batch, channels, crop, crop]`
    Image(Tensor<4>),
    /// `[batch, channels, crop, crop, crop]`
    Volume(Tensor<5>),
}

/// The run's critic: the 2D critic for images and solid textures, the 3D one for volumes.
/// Updates and checkpoints go to the inner module, so parameter paths are the same as a
/// plain critic's.
#[derive(Debug, Clone)]
pub enum RunCritic {
    Image(Critic),
    Volume(VolumeCritic),
}

impl RunCritic {
    /// The 2D critic, if this run has one.
    pub fn image(&self) -> Option<&Critic> {
        match self {
            Self::Image(c) => Some(c),
            Self::Volume(_) => None,
        }
    }

    /// Mean critic score of a batch.
    fn mean_score(&self, x: Batch) -> Tensor<1> {
        match (self, x) {
            (Self::Image(c), Batch::Image(x)) => c.forward(x).mean(),
            (Self::Volume(c), Batch::Volume(x)) => c.forward(x).mean(),
            _ => unreachable!("a run's batches are of its critic's kind"),
        }
    }

    fn gradient_penalty(
        &self,
        real: Batch,
        fake: Batch,
        alpha: Tensor<1>,
        lambda: f64,
    ) -> Tensor<1> {
        match (self, real, fake) {
            (Self::Image(c), Batch::Image(r), Batch::Image(f)) => {
                c.gradient_penalty(r, f, alpha, lambda)
            }
            (Self::Volume(c), Batch::Volume(r), Batch::Volume(f)) => {
                c.gradient_penalty(r, f, alpha, lambda)
            }
            _ => unreachable!("a run's batches are of its critic's kind"),
        }
    }

    fn no_grad(self) -> Self {
        match self {
            Self::Image(c) => Self::Image(c.no_grad()),
            Self::Volume(c) => Self::Volume(c.no_grad()),
        }
    }

    /// The gradient of `loss` with respect to the critic's parameters.
    fn gradients(&self, loss: Tensor<1>) -> GradientsParams {
        match self {
            Self::Image(c) => GradientsParams::from_grads(loss.backward(), c),
            Self::Volume(c) => GradientsParams::from_grads(loss.backward(), c),
        }
    }

    /// One Adam step.
    fn update(self, grads: GradientsParams, adam: &mut Adam) -> Self {
        match self {
            Self::Image(c) => Self::Image(adam.step(c, grads)),
            Self::Volume(c) => Self::Volume(adam.step(c, grads)),
        }
    }

    fn write_to(&self, checkpoint: &mut Checkpoint) {
        match self {
            Self::Image(c) => checkpoint::write_module(c, "critic", checkpoint),
            Self::Volume(c) => checkpoint::write_module(c, "critic", checkpoint),
        }
    }
}

impl Trainer {
    /// A fresh run. `device` is a plain device (flex or wgpu); training uses its autodiff form.
    pub fn new(
        config: TrainConfig,
        source: impl Into<ExemplarSource>,
        run_dir: &Path,
        device: &Device,
    ) -> Result<Self> {
        let source = source.into();
        let mut config = config;
        config.volume = matches!(source, ExemplarSource::Volume(_));
        let (exemplar, maps) = source.load(&config)?;
        config.validate(&exemplar, source.main_path())?;
        let guide = config.guide()?;
        let device = device.clone().autodiff();
        let generator = initialise(
            config.generator_config(exemplar.channels).init(&device),
            config.seed,
            stream::INIT_GENERATOR,
        );
        let critic = if config.volume {
            RunCritic::Volume(initialise(
                config.volume_critic_config().init(&device),
                config.seed,
                stream::INIT_CRITIC,
            ))
        } else {
            RunCritic::Image(initialise(
                config.critic_config(exemplar.channels).init(&device),
                config.seed,
                stream::INIT_CRITIC,
            ))
        };
        Ok(Self {
            adam_generator: Adam::new(config.lr, config.beta1, config.beta2),
            adam_critic: Adam::new(config.lr, config.beta1, config.beta2),
            config,
            exemplar,
            source,
            maps,
            guide,
            run_dir: run_dir.to_path_buf(),
            device,
            generator,
            critic,
            iteration: 0,
        })
    }

    /// Continues the run in `run_dir` from its `latest.ipfn`. `iterations`, if given, replaces
    /// the planned total.
    pub fn resume(run_dir: &Path, iterations: Option<u64>, device: &Device) -> Result<Self> {
        let latest = run_dir.join("latest.ipfn");
        if !latest.exists() {
            return Err(input_error!(
                "{}: no latest.ipfn to resume from; is this a training run folder?",
                run_dir.display()
            ));
        }
        let ckpt = Checkpoint::load(&latest)?;
        let mut config = TrainConfig::from_toml(ckpt.meta(TRAIN_CONFIG_KEY)?, &latest)?;
        if let Some(n) = iterations {
            config.iterations = n;
        }
        let source = ExemplarSource::from_meta(ckpt.meta(EXEMPLAR_KEY)?, &latest)?;
        let (exemplar, maps) = source.load(&config)?;
        if ckpt.meta(FINGERPRINT_KEY)? != exemplar.fingerprint().to_string() {
            return Err(input_error!(
                "{}: the exemplar changed since this run started; start a new run instead of resuming",
                source.main_path().display()
            ));
        }
        config.validate(&exemplar, source.main_path())?;
        let guide = config.guide()?;
        let device = device.clone().autodiff();
        let (gen_config, weights) = GeneratorWeights::read_from(&ckpt)?;
        if gen_config != config.generator_config(exemplar.channels) {
            return Err(input_error!(
                "{}: generator does not match the run's config",
                latest.display()
            ));
        }
        let generator = Generator::from_weights(&weights, &device);
        let critic = if config.volume {
            RunCritic::Volume(checkpoint::read_module(
                config.volume_critic_config().init(&device),
                "critic",
                &ckpt,
            )?)
        } else {
            RunCritic::Image(checkpoint::read_module(
                config.critic_config(exemplar.channels).init(&device),
                "critic",
                &ckpt,
            )?)
        };
        let mut adam_generator = Adam::new(config.lr, config.beta1, config.beta2);
        adam_generator.read_from("adam.generator", &ckpt, &device)?;
        let mut adam_critic = Adam::new(config.lr, config.beta1, config.beta2);
        adam_critic.read_from("adam.critic", &ckpt, &device)?;
        let iteration = ckpt
            .meta(ITERATION_KEY)?
            .parse()
            .map_err(|_| input_error!("{}: unreadable iteration count", latest.display()))?;
        Ok(Self {
            config,
            exemplar,
            source,
            maps,
            guide,
            run_dir: run_dir.to_path_buf(),
            device,
            generator,
            critic,
            adam_generator,
            adam_critic,
            iteration,
        })
    }

    /// The maps of a map-set run.
    pub fn maps(&self) -> Option<&MapSet> {
        self.maps.as_ref()
    }

    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    pub fn generator(&self) -> &Generator {
        &self.generator
    }

    pub fn critic(&self) -> &RunCritic {
        &self.critic
    }

    /// The current generator's config and host weights.
    pub fn model(&self) -> (GeneratorConfig, GeneratorWeights) {
        (
            self.config.generator_config(self.exemplar.channels),
            self.generator.weights(),
        )
    }

    /// The top-left pixel `(row, col)` of a random crop of the exemplar for sample `s`, drawn
    /// from stream `purpose`.
    fn crop_origin(&self, purpose: u64, s: usize, counters: &[u64]) -> (usize, usize) {
        let (crop, ex) = (self.config.crop, &self.exemplar);
        let draw = |axis: u64, range: usize| {
            let mut k = vec![purpose, s as u64, axis];
            k.extend_from_slice(counters);
            ((uniform(self.config.seed, &k) * range as f32) as usize).min(range - 1)
        };
        (draw(0, ex.height - crop + 1), draw(1, ex.width - crop + 1))
    }

    /// Random real cubes of a volume run for step `step` of the current iteration.
    ///
    /// # Shapes
    /// - output: `[batch, 1, crop, crop, crop]`
    pub fn real_volume_batch(&self, counters: &[u64]) -> Tensor<5> {
        let (b, s) = (self.config.batch, self.config.crop);
        let cg = 1 + self.config.density as usize; // + the density channel
        let n = s * s * s;
        let mut data = vec![0f32; b * cg * n];
        for (i, sample) in data.chunks_mut(cg * n).enumerate() {
            let origin = self.volume_crop_origin(stream::REAL_CROP, i, counters);
            for (row, values) in sample[..n].chunks_mut(s).zip(self.cube_rows(origin)) {
                row.copy_from_slice(values);
            }
            if self.config.density {
                let d = self.crop_density(origin);
                sample[n..].iter_mut().for_each(|v| *v = d);
            }
        }
        Tensor::from_data(TensorData::new(data, [b, cg, s, s, s]), &self.device)
    }

    /// The first voxel `(depth, row, col)` of a random cube of the volume exemplar for sample
    /// `s`, drawn from stream `purpose`.
    fn volume_crop_origin(
        &self,
        purpose: u64,
        s: usize,
        counters: &[u64],
    ) -> (usize, usize, usize) {
        let (crop, ex) = (self.config.crop, &self.exemplar);
        // Rows and columns as for an image crop; depth from a third draw of the stream.
        let (top, left) = self.crop_origin(purpose, s, counters);
        let mut k = vec![purpose, s as u64, 2];
        k.extend_from_slice(counters);
        let range = ex.depth - crop + 1;
        let front = ((uniform(self.config.seed, &k) * range as f32) as usize).min(range - 1);
        (front, top, left)
    }

    /// The generator's density input for the cube at `origin`: the mean |sdf| of its
    /// truncated SDF, through [`crate::synth::density_input`].
    fn crop_density(&self, origin: (usize, usize, usize)) -> f32 {
        let s = self.config.crop;
        let total: f64 = self
            .cube_rows(origin)
            .map(|row| row.iter().map(|v| v.abs() as f64).sum::<f64>())
            .sum();
        crate::synth::density_input((total / (s * s * s) as f64) as f32)
    }

    /// The rows of the exemplar's `crop`³ cube at `origin` (depth, row, col), in order: `crop²`
    /// slices of `crop` voxels.
    fn cube_rows(
        &self,
        (front, top, left): (usize, usize, usize),
    ) -> impl Iterator<Item = &[f32]> + '_ {
        let (s, ex) = (self.config.crop, &self.exemplar);
        (0..s * s).map(move |zy| {
            let from = ((front + zy / s) * ex.height + top + zy % s) * ex.width + left;
            &ex.values[from..from + s]
        })
    }

    /// The critic's real input of this run's kind.
    fn real(&self, counters: &[u64]) -> Batch {
        if self.config.volume {
            Batch::Volume(self.real_volume_batch(counters))
        } else {
            Batch::Image(self.real_batch(counters))
        }
    }

    /// Random real crops for step `step` of the current iteration.
    ///
    /// # Shapes
    /// - output: `[batch, channels, crop, crop]`
    pub fn real_batch(&self, counters: &[u64]) -> Tensor<4> {
        let (b, crop, c) = (self.config.batch, self.config.crop, self.exemplar.channels);
        let guide = &self.guide;
        let cg = c + guide.is_some() as usize; // + the guidance channel
        let ex = &self.exemplar;
        let mut data = vec![0f32; b * cg * crop * crop];
        for (s, sample) in data.chunks_mut(cg * crop * crop).enumerate() {
            let (top, left) = self.crop_origin(stream::REAL_CROP, s, counters);
            for ch in 0..c {
                for y in 0..crop {
                    for x in 0..crop {
                        sample[(ch * crop + y) * crop + x] =
                            ex.values[((top + y) * ex.width + left + x) * c + ch];
                    }
                }
            }
            if let Some(g) = guide {
                // The crop's slice of g over the whole exemplar.
                for y in 0..crop {
                    for x in 0..crop {
                        sample[(c * crop + y) * crop + x] =
                            g.at((top + y) as i64, (left + x) as i64, ex.width, ex.height);
                    }
                }
            }
        }
        Tensor::from_data(TensorData::new(data, [b, cg, crop, crop]), &self.device)
    }

    /// The guidance slice `[crop * crop]` of generated sample `s`: g over the exemplar at a
    /// random crop position (empty for an unguided run). For a density-controlled volume run:
    /// the density of a random real crop, at every point.
    fn fake_condition(&self, s: usize, counters: &[u64]) -> Vec<f32> {
        if self.config.density {
            let origin = self.volume_crop_origin(stream::GUIDE, s, counters);
            return vec![self.crop_density(origin); self.sample_points()];
        }
        let Some(g) = &self.guide else {
            return Vec::new();
        };
        let (crop, ex) = (self.config.crop, &self.exemplar);
        let (top, left) = self.crop_origin(stream::GUIDE, s, counters);
        (0..crop * crop)
            .map(|q| {
                g.at(
                    (top + q / crop) as i64,
                    (left + q % crop) as i64,
                    ex.width,
                    ex.height,
                )
            })
            .collect()
    }

    /// Points of one generated sample: `crop²` pixels, or `crop³` voxels for a volume run.
    fn sample_points(&self) -> usize {
        let crop = self.config.crop;
        if self.config.volume {
            crop * crop * crop
        } else {
            crop * crop
        }
    }

    /// The coordinates `[points, dims]` of generated sample `s` and its latent field.
    ///
    /// A crop's grid of pixel centres spans 2 units and is shifted by a random offset per
    /// axis. For a solid texture it lies in a random axis-aligned plane of the volume: the
    /// plane's axis sits at its random offset, and the crop's rows and columns run along the
    /// other two axes in order. For a volume it is a cube of `crop³` voxels.
    fn sample_coordinates(&self, s: usize, counters: &[u64]) -> (Vec<f32>, LatentField) {
        let cfg = &self.config;
        let dims = cfg.dims();
        let key = |purpose: u64, extra: u64| {
            let mut k = vec![purpose, s as u64, extra];
            k.extend_from_slice(counters);
            k
        };
        let shift: Vec<f32> = (0..dims as u64)
            .map(|axis| (uniform(cfg.seed, &key(stream::SHIFT, axis)) * 2.0 - 1.0) * cfg.shift)
            .collect();
        let field = LatentField::hashed(
            derive_seed(cfg.seed, &key(stream::LATENT, 0)),
            dims,
            cfg.latent_dim,
        )
        .with_sigma(cfg.sigma);
        let crop = cfg.crop;
        let step = 2.0 / crop as f32;
        let along = |i: usize, axis: usize| -1.0 + (i as f32 + 0.5) * step + shift[axis];
        let coords = if dims == 2 {
            (0..crop * crop)
                .flat_map(|q| [along(q / crop, 0), along(q % crop, 1)])
                .collect()
        } else if cfg.volume {
            // A cube of voxel centres.
            (0..crop * crop * crop)
                .flat_map(|q| {
                    [
                        along(q / (crop * crop), 0),
                        along(q / crop % crop, 1),
                        along(q % crop, 2),
                    ]
                })
                .collect()
        } else {
            let normal = ((uniform(cfg.seed, &key(stream::SLICE_AXIS, 0)) * 3.0) as usize).min(2);
            let (row_axis, col_axis) = match normal {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            let mut coords = vec![0f32; crop * crop * 3];
            for (q, p) in coords.chunks_exact_mut(3).enumerate() {
                p[normal] = shift[normal];
                p[row_axis] = along(q / crop, row_axis);
                p[col_axis] = along(q % crop, col_axis);
            }
            coords
        };
        (coords, field)
    }

    /// Generated crops: a crop's grid shifted by a random offset per sample, and a fresh
    /// latent field per sample.
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1 guidance), crop, crop]` on `device` (`generator`'s)
    pub fn fake_batch(
        &self,
        generator: &Generator,
        device: &Device,
        counters: &[u64],
    ) -> Tensor<4> {
        let cfg = &self.config;
        let (b, crop, c) = (cfg.batch, cfg.crop, self.exemplar.channels);
        let (values, guides) = self.fake_values(generator, device, counters);
        let image = values.reshape([b, crop, crop, c]).permute([0, 3, 1, 2]); // [b, c, crop, crop]
        if guides.is_empty() {
            return image;
        }
        // The critic sees the guidance the generator was given, as one more channel.
        let g = Tensor::<4>::from_data(TensorData::new(guides, [b, 1, crop, crop]), device);
        Tensor::cat(vec![image, g], 1) // [b, c + 1, crop, crop]
    }

    /// Generated cubes of a volume run, as [`Trainer::fake_batch`] makes crops.
    ///
    /// # Shapes
    /// - output: `[batch, channels, crop, crop, crop]` on `device`
    pub fn fake_volume_batch(
        &self,
        generator: &Generator,
        device: &Device,
        counters: &[u64],
    ) -> Tensor<5> {
        let cfg = &self.config;
        let (b, s, c) = (cfg.batch, cfg.crop, self.exemplar.channels);
        let (values, densities) = self.fake_values(generator, device, counters);
        let volume = values.reshape([b, s, s, s, c]).permute([0, 4, 1, 2, 3]); // [b, c, s, s, s]
        if densities.is_empty() {
            return volume;
        }
        // The critic sees the density the generator was given, as one more channel.
        let d = Tensor::<5>::from_data(TensorData::new(densities, [b, 1, s, s, s]), device);
        Tensor::cat(vec![volume, d], 1) // [b, c + 1, s, s, s]
    }

    /// The critic's input for generated samples of this run's kind.
    fn fake(&self, generator: &Generator, device: &Device, counters: &[u64]) -> Batch {
        if self.config.volume {
            Batch::Volume(self.fake_volume_batch(generator, device, counters))
        } else {
            Batch::Image(self.fake_batch(generator, device, counters))
        }
    }

    /// The generator at every point of every sample, and each point's guidance value (empty
    /// for an unguided run).
    ///
    /// # Shapes
    /// - output: `[batch * points, channels]` on `device`, and `[batch * points]`
    fn fake_values(
        &self,
        generator: &Generator,
        device: &Device,
        counters: &[u64],
    ) -> (Tensor<2>, Vec<f32>) {
        let cfg = &self.config;
        let (b, ld) = (cfg.batch, cfg.latent_dim);
        let guided = cfg.conditioned() as usize;
        let zw = ld + guided; // generator input after the encoding: latent, then g
        let (n, dims) = (self.sample_points(), cfg.dims());
        if device.clone().inner() != Device::flex() {
            return self.fake_values_on_device(generator, device, counters);
        }
        let mut coords = vec![0f32; b * n * dims];
        let mut latent = vec![0f32; b * n * zw];
        let mut guides = vec![0f32; b * n]; // kept for a conditioned run only
        coords
            .par_chunks_mut(n * dims)
            .zip(latent.par_chunks_mut(n * zw))
            .zip(guides.par_chunks_mut(n))
            .enumerate()
            .for_each(|(s, ((p, z), gs))| {
                let (sample, field) = self.sample_coordinates(s, counters);
                p.copy_from_slice(&sample);
                let u: Vec<f32> = p.iter().map(|v| v * cfg.latent_scale).collect();
                if guided == 0 {
                    field.fill(&u, z);
                } else {
                    let g = self.fake_condition(s, counters);
                    let mut zs = vec![0f32; n * ld];
                    field.fill(&u, &mut zs);
                    for q in 0..n {
                        z[q * zw..q * zw + ld].copy_from_slice(&zs[q * ld..(q + 1) * ld]);
                        z[q * zw + ld] = g[q];
                    }
                    gs.copy_from_slice(&g);
                }
            });
        if guided == 0 {
            guides.clear();
        }
        let p = Tensor::<2>::from_data(TensorData::new(coords, [b * n, dims]), device);
        let z = Tensor::<2>::from_data(TensorData::new(latent, [b * n, zw]), device);
        // The MLP in chunks of FLEX_TRAIN_CHUNK points, so each layer's activations (and, in
        // the backward pass, their gradients) stay in cache; the weight gradients sum over
        // the chunks.
        let values: Vec<Tensor<2>> = p
            .split(FLEX_TRAIN_CHUNK, 0)
            .into_iter()
            .zip(z.split(FLEX_TRAIN_CHUNK, 0))
            .map(|(p, z)| generator.forward(p, z)) // [chunk, c]
            .collect();
        (Tensor::cat(values, 0), guides) // [b * n, c]
    }

    /// [`Trainer::fake_values`] on a GPU: the same crops and fields, with the latent blend
    /// evaluated on the device from each sample's few lattice vectors ([`DeviceLattice`])
    /// instead of `latent_dim` floats per point sent from the host. (On flex the host blend
    /// is kept: it is as fast there, and gives the latent values the fused CPU evaluator gives.)
    ///
    /// # Shapes
    /// - output: `[batch * points, channels]` on `device`, and `[batch * points]`
    fn fake_values_on_device(
        &self,
        generator: &Generator,
        device: &Device,
        counters: &[u64],
    ) -> (Tensor<2>, Vec<f32>) {
        let cfg = &self.config;
        let b = cfg.batch;
        let (n, dims) = (self.sample_points(), cfg.dims());
        let mut coords = Vec::with_capacity(b * n * dims);
        let mut guides = Vec::new();
        let mut plans = Vec::with_capacity(b);
        for s in 0..b {
            let (p, field) = self.sample_coordinates(s, counters);
            // The box of lattice cells this crop touches (u = p * latent_scale, as on the device).
            let (mut lo, mut hi) = (vec![f32::INFINITY; dims], vec![f32::NEG_INFINITY; dims]);
            for q in p.chunks_exact(dims) {
                for d in 0..dims {
                    let u = q[d] * cfg.latent_scale;
                    lo[d] = lo[d].min(u);
                    hi[d] = hi[d].max(u);
                }
            }
            coords.extend_from_slice(&p);
            guides.extend(self.fake_condition(s, counters));
            plans.push((field, lo, hi));
        }
        let fields: Vec<(&LatentField, Vec<f32>, Vec<f32>)> = plans
            .iter()
            .map(|(f, lo, hi)| (f, lo.clone(), hi.clone()))
            .collect();
        let lattice = DeviceLattice::new(&fields, device);
        let sample = Tensor::<1, Int>::arange(0..b as i64, device)
            .reshape([b, 1])
            .expand([b, n])
            .reshape([b * n]); // [b * n]: the field of each point
        let p = Tensor::<2>::from_data(TensorData::new(coords, [b * n, dims]), device);
        let mut z = lattice.blend(p.clone().mul_scalar(cfg.latent_scale), Some(sample)); // [b * n, ld]
        if !guides.is_empty() {
            let g = Tensor::<2>::from_data(TensorData::new(guides.clone(), [b * n, 1]), device);
            z = Tensor::cat(vec![z, g], 1); // [b * n, ld + 1]
        }
        (generator.forward(p, z), guides) // [b * n, c]
    }

    /// The same crops as [`Trainer::fake_batch`], evaluated by the fused CPU generator (no
    /// gradient: for the critic's steps).
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1 guidance), crop, crop]` on the training device
    pub fn fake_batch_fused(&self, generator: &FusedGenerator, counters: &[u64]) -> Tensor<4> {
        let cfg = &self.config;
        let (b, crop, cg) = (
            cfg.batch,
            cfg.crop,
            self.exemplar.channels + cfg.conditioned() as usize,
        );
        let planar = self.fake_planar_fused(generator, counters);
        Tensor::from_data(TensorData::new(planar, [b, cg, crop, crop]), &self.device)
    }

    /// The critic's fake input of this run's kind, from the fused CPU generator.
    fn fake_fused(&self, generator: &FusedGenerator, counters: &[u64]) -> Batch {
        if !self.config.volume {
            return Batch::Image(self.fake_batch_fused(generator, counters));
        }
        let (b, s) = (self.config.batch, self.config.crop);
        let cg = self.exemplar.channels + self.config.density as usize;
        let planar = self.fake_planar_fused(generator, counters);
        Batch::Volume(Tensor::from_data(
            TensorData::new(planar, [b, cg, s, s, s]),
            &self.device,
        ))
    }

    /// Generated samples from the fused CPU generator, channel-planar.
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1 guidance), points]`
    fn fake_planar_fused(&self, generator: &FusedGenerator, counters: &[u64]) -> Vec<f32> {
        let cfg = &self.config;
        let (b, c) = (cfg.batch, self.exemplar.channels);
        let guided = cfg.conditioned() as usize;
        let cg = c + guided;
        let n = self.sample_points();
        let dims = cfg.dims();
        let scale = vec![cfg.latent_scale; dims];
        let mut points = vec![0f32; b * n * c]; // [b, n, c]
        let mut guides = vec![0f32; b * n]; // [b, n], used by a guided run only
        points
            .par_chunks_mut(n * c)
            .zip(guides.par_chunks_mut(n))
            .enumerate()
            .for_each(|(s, (out, gs))| {
                let (p, field) = self.sample_coordinates(s, counters);
                let g = self.fake_condition(s, counters);
                if !g.is_empty() {
                    gs.copy_from_slice(&g);
                }
                out.par_chunks_mut(CHUNK_POINTS * c)
                    .enumerate()
                    .for_each_init(Scratch::default, |scratch, (i, o)| {
                        let start = i * CHUNK_POINTS;
                        let count = o.len() / c;
                        let gi = if g.is_empty() {
                            &g[..]
                        } else {
                            &g[start..start + count]
                        };
                        generator.eval(
                            &p[start * dims..(start + count) * dims],
                            &field,
                            &scale,
                            gi,
                            o,
                            scratch,
                        );
                    });
            });
        let mut planar = vec![0f32; b * cg * n]; // [b, c (+ g), n]
        for s in 0..b {
            for q in 0..n {
                for ch in 0..c {
                    planar[(s * cg + ch) * n + q] = points[(s * n + q) * c + ch];
                }
                if guided == 1 {
                    planar[(s * cg + c) * n + q] = guides[s * n + q];
                }
            }
        }
        planar
    }

    /// Runs one iteration: critic steps, then generator steps.
    pub fn step(&mut self) -> IterationStats {
        let start = Instant::now();
        let it = self.iteration;
        let cfg = self.config.clone();
        let mut stats = IterationStats {
            iteration: it + 1,
            ..Default::default()
        };
        let times = &mut stats.times;
        // The generator is fixed during the critic's steps: on the CPU its fakes come from the
        // fused evaluator, several times faster than the framework's forward pass.
        let fused = self
            .device
            .clone()
            .inner()
            .eq(&Device::flex())
            .then(|| FusedGenerator::new(self.generator.weights()));
        for step in 0..cfg.critic_steps as u64 {
            let t = Instant::now();
            let real = self.real(&[it, step]);
            let counters = [stream::CRITIC_FAKE, it, step];
            let fake = match &fused {
                Some(g) => self.fake_fused(g, &counters),
                None => match self.fake(
                    &self.generator.valid(),
                    &self.device.clone().inner(),
                    &counters,
                ) {
                    Batch::Image(x) => Batch::Image(Tensor::from_inner(x)),
                    Batch::Volume(x) => Batch::Volume(Tensor::from_inner(x)),
                },
            };
            let alphas: Vec<f32> = (0..cfg.batch as u64)
                .map(|s| uniform(cfg.seed, &[stream::ALPHA, s, it, step]))
                .collect();
            let alpha = Tensor::<1>::from_data(TensorData::new(alphas, [cfg.batch]), &self.device);
            times.critic_data += t.elapsed().as_secs_f64();

            let t = Instant::now();
            let d_real = self.critic.mean_score(real.clone());
            let d_fake = self.critic.mean_score(fake.clone());
            let penalty = self
                .critic
                .gradient_penalty(real, fake, alpha, cfg.gp_lambda);
            let loss = d_fake.clone() - d_real.clone() + penalty.clone();
            stats.wasserstein = (d_real - d_fake).into_scalar::<f32>();
            stats.penalty = penalty.into_scalar::<f32>();
            times.critic_forward += t.elapsed().as_secs_f64();

            let t = Instant::now();
            let grads = self.critic.gradients(loss);
            times.critic_backward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            self.critic = self.critic.clone().update(grads, &mut self.adam_critic);
            times.critic_update += t.elapsed().as_secs_f64();
        }
        for step in 0..cfg.generator_steps as u64 {
            let t = Instant::now();
            let frozen = self.critic.clone().no_grad();
            let fake = self.fake(
                &self.generator,
                &self.device,
                &[stream::GENERATOR_FAKE, it, step],
            );
            let loss = frozen.mean_score(fake).neg();
            stats.generator_loss = loss.clone().into_scalar::<f32>();
            times.generator_forward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            let grads = GradientsParams::from_grads(loss.backward(), &self.generator);
            times.generator_backward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            self.generator = self.adam_generator.step(self.generator.clone(), grads);
            times.generator_update += t.elapsed().as_secs_f64();
        }
        self.iteration += 1;
        stats.k = self
            .generator
            .k
            .val()
            .try_into_vec_as::<f32>()
            .expect("K readable");
        stats.iterations_per_second = 1.0 / start.elapsed().as_secs_f32();
        stats
    }

    /// Writes `latest.ipfn` (full training state, also a synth-ready model) and
    /// `checkpoints/iter-NNNNNN.ipfn` (the generator alone). Both are written atomically.
    pub fn save_checkpoint(&self) -> Result<PathBuf> {
        let (gen_config, weights) = self.model();
        let mut model = Checkpoint::new();
        weights.write_to(&gen_config, &mut model);
        model
            .metadata
            .insert(TRAIN_CONFIG_KEY.into(), self.config.to_toml());
        model
            .metadata
            .insert(ITERATION_KEY.into(), self.iteration.to_string());
        if let Some(maps) = &self.maps {
            maps.write_to(&mut model);
        }
        let dir = self.run_dir.join("checkpoints");
        std::fs::create_dir_all(&dir)
            .map_err(|e| Error::Runtime(format!("{}: cannot create: {e}", dir.display())))?;
        let path = dir.join(format!("iter-{:06}.ipfn", self.iteration));
        model.save(&path)?;

        let mut state = model;
        let critic_config = if self.config.volume {
            serde_json::to_string(&self.config.volume_critic_config())
        } else {
            serde_json::to_string(&self.config.critic_config(self.exemplar.channels))
        };
        state
            .metadata
            .insert(CRITIC_CONFIG_KEY.into(), critic_config.expect("serialises"));
        state
            .metadata
            .insert(EXEMPLAR_KEY.into(), self.source.to_meta());
        state.metadata.insert(
            FINGERPRINT_KEY.into(),
            self.exemplar.fingerprint().to_string(),
        );
        self.critic.write_to(&mut state);
        self.adam_generator.write_to("adam.generator", &mut state);
        self.adam_critic.write_to("adam.critic", &mut state);
        state.save(&self.run_dir.join("latest.ipfn"))?;
        Ok(path)
    }

    /// Writes `previews/iter-NNNNNN.png`: a fixed-seed sample covering 4x the crop's area.
    pub fn save_preview(&self) -> Result<PathBuf> {
        let (config, weights) = self.model();
        let side = 2 * config.crop; // 4x the crop's area, in the model's pixels
        let crop = self.config.crop as i64;
        let mut synth = Synth::new(config, weights)
            .seed(derive_seed(self.config.seed, &[stream::PREVIEW]))
            .offset(-crop, -crop);
        if let Some(g) = self.guide.clone() {
            synth = synth.guide(g, side, side); // the training line over the preview's frame
        }
        let pixels = if self.config.dims() == 3 {
            // A solid texture or a volume previews its depth-0 slice; a density-controlled
            // volume, at the exemplar's mean density.
            if self.config.density {
                let mean = self.exemplar.values.iter().map(|v| v.abs()).sum::<f32>()
                    / self.exemplar.values.len() as f32;
                synth = synth.density(crate::synth::DensityRamp {
                    from: mean,
                    to: mean,
                    width: side,
                });
            }
            synth
                .volume_painter()?
                .render([0, -crop, -crop], 1, side, side)
        } else {
            synth.painter()?.render(0, 0, side, side)
        };
        let dir = self.run_dir.join("previews");
        std::fs::create_dir_all(&dir)
            .map_err(|e| Error::Runtime(format!("{}: cannot create: {e}", dir.display())))?;
        let path = dir.join(format!("iter-{:06}.png", self.iteration));
        // A map set previews its first map.
        let c = self.exemplar.channels;
        let shown = self.maps.as_ref().map_or(0..c, |m| m.ranges()[0].clone());
        let pixels: Vec<f32> = pixels
            .chunks_exact(c)
            .flat_map(|px| px[shown.clone()].iter().copied())
            .collect();
        write_png(&path, side, side, shown.len(), &pixels)?;
        Ok(path)
    }

    /// Creates the run folder and writes `config.toml`; keeps `metrics.csv` rows up to the
    /// current iteration (a resumed run drops rows written after its last checkpoint).
    pub fn prepare_run_dir(&self) -> Result<()> {
        let err = |p: &Path, e: std::io::Error| Error::Runtime(format!("{}: {e}", p.display()));
        std::fs::create_dir_all(&self.run_dir).map_err(|e| err(&self.run_dir, e))?;
        crate::io::write_atomic(
            &self.run_dir.join("config.toml"),
            self.config.to_toml().as_bytes(),
        )?;
        let metrics = self.run_dir.join("metrics.csv");
        let mut kept = metrics_header(self.config.dims());
        if let Ok(old) = std::fs::read_to_string(&metrics) {
            for line in old.lines().skip(1) {
                let it: u64 = line
                    .split(',')
                    .next()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(u64::MAX);
                if it <= self.iteration {
                    kept.push_str(line);
                    kept.push('\n');
                }
            }
        }
        crate::io::write_atomic(&metrics, kept.as_bytes())
    }

    /// Appends one row to `metrics.csv`.
    pub fn append_metrics(&self, s: &IterationStats) -> Result<()> {
        let path = self.run_dir.join("metrics.csv");
        let mut file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::Runtime(format!("{}: {e}", path.display())))?;
        let k: Vec<String> = s.k.iter().map(f32::to_string).collect();
        writeln!(
            file,
            "{},{},{},{},{},{}",
            s.iteration,
            s.wasserstein,
            s.penalty,
            s.generator_loss,
            k.join(","),
            s.iterations_per_second
        )
        .map_err(|e| Error::Runtime(format!("{}: {e}", path.display())))
    }
}

/// Header of `metrics.csv` for a run over `dims` axes: one K column per axis.
pub fn metrics_header(dims: usize) -> String {
    let k = if dims == 3 {
        "k_depth,k_rows,k_cols"
    } else {
        "k_rows,k_cols"
    };
    format!("iteration,wasserstein,penalty,generator_loss,{k},iterations_per_second\n")
}
