//! Every training setting ([`TrainConfig`], the TOML file) and the run's kind ([`RunKind`]),
//! decided once; the flags that override the settings are [`super::overrides`].

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::condition::Guide;
use crate::critic::CriticConfig;
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::generator::GeneratorConfig;
use crate::input_error;

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
    /// The last this fraction of the run's iterations takes the learning rate linearly down to
    /// 0 (`0.5`: the second half), so the schedule ends with the planned total (or the time
    /// budget's plan); 0 keeps it constant.
    #[serde(skip_serializing_if = "is_zero")]
    pub lr_decay: f64,
    /// The generator's K learns at `k_lr` times `lr` (its own rate: K is two numbers that the
    /// whole image's layout hangs on); 1 is the paper's single rate.
    #[serde(skip_serializing_if = "is_unit")]
    pub k_lr: f64,
    /// Weight of the diversity hinge ([`super::diversity`]): each generated crop and its twin
    /// under a fresh latent field must differ as much as two crops of the exemplar do; 0 (the
    /// paper) leaves diversity to the critic.
    #[serde(skip_serializing_if = "is_zero")]
    pub diversity: f64,
    /// The coarse critic ([`super::coarse`]): a second critic judges crops painted at every
    /// `coarse_stride`-th pixel of a crop this many times wider, so it sees the pattern's
    /// arrangement over several periods; 0 (the paper) trains the fine critic alone.
    #[serde(skip_serializing_if = "is_zero_usize")]
    pub coarse_stride: usize,
    /// Coarse to fine: for this first fraction of the run's iterations the one critic judges
    /// crops painted every `coarse_stride`-th pixel (the arrangement over several periods),
    /// then the fine crops (the detail); no second critic. 0: no schedule (with
    /// `coarse_stride`, the two critics side by side).
    #[serde(skip_serializing_if = "is_zero")]
    pub coarse_until: f64,
    pub beta1: f64,
    pub beta2: f64,
    /// Weight of the gradient penalty.
    pub gp_lambda: f64,
    /// The penalty runs on every this-many-th critic step, weighted by `penalty_every ·
    /// gp_lambda` (lazy regularisation, Karras et al. 2020); 1 runs it on every step.
    #[serde(skip_serializing_if = "is_one")]
    pub penalty_every: usize,
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
    /// Initial K per generator axis (rows, cols; depth first in 3D). Unset: 1, as the paper.
    /// `ipfn train` sets it from the exemplar's measured period ([`super::recipe`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub k_init: Option<Vec<f32>>,
    /// Train on the first channel only (and keep alpha): for a gray photo stored as RGB, whose
    /// channels are all equal. `ipfn train` sets it when it finds one.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub gray: bool,
    /// A time budget such as `15m`, `90s` or `1h30m`: after a few iterations the run plans how
    /// many fit in the budget, sets `iterations` to that, and clears `time`; it also stops when
    /// the budget is spent. Unset: `iterations` alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    /// Samples scored (SIFID and structure distance against the exemplar, at its size) at each
    /// checkpoint of an image run; the best-scoring generator is kept as `best.ipfn`. 0: none.
    pub score_samples: usize,
    /// Decay per iteration of the moving average of the generator's weights that the run
    /// scores, saves and paints ([`super::average`]); 0 paints the trained weights themselves.
    #[serde(skip_serializing_if = "is_zero")]
    pub average: f64,
}

fn is_zero_usize(v: &usize) -> bool {
    *v == 0
}

fn is_one(v: &usize) -> bool {
    *v == 1
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_unit(v: &f64) -> bool {
    *v == 1.0
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
            lr_decay: 0.0,
            k_lr: 1.0,
            diversity: 0.0,
            coarse_stride: 0,
            coarse_until: 0.0,
            beta1: 0.5,
            beta2: 0.9,
            gp_lambda: 10.0,
            penalty_every: 1,
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
            k_init: None,
            gray: false,
            time: None,
            score_samples: 2,
            average: 0.0,
        }
    }
}

/// What a run learns and how its critic sees it. Decided once from the config and the exemplar
/// ([`TrainConfig::run_kind`]); the trainer matches on it, so an illegal combination (a guided
/// volume, a density-controlled image) cannot be written.
#[derive(Debug, Clone, PartialEq)]
pub enum RunKind {
    /// A 2D generator against 2D crops of an image or map set, guided or not.
    Image { guide: Option<Guide> },
    /// A 3D generator whose random axis-aligned slices the 2D critic compares with 2D crops.
    Solid,
    /// A 3D generator against cubes of an SDF volume, density-controlled or not.
    Volume { density: bool },
}

impl RunKind {
    /// Coordinate axes of the generator.
    pub fn generator_axes(&self) -> usize {
        match self {
            Self::Image { .. } => 2,
            Self::Solid | Self::Volume { .. } => 3,
        }
    }

    /// Axes of the exemplar's crops and of the critic.
    pub fn crop_axes(&self) -> usize {
        match self {
            Self::Image { .. } | Self::Solid => 2,
            Self::Volume { .. } => 3,
        }
    }

    /// Whether the generator takes a condition input (and the critic one more channel).
    pub fn conditioned(&self) -> bool {
        matches!(
            self,
            Self::Image { guide: Some(_) } | Self::Volume { density: true }
        )
    }
}

impl TrainConfig {
    /// Parses TOML; `source` names the file in errors.
    pub fn from_toml(text: &str, source: &Path) -> Result<Self> {
        let config: Self = toml::from_str(text).map_err(|e| {
            let msg = e.message().replace('\n', " ");
            crate::file_error!(&source, "{msg}")
        })?;
        // Values are checked here too, so an error names the file that holds them.
        if let Ok(kind) = config.run_kind() {
            config
                .check_values(&kind)
                .map_err(|e| crate::file_error!(&source, "{e}"))?;
        }
        Ok(config)
    }

    /// Reads a TOML config file, and the keys it sets.
    pub fn from_file(path: &Path) -> Result<(Self, std::collections::BTreeSet<String>)> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| crate::file_error!(&path, "cannot read: {e}"))?;
        Ok((Self::from_toml(&text, path)?, Self::keys_in(&text)))
    }

    /// The keys a TOML config sets (a recipe keeps them as given).
    pub fn keys_in(text: &str) -> std::collections::BTreeSet<String> {
        text.parse::<toml::Table>()
            .map(|t| t.keys().cloned().collect())
            .unwrap_or_default()
    }

    /// The time budget, if `time` is set.
    pub fn time_budget(&self) -> Result<Option<std::time::Duration>> {
        self.time.as_deref().map(parse_duration).transpose()
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("config serialises")
    }

    /// The run's kind from the config's flags (`volume` is set from the exemplar's format).
    /// This is the one place where their combinations are checked.
    pub fn run_kind(&self) -> Result<RunKind> {
        let guide = self.guide.as_deref().map(str::parse).transpose()?;
        match (self.volume, self.solid, guide, self.density) {
            (true, false, None, density) => Ok(RunKind::Volume { density }),
            (true, ..) => Err(input_error!(
                "a volume exemplar takes neither --solid nor --guide"
            )),
            (false, _, _, true) => Err(input_error!(
                "--density is for volumes (.npy); for images, --guide conditions on a direction"
            )),
            (false, true, Some(_), _) => Err(input_error!(
                "--solid and --guide cannot be combined: guidance is defined over a 2D exemplar's frame"
            )),
            (false, true, None, false) => Ok(RunKind::Solid),
            (false, false, guide, false) => Ok(RunKind::Image { guide }),
        }
    }

    /// The generator of a run of `kind` on an exemplar of `channels` channels.
    pub fn generator_config(&self, kind: &RunKind, channels: usize) -> GeneratorConfig {
        GeneratorConfig::new()
            .with_dims(kind.generator_axes())
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
            .with_guidance(kind.conditioned() as usize)
    }

    /// The critic sees the exemplar's channels and, for a conditioned run, the condition.
    pub fn critic_config(&self, kind: &RunKind, channels: usize) -> CriticConfig {
        CriticConfig::new(channels + kind.conditioned() as usize, self.crop)
            .with_axes(kind.crop_axes())
            .with_widths(self.critic_widths.clone())
    }

    /// Checks the numbers, and that the exemplar is large enough for the crop.
    /// The bounds on iterations, batch and crop ([`MAX_ITERATIONS`] and the others).
    fn check_sizes(&self, kind: &RunKind) -> Result<()> {
        let limits = [
            (
                "iterations",
                self.iterations as usize,
                MAX_ITERATIONS as usize,
            ),
            ("batch", self.batch, MAX_BATCH),
            ("crop", self.crop, MAX_CROP),
            ("critic_steps", self.critic_steps, 1000),
            ("generator_steps", self.generator_steps, 1000),
            ("coarse_stride", self.coarse_stride, MAX_COARSE_STRIDE),
        ];
        for (name, value, max) in limits {
            if value > max {
                return Err(input_error!("{name} = {value}: at most {max}"));
            }
        }
        // The crops, and the critic's first (widest) activation at half the crop's side.
        let first = self.critic_widths.first().copied().unwrap_or(1);
        let activation = (0..kind.crop_axes())
            .try_fold(self.batch.saturating_mul(first), |n, _| {
                n.checked_mul(self.crop / 2)
            })
            .filter(|&n| n <= 4 * MAX_BATCH_VALUES);
        let values = (0..kind.crop_axes())
            .try_fold(self.batch, |n, _| n.checked_mul(self.crop))
            .filter(|&n| n <= MAX_BATCH_VALUES)
            .and(activation);
        if values.is_none() {
            return Err(input_error!(
                "batch {} of {}-pixel crops over {} axes: more than {MAX_BATCH_VALUES} values per batch (or 4x that in the critic's first layer); use a smaller batch, crop or critic",
                self.batch,
                self.crop,
                kind.crop_axes()
            ));
        }
        Ok(())
    }

    pub fn validate(&self, kind: &RunKind, exemplar: &Exemplar, path: &Path) -> Result<()> {
        self.check_values(kind)?;
        self.validate_for(kind, exemplar, path)
    }

    /// The checks that need no exemplar: counts at least 1, rates positive and finite, sizes
    /// within bounds, a valid time budget and K.
    pub fn check_values(&self, kind: &RunKind) -> Result<()> {
        let positive = [
            ("iterations", self.iterations as usize),
            ("batch", self.batch),
            ("critic_steps", self.critic_steps),
            ("generator_steps", self.generator_steps),
            ("penalty_every", self.penalty_every),
            ("checkpoint_every", self.checkpoint_every as usize),
            ("preview_every", self.preview_every as usize),
            ("log_every", self.log_every as usize),
        ];
        for (name, v) in positive {
            if v == 0 {
                return Err(input_error!("{name} = 0: must be at least 1"));
            }
        }
        let finite = [
            self.lr,
            self.gp_lambda,
            self.shift as f64,
            self.resize,
            self.beta1,
            self.beta2,
        ];
        if !(self.lr > 0.0 && self.gp_lambda >= 0.0 && self.shift >= 0.0 && self.resize > 0.0)
            || finite.iter().any(|v| !v.is_finite())
        {
            return Err(input_error!(
                "lr and resize must be positive, gp_lambda and shift not negative, and all finite"
            ));
        }
        if !(0.0..=1.0).contains(&self.lr_decay) {
            return Err(crate::setting_error!(
                "lr_decay",
                self.lr_decay,
                "the decayed fraction of the run is from 0 (constant) to 1, e.g. 0.5"
            ));
        }
        if !(self.k_lr >= 0.0 && self.k_lr.is_finite()) {
            return Err(crate::setting_error!(
                "k_lr",
                self.k_lr,
                "K's learning rate, a multiple of lr, is finite and not negative, e.g. 10"
            ));
        }
        if !(self.diversity >= 0.0 && self.diversity.is_finite()) {
            return Err(crate::setting_error!(
                "diversity",
                self.diversity,
                "the diversity hinge's weight is finite and not negative, e.g. 1"
            ));
        }
        if !(0.0..1.0).contains(&self.coarse_until) {
            return Err(crate::setting_error!(
                "coarse_until",
                self.coarse_until,
                "the coarse part of the run is a fraction from 0 (none) to below 1, e.g. 0.5"
            ));
        }
        if self.coarse_until > 0.0 && self.coarse_stride < 2 {
            return Err(input_error!(
                "coarse_until = {} needs the stride of the coarse crops: give coarse_stride (--coarse-stride N, 2 or more)",
                self.coarse_until
            ));
        }
        if !(0.0..1.0).contains(&self.average) {
            return Err(crate::setting_error!(
                "average",
                self.average,
                "the moving average's decay is at least 0 (off) and below 1, e.g. 0.99"
            ));
        }
        self.check_sizes(kind)?;
        self.time_budget()?;
        if let Some(k) = &self.k_init
            && (k.len() != kind.generator_axes() || k.iter().any(|v| !v.is_finite() || *v == 0.0))
        {
            return Err(input_error!(
                "k_init = {k:?}: one finite, non-zero K per generator axis ({})",
                kind.generator_axes()
            ));
        }
        // The networks' shapes (the exemplar's channels only size the output layer).
        self.generator_config(kind, 1).validate()?;
        self.critic_config(kind, 1).validate()
    }

    fn validate_for(&self, kind: &RunKind, exemplar: &Exemplar, path: &Path) -> Result<()> {
        if let RunKind::Volume { .. } = kind {
            if self.coarse_stride > 0 {
                return Err(crate::file_error!(
                    &path,
                    "coarse_stride is for images and solid textures; a volume trains with its one critic (coarse_stride = 0)",
                ));
            }
            if self.resize != 1.0 {
                return Err(crate::file_error!(
                    &path,
                    "a volume exemplar takes neither --solid, --guide nor --resize",
                ));
            }
            if !self.sdf_scale.is_finite() || self.sdf_scale <= 0.0 {
                return Err(input_error!("sdf_scale must be positive"));
            }
        }
        self.critic_config(kind, exemplar.channels).validate()?;
        self.generator_config(kind, exemplar.channels).validate()?;
        let shape = exemplar.shape(kind.crop_axes());
        let smallest = shape.iter().copied().min().unwrap_or(0);
        if smallest < self.crop {
            let sizes: Vec<String> = shape.iter().rev().map(usize::to_string).collect();
            let (what, unit, resize) = match kind {
                RunKind::Volume { .. } => ("volume", "voxel", ""),
                _ => ("exemplar", "pixel", " or --resize"),
            };
            return Err(crate::file_error!(
                &path,
                "the {what} is {}, smaller than the {} {unit} crop; use a smaller --crop (a multiple of 16, e.g. {}){resize}",
                sizes.join("x"),
                self.crop,
                (smallest / 16 * 16).max(16),
            ));
        }
        let span = (self.crop - 1) * self.coarse_stride.max(1) + 1;
        if smallest < span {
            return Err(crate::file_error!(
                &path,
                "the exemplar is {}x{}, smaller than a coarse crop of {} points every {} pixels ({span} pixels); use a smaller --coarse-stride (at most {})",
                exemplar.width,
                exemplar.height,
                self.crop,
                self.coarse_stride,
                super::coarse::largest_stride(smallest, self.crop),
            ));
        }
        Ok(())
    }
}

/// The longest time budget: a year.
const MAX_TIME_SECONDS: f64 = 365.0 * 24.0 * 3600.0;

/// Upper bounds on the settings that size memory and time, so a typing slip or a hostile config
/// is a one-line error instead of an allocation that takes the machine down.
pub const MAX_ITERATIONS: u64 = 1_000_000_000;
pub const MAX_BATCH: usize = 4096;
pub const MAX_CROP: usize = 2048;
pub const MAX_COARSE_STRIDE: usize = 64;
/// The most values in one batch of crops (`batch x crop^axes`): 2^26, 256 MiB of floats per
/// channel before the critic's activations.
pub const MAX_BATCH_VALUES: usize = 1 << 26;

/// Parses a duration such as `15m`, `90s`, `1h30m` or `2h` (a bare number is seconds).
pub fn parse_duration(text: &str) -> Result<std::time::Duration> {
    let bad = || {
        crate::setting_error!(
            "--time",
            text,
            "expected a duration such as 15m, 90s or 1h30m"
        )
    };
    let mut seconds = 0f64;
    let mut number = String::new();
    for ch in text.trim().chars() {
        match ch {
            '0'..='9' | '.' => number.push(ch),
            'h' | 'm' | 's' => {
                let unit = match ch {
                    'h' => 3600.0,
                    'm' => 60.0,
                    _ => 1.0,
                };
                seconds += number.parse::<f64>().map_err(|_| bad())? * unit;
                number.clear();
            }
            _ => return Err(bad()),
        }
    }
    if !number.is_empty() {
        seconds += number.parse::<f64>().map_err(|_| bad())?;
    }
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(bad());
    }
    if seconds > MAX_TIME_SECONDS {
        return Err(crate::setting_error!(
            "--time",
            text,
            "at most 8760h (a year); a run that long should checkpoint and resume"
        ));
    }
    Ok(std::time::Duration::from_secs_f64(seconds))
}
