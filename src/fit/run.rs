//! The fitting loop and its run folder: `latest.ipfn` (the network, the stage, the step, Adam's
//! moments: `--resume` continues bit for bit), `metrics.csv`, and at the end `tile.ipfn` (the
//! model `ipfn synth` paints) and the tile image.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::fused::Stage;
use super::network::PeriodicNet;
use super::target::{StageTarget, seam_mask};
use super::{FitConfig, TilePainter, psnr};
use crate::checkpoint::Checkpoint;
use crate::error::{Error, Result};
use crate::exemplar::Exemplar;
use crate::input_error;
use crate::io::lock::RunLock;
use crate::latent::derive_seed;
use crate::maps::MapSet;

const CONFIG_KEY: &str = "fit_config";
const STAGE_KEY: &str = "fit_stage";
const ITERATION_KEY: &str = "fit_iteration";
const FINGERPRINT_KEY: &str = "photo_fingerprint";
/// The share of a time budget kept for checkpoints, the stages' targets and the outputs.
const BUDGET_RESERVE: f64 = 0.08;

/// How a call to [`Fitter::run`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitEnd {
    /// Every stage ran its steps.
    Done,
    /// A signal asked to stop; the state is saved.
    Stopped,
    /// The time budget ran out before the planned steps; the state is saved.
    BudgetSpent,
}

/// Where a fit stands, for a progress line.
#[derive(Debug, Clone)]
pub struct Progress {
    pub stage: usize,
    pub stages: usize,
    pub iteration: u64,
    pub iterations: u64,
    /// The last step's loss (mean per pixel).
    pub loss: f64,
    /// PSNR of the stages so far against the photo, at checkpoints.
    pub psnr: Option<f64>,
}

/// Adam over a flat vector (betas 0.9, 0.999, as MR-Net's PyTorch defaults).
#[derive(Debug, Clone, PartialEq)]
struct FlatAdam {
    m: Vec<f32>,
    v: Vec<f32>,
    steps: u64,
}

impl FlatAdam {
    fn new(n: usize) -> Self {
        Self {
            m: vec![0.0; n],
            v: vec![0.0; n],
            steps: 0,
        }
    }

    fn step(&mut self, params: &mut [f32], grad: &[f32], lr: f64) {
        let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8f64);
        self.steps += 1;
        let c1 = 1.0 - b1.powi(self.steps as i32);
        let c2 = 1.0 - b2.powi(self.steps as i32);
        let step = (lr * c2.sqrt() / c1) as f32;
        let (b1, b2) = (b1 as f32, b2 as f32);
        let eps = (eps * c2.sqrt()) as f32;
        for (((p, g), m), v) in params
            .iter_mut()
            .zip(grad)
            .zip(&mut self.m)
            .zip(&mut self.v)
        {
            *m = b1 * *m + (1.0 - b1) * g;
            *v = b2 * *v + (1.0 - b2) * g * g;
            *p -= step * *m / (v.sqrt() + eps);
        }
    }
}

/// A fit in progress.
pub struct Fitter {
    pub config: FitConfig,
    pub net: PeriodicNet,
    /// The stage being fitted (`stages` once all are done).
    pub stage: usize,
    /// Steps done in the current stage.
    pub iteration: u64,
    adam: FlatAdam,
    photo: Exemplar,
    mask: Option<Vec<f32>>,
    maps: Option<MapSet>,
    run_dir: PathBuf,
    _lock: RunLock,
    target: Option<StageTarget>,
    device: Option<burn::tensor::Device>,
}

/// The photo (or stacked maps), its map set and its mask.
type Inputs = (Exemplar, Option<MapSet>, Option<Vec<f32>>);

/// The [`Inputs`] `config` names.
fn load_inputs(config: &FitConfig) -> Result<Inputs> {
    let (photo, maps) = match (&config.photo, &config.maps) {
        (Some(path), _) => (crate::exemplar::read_exemplar(path)?, None),
        (None, Some(files)) => {
            let (photo, set) = files.load()?;
            (photo, Some(set))
        }
        (None, None) => return Err(input_error!("no photo to fit: `ipfn fit PHOTO`")),
    };
    let mask = match &config.mask {
        None => None,
        Some(path) => {
            let m = crate::exemplar::read_exemplar(path)?;
            if (m.width, m.height) != (photo.width, photo.height) {
                return Err(crate::file_error!(
                    &path,
                    "the mask is {}x{} but the photo is {}x{}; give a mask of the photo's size",
                    m.width,
                    m.height,
                    photo.width,
                    photo.height,
                ));
            }
            let c = m.channels;
            // The mean of the colour channels, in [0, 1].
            let colour = if c == 2 || c == 4 { c - 1 } else { c };
            Some(
                m.values
                    .chunks_exact(c)
                    .map(|px| px[..colour].iter().sum::<f32>() / colour as f32 * 0.5 + 0.5)
                    .collect(),
            )
        }
    };
    Ok((photo, maps, mask))
}

impl Fitter {
    /// A new fit of the photo `config` names, in `run_dir` (created; refused if it holds a
    /// fit), on `device` (`None`: the fused CPU path).
    pub fn start(
        config: FitConfig,
        run_dir: &Path,
        device: Option<burn::tensor::Device>,
    ) -> Result<Self> {
        let (photo, maps, mask) = load_inputs(&config)?;
        let source = config
            .photo
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "the maps".into());
        config.validate([photo.height, photo.width], &source)?;
        if run_dir.join("latest.ipfn").exists() {
            return Err(input_error!(
                "{} already holds a fit; continue it with `ipfn fit --resume {}` or start another with --run DIR",
                run_dir.display(),
                run_dir.display()
            ));
        }
        std::fs::create_dir_all(run_dir)
            .map_err(|e| crate::file_error!(&run_dir, "cannot create: {e}"))?;
        let lock = RunLock::acquire(run_dir)?;
        Ok(Self::fresh(
            config,
            (photo, maps, mask),
            run_dir,
            lock,
            device,
        ))
    }

    /// A fit at its first step: the network as initialised, stage 0.
    fn fresh(
        config: FitConfig,
        (photo, maps, mask): Inputs,
        run_dir: &Path,
        lock: RunLock,
        device: Option<burn::tensor::Device>,
    ) -> Self {
        let shape = config.shape(
            config.period_for([photo.height, photo.width]),
            photo.channels,
        );
        let net = PeriodicNet::init(shape, config.seed);
        let adam = FlatAdam::new(net.params[0].len());
        Self {
            config,
            net,
            stage: 0,
            iteration: 0,
            adam,
            photo,
            mask,
            maps,
            run_dir: run_dir.to_path_buf(),
            _lock: lock,
            target: None,
            device,
        }
    }

    /// The fit saved in `run_dir`'s `latest.ipfn`, exactly where it stopped.
    pub fn resume(run_dir: &Path, device: Option<burn::tensor::Device>) -> Result<Self> {
        let path = run_dir.join("latest.ipfn");
        if !path.is_file() {
            return Err(crate::file_error!(
                &run_dir,
                "no latest.ipfn to resume from; is this a fit's run folder?",
            ));
        }
        let lock = RunLock::acquire(run_dir)?;
        let checkpoint = Checkpoint::load(&path)?;
        let file = path.display();
        let number = |key: &str| -> Result<u64> {
            checkpoint
                .meta(key)?
                .parse()
                .map_err(|_| input_error!("{file}: '{key}' is not a number: the file is damaged"))
        };
        let config: FitConfig = serde_json::from_str(checkpoint.meta(CONFIG_KEY)?)
            .map_err(|e| input_error!("{file}: not a fit's state ({e})"))?;
        let inputs = load_inputs(&config)?;
        if number(FINGERPRINT_KEY)? != inputs.0.fingerprint() {
            return Err(input_error!(
                "{file}: the photo has changed since this fit started; start a new fit with `ipfn fit PHOTO --run DIR`"
            ));
        }
        let mut fit = Self::fresh(config, inputs, run_dir, lock, device);
        fit.net = PeriodicNet::read_from(&checkpoint)?;
        fit.stage = number(STAGE_KEY)? as usize;
        let stages = fit.net.stages();
        if fit.stage >= stages {
            return Err(input_error!(
                "{file}: this fit is complete ({stages} of {stages} stages); its tile is {}; to fit again, start a new fit in another folder with `ipfn fit PHOTO --run NEW_DIR`",
                run_dir.join("tile.ipfn").display()
            ));
        }
        let n = fit.net.params[fit.stage].len();
        fit.adam = FlatAdam {
            m: checkpoint.tensor("adam.m", &[n])?.to_vec(),
            v: checkpoint.tensor("adam.v", &[n])?.to_vec(),
            steps: number(ITERATION_KEY)?,
        };
        fit.iteration = fit.adam.steps;
        Ok(fit)
    }

    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    pub fn photo(&self) -> &Exemplar {
        &self.photo
    }

    pub fn maps(&self) -> Option<&MapSet> {
        self.maps.as_ref()
    }

    /// The user's mask `[H, W]` in [0, 1], if any.
    pub fn mask(&self) -> Option<&[f32]> {
        self.mask.as_deref()
    }

    /// The tile's model file: the network (and map set) without the fitting state.
    pub fn model_file(&self) -> Checkpoint {
        let mut checkpoint = Checkpoint::new();
        self.net.write_to(&mut checkpoint);
        if let Some(maps) = &self.maps {
            maps.write_to(&mut checkpoint);
        }
        checkpoint
    }

    /// A painter of the stages fitted so far, one photo pixel per pixel.
    pub fn painter(&self) -> TilePainter {
        let mut painter = TilePainter::new(self.net.clone());
        painter.lod = (self.stage + 1).min(self.net.stages()) as f32;
        painter
    }

    /// Sets `config.iterations` from a time budget, by timing two steps of every stage (after one to warm up): the
    /// last stage gets `N` steps and each lower stage `N / 4` ([`FitConfig::stage_steps`]).
    /// Called before the first step of a new fit.
    pub fn plan(&mut self, budget: Duration) {
        let start = Instant::now();
        self.ensure_target();
        let stages = self.net.stages();
        let mut per_step = 0.0;
        for s in 0..stages {
            let _ = self.loss_and_gradient(s, 0); // warms the allocator and caches
            let t = Instant::now();
            for i in 1..3 {
                let _ = self.loss_and_gradient(s, i);
            }
            let share = if s + 1 == stages { 1.0 } else { 0.25 };
            per_step += share * t.elapsed().as_secs_f64() / 2.0;
        }
        let left = budget.as_secs_f64() * (1.0 - BUDGET_RESERVE) - start.elapsed().as_secs_f64();
        let steps = (left / per_step).max(10.0) as u64;
        self.config.iterations = FitConfig::stage_steps(steps, stages);
    }

    /// The steps of the current stage.
    pub fn stage_iterations(&self) -> u64 {
        let i = self
            .stage
            .min(self.config.iterations.len().saturating_sub(1));
        self.config.iterations.get(i).copied().unwrap_or(0)
    }

    /// Builds the current stage's targets: its level of the photo less the stages below.
    fn ensure_target(&mut self) {
        if self.target.is_some() || self.stage >= self.net.stages() {
            return;
        }
        let level = self.config.level(&self.photo, self.stage);
        let (h, w, c) = (self.photo.height, self.photo.width, self.photo.channels);
        let below = (self.stage > 0).then(|| {
            let shape = &self.net.shape;
            let mut positions = Vec::with_capacity(h * w * 2);
            for y in 0..h {
                for x in 0..w {
                    positions.extend([y as f32 + 0.5, x as f32 + 0.5]);
                }
            }
            let (mut values, mut tangents) = (vec![0f32; h * w * c], vec![0f32; h * w * 2 * c]);
            for s in 0..self.stage {
                let stage = Stage::new(
                    &shape.stages[s],
                    &self.net.params[s],
                    c,
                    shape.omega0,
                    shape.period,
                );
                let (v, t) = eval_with_tangents(&stage, &positions);
                values.iter_mut().zip(v).for_each(|(a, b)| *a += b);
                tangents.iter_mut().zip(t).for_each(|(a, b)| *a += b);
            }
            (values, tangents)
        });
        let lambda = seam_mask(h, w, self.config.seam_band_for([h, w]));
        let below = below.as_ref().map(|(v, t)| (v.as_slice(), t.as_slice()));
        self.target = Some(StageTarget::new(
            &level,
            below,
            lambda,
            self.mask.as_deref(),
        ));
    }

    /// The mean loss and gradient of stage `s`'s batch at step `step`.
    fn loss_and_gradient(&self, s: usize, step: u64) -> (f64, Vec<f32>) {
        let target = self.target.as_ref().expect("the stage's target is built");
        let batch = target.batch(
            self.config.batch,
            derive_seed(self.config.seed, &[s as u64]),
            step,
        );
        let shape = &self.net.shape;
        let stage = Stage::new(
            &shape.stages[s],
            &self.net.params[s],
            shape.channels,
            shape.omega0,
            shape.period,
        );
        let (loss, mut grad) = match &self.device {
            None => stage.loss_and_gradient(&batch.view()),
            Some(device) => super::reference::loss_and_gradient(&stage, &batch.view(), device),
        };
        let n = self.config.batch as f32;
        grad.iter_mut().for_each(|g| *g /= n);
        (loss / n as f64, grad)
    }

    /// Runs the remaining steps of every stage, checkpointing every `checkpoint_every` steps
    /// and at each stage's end, until done, `stop` is set, or `deadline` passes.
    pub fn run(
        &mut self,
        stop: &AtomicBool,
        deadline: Option<Instant>,
        mut progress: impl FnMut(&Progress),
    ) -> Result<FitEnd> {
        while self.stage < self.net.stages() {
            self.ensure_target();
            let total = self.stage_iterations();
            while self.iteration < total {
                if stop.load(Ordering::SeqCst) {
                    self.checkpoint(None)?;
                    return Ok(FitEnd::Stopped);
                }
                if deadline.is_some_and(|d| Instant::now() >= d) {
                    self.checkpoint(None)?;
                    return Ok(FitEnd::BudgetSpent);
                }
                let (loss, grad) = self.loss_and_gradient(self.stage, self.iteration);
                let t = self.iteration as f64 / total.max(1) as f64;
                let lr =
                    self.config.lr * (0.01 + 0.99 * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()));
                self.adam.step(&mut self.net.params[self.stage], &grad, lr);
                self.iteration += 1;
                let at_checkpoint = self.iteration.is_multiple_of(self.config.checkpoint_every)
                    || self.iteration == total;
                let psnr = if at_checkpoint {
                    Some(self.checkpoint(Some(loss))?)
                } else {
                    None
                };
                progress(&Progress {
                    stage: self.stage,
                    stages: self.net.stages(),
                    iteration: self.iteration,
                    iterations: total,
                    loss,
                    psnr,
                });
            }
            self.stage += 1;
            self.iteration = 0;
            self.target = None;
            if let Some(params) = self.net.params.get(self.stage) {
                self.adam = FlatAdam::new(params.len());
            }
            self.checkpoint(None)?;
        }
        Ok(FitEnd::Done)
    }

    /// Saves `latest.ipfn` and, given the step's loss, a `metrics.csv` row with the PSNR of
    /// the stages so far (returned; NaN without a loss).
    pub fn checkpoint(&self, loss: Option<f64>) -> Result<f64> {
        let mut checkpoint = self.model_file();
        let meta = &mut checkpoint.metadata;
        meta.insert(
            CONFIG_KEY.into(),
            serde_json::to_string(&self.config).expect("config serialises"),
        );
        meta.insert(STAGE_KEY.into(), self.stage.to_string());
        meta.insert(ITERATION_KEY.into(), self.iteration.to_string());
        meta.insert(FINGERPRINT_KEY.into(), self.photo.fingerprint().to_string());
        let n = self.adam.m.len();
        checkpoint.insert("adam.m", vec![n], self.adam.m.clone());
        checkpoint.insert("adam.v", vec![n], self.adam.v.clone());
        checkpoint.save(&self.run_dir.join("latest.ipfn"))?;
        let Some(loss) = loss else {
            return Ok(f64::NAN);
        };
        let (h, w, c) = (self.photo.height, self.photo.width, self.photo.channels);
        let tile = self.painter().render([0, 0], [h, w]);
        let score = psnr(&tile, &self.photo.values, c, |i| {
            self.mask.as_ref().is_none_or(|m| m[i] > 0.5)
        });
        let path = self.run_dir.join("metrics.csv");
        let new = !path.exists();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", path.display())))?;
        let header = if new {
            "stage,iteration,loss,psnr\n"
        } else {
            ""
        };
        writeln!(
            file,
            "{header}{},{},{loss:.6e},{score:.3}",
            self.stage, self.iteration
        )
        .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", path.display())))?;
        Ok(score)
    }
}

/// Values and tangents of a stage at `positions`, in parallel chunks on the CPU.
fn eval_with_tangents(stage: &Stage, positions: &[f32]) -> (Vec<f32>, Vec<f32>) {
    use rayon::prelude::*;
    let c = stage.channels;
    let n = positions.len() / 2;
    let (mut values, mut tangents) = (vec![0f32; n * c], vec![0f32; n * 2 * c]);
    let per = super::fused::CHUNK * 8;
    positions
        .par_chunks(2 * per)
        .zip(values.par_chunks_mut(per * c))
        .zip(tangents.par_chunks_mut(per * 2 * c))
        .for_each(|((p, v), t)| stage.eval(p, v, Some(t)));
    (values, tangents)
}
