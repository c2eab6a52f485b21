//! Training (paper §3.3): WGAN-GP between random crops of the exemplar and generated crops.
//!
//! One path for every kind of run ([`RunKind`]: image, solid texture, volume; guided or
//! density-controlled), split by idea:
//! - [`config`]: every setting and the run's kind; [`overrides`]: the flags that override them;
//! - [`data`]: the exemplar and its random crops (over 2 or 3 axes), the critic's real input;
//! - [`fakes`]: generated crops, the critic's fake input;
//! - [`diversity`]: a hinge that keeps generated crops as varied as the exemplar's;
//! - [`coarse`]: a second critic on strided crops several periods wide, for the arrangement;
//! - [`draws`]: every random draw's stream, and the networks' initial weights;
//! - [`step`]: one iteration; on the CPU the critic's and the generator's steps are fused ([`crate::critic::fused`], [`crate::generator::backward`]),
//!   elsewhere they go through burn's autodiff;
//! - [`average`]: the moving average of the generator's weights that a run can paint;
//! - [`run`]: the run folder, checkpoints, previews, metrics, and the training loop;
//! - [`adam`]: the optimiser, whose moments live in the checkpoint (one host pass per parameter
//!   on the CPU).

pub mod adam;
pub mod average;
pub mod coarse;
pub mod config;
pub mod data;
pub mod diversity;
pub mod draws;
pub mod fakes;
pub mod overrides;
pub mod recipe;
pub mod request;
pub mod run;
pub mod score;
pub mod step;

use std::path::{Path, PathBuf};

use burn::prelude::*;

pub use coarse::Scale;
pub use config::{DEFAULT_SDF_SCALE, RunKind, TrainConfig};
pub use data::{ExemplarSource, load_exemplar};
pub use fakes::FLEX_TRAIN_CHUNK;
pub use overrides::TrainOverrides;
pub use run::{RunEnd, RunState, metrics_header};
pub use step::{IterationStats, StepTimes};

use crate::checkpoint::{self, Checkpoint};
use crate::critic::Critic;
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::generator::{Generator, GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::io::lock::RunLock;
use crate::maps::MapSet;
use adam::Adam;
use draws::{initialise, stream};
use run::{EXEMPLAR_KEY, FINGERPRINT_KEY, ITERATION_KEY, TRAIN_CONFIG_KEY};

/// A training run: networks, optimisers, exemplar and run folder.
pub struct Trainer {
    pub config: TrainConfig,
    kind: RunKind,
    exemplar: Exemplar,
    source: ExemplarSource,
    /// The maps of a map-set exemplar (stored in every model file, so synth writes one file each).
    maps: Option<MapSet>,
    run_dir: PathBuf,
    device: Device,
    generator: Generator,
    /// The moving average of the generator's weights (`config.average > 0`), which the run
    /// scores, saves and paints.
    average: Option<GeneratorWeights>,
    critic: Critic,
    /// The coarse critic (`coarse_stride` set; [`coarse`]).
    coarse: Option<coarse::CoarseCritic>,
    adam_generator: Adam,
    adam_critic: Adam,
    /// Iterations completed.
    pub iteration: u64,
    /// The best score so far ([`score::Score::combined`], SIFID × structure distance; lower is
    /// better) and its iteration.
    best: Option<(f64, u64)>,
    /// The run folder's lock, taken by `start`, `resume` or the first `run`.
    lock: Option<RunLock>,
    /// Steps through the framework's autodiff even on the CPU ([`Trainer::framework_steps`]).
    framework_only: bool,
    /// The most memory a fused generator step keeps its forward passes in
    /// ([`Trainer::keep_passes_within`]).
    kept_passes_bytes: usize,
    /// The diversity hinge's target distance, measured on first use
    /// ([`Trainer::diversity_target`]).
    diversity_target: std::sync::OnceLock<f32>,
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
        let kind = config
            .run_kind()
            .map_err(|e| volume_error(e, &config, &source))?;
        let (exemplar, maps) = source.load(&config)?;
        config.validate(&kind, &exemplar, source.main_path())?;
        let device = device.clone().autodiff();
        let channels = exemplar.channels;
        let mut generator = initialise(
            config.generator_config(&kind, channels).init(&device),
            config.seed,
            stream::INIT_GENERATOR,
        );
        if let Some(k) = &config.k_init {
            let mut weights = generator.weights();
            weights.k = k.clone();
            generator = Generator::from_weights(&weights, &device);
        }
        let critic = initialise(
            config.critic_config(&kind, channels).init(&device),
            config.seed,
            stream::INIT_CRITIC,
        );
        let average = (config.average > 0.0).then(|| generator.weights());
        let coarse = coarse::has_coarse_critic(&config).then(|| coarse::CoarseCritic {
            critic: initialise(
                config.critic_config(&kind, channels).init(&device),
                config.seed,
                stream::INIT_COARSE_CRITIC,
            ),
            adam: Adam::new(config.lr, config.beta1, config.beta2),
        });
        Ok(Self {
            average,
            coarse,
            adam_generator: Adam::new(config.lr, config.beta1, config.beta2),
            adam_critic: Adam::new(config.lr, config.beta1, config.beta2),
            config,
            kind,
            exemplar,
            source,
            maps,
            run_dir: run_dir.to_path_buf(),
            device,
            generator,
            critic,
            iteration: 0,
            best: None,
            lock: None,
            framework_only: false,
            kept_passes_bytes: fakes::KEPT_PASSES_BYTES,
            diversity_target: Default::default(),
        })
    }

    /// Takes this fresh run's folder: refuses one that already holds a run, then creates and
    /// locks it.
    pub fn start(mut self) -> Result<Self> {
        let run_dir = self.run_dir.clone();
        if run_dir.join("latest.ipfn").exists() {
            return Err(input_error!(
                "{} already holds a run; continue it with `ipfn train --resume {}` or start another with --out DIR",
                run_dir.display(),
                run_dir.display()
            ));
        }
        run::create_dir(&run_dir)?;
        self.lock = Some(RunLock::acquire(&run_dir)?);
        Ok(self)
    }

    /// Continues the run in `run_dir` with the flags of `overrides` that a resumed run may
    /// change (the total iterations, how often to checkpoint, preview and log); the others are
    /// refused.
    ///
    /// `state` is the run's `latest.ipfn`, or its `previous.ipfn` (the full state one checkpoint
    /// earlier) where `latest.ipfn` is damaged.
    pub fn resume_with(
        run_dir: &Path,
        state: RunState,
        overrides: &TrainOverrides,
        device: &Device,
    ) -> Result<Self> {
        let fixed = overrides.fixed_on_resume();
        if !fixed.is_empty() {
            return Err(input_error!(
                "{} cannot change when resuming (they change the model or its random draws); start a new run with --out instead",
                fixed.join(", ")
            ));
        }
        let mut trainer = Self::resume_from(run_dir, state, overrides.iterations, device)?;
        overrides.apply(&mut trainer.config);
        if overrides.time.is_some() && overrides.iterations.is_none() {
            // A new budget plans the rest of the run afresh.
            trainer.config.iterations = recipe::BUDGET_ITERATIONS;
        }
        trainer.config.time_budget()?;
        Ok(trainer)
    }

    /// Continues the run in `run_dir` from its `latest.ipfn`. `iterations`, if given, replaces
    /// the planned total.
    pub fn resume(run_dir: &Path, iterations: Option<u64>, device: &Device) -> Result<Self> {
        Self::resume_from(run_dir, RunState::Latest, iterations, device)
    }

    /// Continues the run in `run_dir` from its `latest.ipfn` or `previous.ipfn`. A damaged
    /// `latest.ipfn` is refused with a line that says whether `previous.ipfn` is intact.
    pub fn resume_from(
        run_dir: &Path,
        state: RunState,
        iterations: Option<u64>,
        device: &Device,
    ) -> Result<Self> {
        let file = run_dir.join(state.file_name());
        if !file.exists() && state == RunState::Latest {
            return Err(crate::file_error!(
                &run_dir,
                "no latest.ipfn to resume from; is this a training run folder?",
            ));
        }
        let lock = RunLock::acquire(run_dir)?;
        // What the state file says (its config, its exemplar's fingerprint) decides the
        // refusal: name the file.
        let resumed = Self::resume_file(run_dir, &file, lock, iterations, device)
            .map_err(|e| e.in_file(&file));
        match (resumed, state) {
            (Err(e), RunState::Latest) if e.is_input() => Err(run::offer_previous(run_dir, e)),
            (Ok(trainer), RunState::Previous) => {
                // The first checkpoint would make the damaged latest.ipfn the new
                // previous.ipfn: put previous.ipfn in its place first.
                run::restore_previous(run_dir)?;
                Ok(trainer)
            }
            (resumed, _) => resumed,
        }
    }

    fn resume_file(
        run_dir: &Path,
        latest: &Path,
        lock: RunLock,
        iterations: Option<u64>,
        device: &Device,
    ) -> Result<Self> {
        let ckpt = Checkpoint::load(latest)?;
        let mut config = TrainConfig::from_toml(ckpt.meta(TRAIN_CONFIG_KEY)?, latest)?;
        if let Some(n) = iterations {
            config.iterations = n;
        }
        let source = ExemplarSource::from_meta(ckpt.meta(EXEMPLAR_KEY)?, latest)?;
        // A fresh trainer of the same config and exemplar, whose state is then read back.
        let mut trainer = Self::new(config, source, run_dir, device)?;
        if ckpt.meta(FINGERPRINT_KEY)? != trainer.exemplar.fingerprint().to_string() {
            // The state file and the exemplar disagree: the state file is named, as for every
            // other refusal of a resume, and the exemplar after it.
            return Err(crate::file_error!(
                latest,
                "{}: the exemplar changed since this run started; start a new run instead of resuming",
                trainer.source.main_path().display()
            ));
        }
        trainer.read_state(&ckpt, latest)?;
        trainer.lock = Some(lock);
        Ok(trainer)
    }

    /// Reads the networks, the optimisers' moments, the iteration and the best score from a
    /// checkpoint of this run.
    fn read_state(&mut self, ckpt: &Checkpoint, latest: &Path) -> Result<()> {
        let (config, device) = (&self.config, &self.device);
        let channels = self.exemplar.channels;
        let (gen_config, model) = GeneratorWeights::read_from(ckpt)?;
        if gen_config != config.generator_config(&self.kind, channels) {
            return Err(crate::file_error!(
                latest,
                "generator does not match the run's config",
            ));
        }
        // With an average, the model is the average and the trained weights are stored apart.
        let (weights, average) = if config.average > 0.0 {
            let (_, trained) = GeneratorWeights::read_named(average::TRAINED_PREFIX, ckpt)?;
            (trained, Some(model))
        } else {
            (model, None)
        };
        let critic_config = config.critic_config(&self.kind, channels);
        self.critic = checkpoint::read_module(critic_config.init(device), "critic", ckpt)?;
        self.adam_generator
            .read_from("adam.generator", ckpt, device)?;
        self.adam_critic.read_from("adam.critic", ckpt, device)?;
        if let Some(coarse) = &mut self.coarse {
            let prefix = run::COARSE_CRITIC_PREFIX;
            coarse.critic = checkpoint::read_module(critic_config.init(device), prefix, ckpt)?;
            coarse
                .adam
                .read_from(run::COARSE_ADAM_PREFIX, ckpt, device)?;
        }
        self.iteration = ckpt
            .meta(ITERATION_KEY)?
            .parse()
            .map_err(|_| crate::file_error!(latest, "unreadable iteration count"))?;
        self.best = run::read_best(ckpt);
        self.generator = Generator::from_weights(&weights, device);
        self.average = average;
        Ok(())
    }

    /// Takes every step through the framework's autodiff, as on a GPU, even on the CPU (where
    /// steps are otherwise fused: [`crate::critic::fused`], [`crate::generator::backward`]).
    /// For tests and benches that compare the two.
    pub fn framework_steps(mut self) -> Self {
        self.framework_only = true;
        self
    }

    /// Keeps a fused generator step's forward passes (which paint its crops) for its backward
    /// only while they take at most `bytes` (default [`fakes::KEPT_PASSES_BYTES`]); beyond, the
    /// backward runs them again. 0 always runs them again. For tests that compare the two.
    pub fn keep_passes_within(mut self, bytes: usize) -> Self {
        self.kept_passes_bytes = bytes;
        self
    }

    /// Whether steps run fused on the CPU.
    fn fused_steps(&self) -> bool {
        !self.framework_only && self.device.clone().inner() == Device::flex()
    }

    /// What this run learns.
    pub fn kind(&self) -> &RunKind {
        &self.kind
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

    pub fn critic(&self) -> &Critic {
        &self.critic
    }

    /// The model the run paints: its config and host weights (the moving average of the
    /// generator's weights when the run keeps one, else the generator's own).
    pub fn model(&self) -> (GeneratorConfig, GeneratorWeights) {
        let weights = match &self.average {
            Some(average) => average.clone(),
            None => self.generator.weights(),
        };
        (self.generator_config(), weights)
    }

    fn generator_config(&self) -> GeneratorConfig {
        self.config
            .generator_config(&self.kind, self.exemplar.channels)
    }
}

/// Where a run's folder goes unless told: `runs/<exemplar file stem>`.
pub fn default_run_dir(exemplar: &Path) -> PathBuf {
    let stem = exemplar
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "run".into());
    Path::new("runs").join(stem)
}

/// A volume's refusal names the file, as other exemplar errors do.
fn volume_error(e: crate::Error, config: &TrainConfig, source: &ExemplarSource) -> crate::Error {
    match config.volume {
        true => e.in_file(source.main_path()),
        false => e,
    }
}
