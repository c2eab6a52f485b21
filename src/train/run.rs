//! The run folder (`config.toml`, `latest.ipfn`, `checkpoints/`, `previews/`, `metrics.csv`,
//! `report.html`) and the training loop that fills it ([`Trainer::run`]), which the CLI and the
//! examples call.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::draws::stream;
use super::score::Score;
use super::step::IterationStats;
use super::{RunKind, Trainer};
use crate::checkpoint::{self, Checkpoint};
use crate::condition::DensityRamp;
use crate::error::{Error, Result};
use crate::io::write_png;
use crate::latent::derive_seed;
use crate::maps::MapSet;
use crate::synth::Synth;

/// Checkpoint metadata keys of the training state.
pub(super) const TRAIN_CONFIG_KEY: &str = "train_config";
pub(super) const ITERATION_KEY: &str = "iteration";
pub(super) const EXEMPLAR_KEY: &str = "exemplar";
pub(super) const FINGERPRINT_KEY: &str = "exemplar_fingerprint";
const CRITIC_CONFIG_KEY: &str = "critic_config";
/// Where the coarse critic and its optimiser's moments are stored (`coarse_stride` set).
pub(super) const COARSE_CRITIC_PREFIX: &str = "coarse_critic";
pub(super) const COARSE_ADAM_PREFIX: &str = "adam.coarse_critic";
/// The best score so far and its iteration (`"SCORE ITERATION"`, the score
/// [`super::score::Score::combined`]), so a resumed run keeps it. Runs from before the
/// structure measure stored SIFID alone under `best_sifid`, which is not comparable: a run
/// resumed from one starts with no best, and its first checkpoint writes `best.ipfn` again.
const BEST_KEY: &str = "best_score";

/// Iterations timed before a run with a time budget plans its length. The first is not timed:
/// it pays for warming up (buffers, caches). Early iterations are still slower than a CPU run's
/// average (a 15-minute run planned once ended at 818 s; from the first 3, at 844 s), so the
/// plan is renewed at every checkpoint.
pub const PLAN_AFTER: u64 = 20;

/// The best score stored in a run's checkpoint.
pub(super) fn read_best(checkpoint: &Checkpoint) -> Option<(f64, u64)> {
    let text = checkpoint.metadata.get(BEST_KEY)?;
    let (score, iteration) = text.split_once(' ')?;
    Some((score.parse().ok()?, iteration.parse().ok()?))
}

/// Which full training state a run resumes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunState {
    /// `latest.ipfn`, written at every checkpoint.
    Latest,
    /// `previous.ipfn`, the state of the checkpoint before `latest.ipfn`'s, kept for when
    /// `latest.ipfn` is damaged (a disk error, a file copied half-way).
    Previous,
}

impl RunState {
    pub fn file_name(self) -> &'static str {
        match self {
            RunState::Latest => "latest.ipfn",
            RunState::Previous => "previous.ipfn",
        }
    }
}

/// The error for a `latest.ipfn` that cannot be resumed, extended with what `previous.ipfn`
/// offers.
pub(super) fn offer_previous(run_dir: &Path, error: Error) -> Error {
    // Only a latest.ipfn that cannot be read is the file's fault (other refusals, such as a
    // changed exemplar, hold for previous.ipfn too).
    let latest = Some(RunState::Latest.file_name().as_ref());
    if error.path().is_none_or(|p| p.file_name() != latest) {
        return error;
    }
    let previous = run_dir.join(RunState::Previous.file_name());
    let iteration = Checkpoint::load(&previous)
        .ok()
        .and_then(|c| c.metadata.get(ITERATION_KEY).cloned());
    match iteration {
        Some(it) => crate::input_error!(
            "{error}; {} holds the full state at iteration {it}: resume from it with `ipfn train --resume {} --from-previous`",
            previous.display(),
            run_dir.display()
        ),
        None => error,
    }
}

/// Sets a damaged `latest.ipfn` aside (as `latest.ipfn.damaged`) and makes `previous.ipfn` the
/// latest state again, so a run resumed from it keeps one good state whatever happens next.
pub(super) fn restore_previous(run_dir: &Path) -> Result<()> {
    let latest = run_dir.join(RunState::Latest.file_name());
    let previous = run_dir.join(RunState::Previous.file_name());
    let failed = |e: std::io::Error| Error::Runtime(format!("{}: {e}", latest.display()));
    if latest.exists() {
        std::fs::rename(&latest, run_dir.join("latest.ipfn.damaged")).map_err(failed)?;
    }
    let bytes = std::fs::read(&previous)
        .map_err(|e| Error::Runtime(format!("{}: cannot read: {e}", previous.display())))?;
    crate::io::write_atomic(&latest, &bytes)
}

/// Makes `previous.ipfn` the current `latest.ipfn` (a hard link, else a copy), before a new
/// `latest.ipfn` replaces it: the run folder always holds two full states.
fn keep_previous(run_dir: &Path) -> Result<()> {
    let latest = run_dir.join(RunState::Latest.file_name());
    if !latest.exists() {
        return Ok(());
    }
    let previous = run_dir.join(RunState::Previous.file_name());
    let link = run_dir.join(".previous.ipfn.link");
    let _ = std::fs::remove_file(&link);
    let linked = std::fs::hard_link(&latest, &link).and_then(|_| std::fs::rename(&link, &previous));
    // Renaming a link onto a name of the same file does nothing and leaves the link.
    let _ = std::fs::remove_file(&link);
    if linked.is_err() {
        let bytes = std::fs::read(&latest)
            .map_err(|e| Error::Runtime(format!("{}: cannot read: {e}", latest.display())))?;
        crate::io::write_atomic(&previous, &bytes)?;
    }
    Ok(())
}

/// How [`Trainer::run`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunEnd {
    /// The planned iterations are done.
    Finished,
    /// The stop flag was raised: the iteration in progress finished and a checkpoint was saved.
    Stopped,
}

impl Trainer {
    /// Trains until `config.iterations` or until `stop` is raised, appending `metrics.csv`,
    /// saving checkpoints (scored, the best kept as `best.ipfn`) and previews on schedule (and a
    /// checkpoint when stopped), and calling `on_iteration` after each iteration. With a time
    /// budget (`config.time`) the run plans its length after [`PLAN_AFTER`] iterations and ends
    /// when the budget is spent. Prepares the run folder first. A failure after a checkpoint
    /// (a full disk, a lost mount) says that the checkpoint is whole and how to continue.
    pub fn run(
        &mut self,
        stop: &AtomicBool,
        on_iteration: impl FnMut(&Trainer, &IterationStats),
    ) -> Result<RunEnd> {
        self.train(stop, on_iteration).map_err(|e| match e {
            Error::Runtime(m) if self.run_dir.join("latest.ipfn").exists() => Error::Runtime(format!(
                "{m}; the last checkpoint is intact: once the cause is fixed (a full disk: free space), continue with `ipfn train --resume {}`",
                self.run_dir.display()
            )),
            e => e,
        })
    }

    fn train(
        &mut self,
        stop: &AtomicBool,
        mut on_iteration: impl FnMut(&Trainer, &IterationStats),
    ) -> Result<RunEnd> {
        self.prepare_run_dir()?;
        if self.lock.is_none() {
            self.lock = Some(crate::io::lock::RunLock::acquire(&self.run_dir)?);
        }
        let budget = self.config.time_budget()?;
        let (clock, first, cap) = (Instant::now(), self.iteration, self.config.iterations);
        let mut warm = None; // the clock after the first iteration
        while self.iteration < self.config.iterations {
            let mut stats = self.step();
            let it = self.iteration;
            let warm = *warm.get_or_insert_with(|| clock.elapsed());
            if let Some(budget) = budget {
                self.follow_budget(budget, clock.elapsed(), warm, it - first, cap)?;
            }
            let (total, cfg) = (self.config.iterations, &self.config);
            let stopped = stop.load(Ordering::SeqCst);
            let checkpoint = it.is_multiple_of(cfg.checkpoint_every) || it == total || stopped;
            let preview = it.is_multiple_of(cfg.preview_every) || it == total;
            let score = if checkpoint { self.score()? } else { None };
            if let Some(s) = &score {
                (stats.sifid, stats.structure) = (Some(s.sifid), Some(s.structure));
                stats.repeat = Some(s.repeat);
                stats.map_structure = s.maps.clone();
            }
            self.append_metrics(&stats)?;
            if checkpoint {
                self.keep_if_best(score.as_ref().map(Score::combined))?;
                self.save_checkpoint()?;
            }
            if preview {
                self.save_preview()?;
            }
            // After the iteration's files are written: a caller sees its checkpoint and preview.
            on_iteration(self, &stats);
            // A stop asked for by the caller (or a signal) during the callback: this iteration
            // is the last, so it is kept.
            if !checkpoint && stop.load(Ordering::SeqCst) {
                let score = self.score()?;
                self.keep_if_best(score.as_ref().map(Score::combined))?;
                self.save_checkpoint()?;
                self.report("stopped");
                return Ok(RunEnd::Stopped);
            }
            if stopped {
                self.report("stopped");
                return Ok(RunEnd::Stopped);
            }
        }
        self.report("finished");
        Ok(RunEnd::Finished)
    }

    /// Writes `report.html`; a failure (a full disk) is a warning: the run itself is saved.
    fn report(&self, state: &str) {
        if let Err(e) = crate::report::write_report(&self.run_dir, state) {
            eprintln!("warning: report.html not written: {e}");
        }
    }

    /// A time budget: after [`PLAN_AFTER`] iterations, and again at each checkpoint,
    /// `iterations` becomes what fits in the rest of the budget at the speed of the iterations
    /// after the first (`warm` is the clock after the first; at most `cap`, the run's own
    /// count), and `time` is cleared, so that a resumed run continues the same iterations to the
    /// count of its last checkpoint; a spent budget ends the run now.
    fn follow_budget(
        &mut self,
        budget: Duration,
        elapsed: Duration,
        warm: Duration,
        done: u64,
        cap: u64,
    ) -> Result<()> {
        // Re-planned at each checkpoint from the speed so far, unless the learning rate's
        // schedule ends with the planned total (`lr_decay`): then the first plan stands.
        let replan = done > PLAN_AFTER
            && self.config.lr_decay == 0.0
            && self.iteration.is_multiple_of(self.config.checkpoint_every);
        let planned = if elapsed >= budget {
            Some(self.iteration)
        } else if (self.config.time.is_some() && done == PLAN_AFTER) || replan {
            let per_iteration = (elapsed - warm).as_secs_f64() / (done - 1) as f64;
            let more = ((budget - elapsed).as_secs_f64() / per_iteration) as u64;
            Some((self.iteration + more).min(cap))
        } else {
            None
        };
        if let Some(total) = planned {
            self.config.iterations = total;
            self.config.time = None;
            crate::io::write_atomic(
                &self.run_dir.join("config.toml"),
                self.config.to_toml().as_bytes(),
            )?;
        }
        Ok(())
    }

    /// Writes `best.ipfn` (the generator alone) when `score` ([`super::score::Score::combined`])
    /// beats the best so far.
    fn keep_if_best(&mut self, score: Option<f64>) -> Result<()> {
        let Some(score) = score.filter(|s| s.is_finite()) else {
            return Ok(());
        };
        if self.best.is_some_and(|(best, _)| best <= score) {
            return Ok(());
        }
        self.best = Some((score, self.iteration));
        self.model_file().save(&self.run_dir.join("best.ipfn"))
    }

    /// The current generator as a model file, with the run's config and map set.
    fn model_file(&self) -> Checkpoint {
        let (gen_config, weights) = self.model();
        let mut model = Checkpoint::new();
        weights.write_to(&gen_config, &mut model);
        let meta = &mut model.metadata;
        meta.insert(TRAIN_CONFIG_KEY.into(), self.config.to_toml());
        meta.insert(ITERATION_KEY.into(), self.iteration.to_string());
        if let Some((score, iteration)) = self.best {
            meta.insert(BEST_KEY.into(), format!("{score} {iteration}"));
        }
        if let Some(maps) = &self.maps {
            maps.write_to(&mut model);
        }
        model
    }

    /// Writes `latest.ipfn` (full training state, also a synth-ready model) and
    /// `checkpoints/iter-NNNNNN.ipfn` (the generator alone). Both are written atomically.
    pub fn save_checkpoint(&self) -> Result<PathBuf> {
        let model = self.model_file();
        let path = create_dir(&self.run_dir.join("checkpoints"))?
            .join(format!("iter-{:06}.ipfn", self.iteration));
        model.save(&path)?;

        let mut state = model;
        let critic_config = self
            .config
            .critic_config(&self.kind, self.exemplar.channels);
        let meta = &mut state.metadata;
        meta.insert(
            CRITIC_CONFIG_KEY.into(),
            serde_json::to_string(&critic_config).expect("serialises"),
        );
        meta.insert(EXEMPLAR_KEY.into(), self.source.to_meta());
        meta.insert(
            FINGERPRINT_KEY.into(),
            self.exemplar.fingerprint().to_string(),
        );
        if self.average.is_some() {
            let trained = self.generator.weights();
            trained.write_named(
                super::average::TRAINED_PREFIX,
                &self.generator_config(),
                &mut state,
            );
        }
        checkpoint::write_module(&self.critic, "critic", &mut state);
        self.adam_generator.write_to("adam.generator", &mut state);
        self.adam_critic.write_to("adam.critic", &mut state);
        if let Some(coarse) = &self.coarse {
            checkpoint::write_module(&coarse.critic, COARSE_CRITIC_PREFIX, &mut state);
            coarse.adam.write_to(COARSE_ADAM_PREFIX, &mut state);
        }
        keep_previous(&self.run_dir)?;
        state.save(&self.run_dir.join(RunState::Latest.file_name()))?;
        Ok(path)
    }

    /// Writes `previews/iter-NNNNNN.png`: a fixed-seed sample covering 4x the area of the
    /// widest crop a critic judges. A solid texture or a volume previews its depth-0 slice (a
    /// density-controlled volume at the exemplar's mean density); a map set its first map.
    pub fn save_preview(&self) -> Result<PathBuf> {
        let (config, weights) = self.model();
        // 4x the area of the widest crop a critic judges (the coarse critic's, where the run
        // has one), in the model's pixels, so the preview shows what the critics see.
        let side = 2 * config.crop * self.stride(super::coarse::Scale::Coarse);
        let crop = self.config.crop as i64;
        let mut synth =
            Synth::new(config, weights).seed(derive_seed(self.config.seed, &[stream::PREVIEW]));
        let (origin, shape) = match &self.kind {
            RunKind::Image { guide } => {
                synth = synth.offset(&[-crop, -crop]);
                if let Some(g) = guide.clone() {
                    synth = synth.guide(g, [side, side]); // the training line over the frame
                }
                (vec![0, 0], vec![side, side])
            }
            RunKind::Solid | RunKind::Volume { .. } => {
                if let RunKind::Volume { density: true } = self.kind {
                    let values = &self.exemplar.values;
                    let mean = values.iter().map(|v| v.abs()).sum::<f32>() / values.len() as f32;
                    synth = synth.density(DensityRamp {
                        from: mean,
                        to: mean,
                        width: side,
                    });
                }
                (vec![0, -crop, -crop], vec![1, side, side])
            }
        };
        let pixels = synth.painter()?.render(&origin, &shape);
        let path = create_dir(&self.run_dir.join("previews"))?
            .join(format!("iter-{:06}.png", self.iteration));
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
        create_dir(&self.run_dir)?;
        crate::io::write_atomic(
            &self.run_dir.join("config.toml"),
            self.config.to_toml().as_bytes(),
        )?;
        let metrics = self.run_dir.join("metrics.csv");
        let mut kept = metrics_header(self.kind.generator_axes(), self.maps.as_ref());
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
        let err = |e: std::io::Error| Error::Runtime(format!("{}: {e}", path.display()));
        let mut file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(err)?;
        let k: Vec<String> = s.k.iter().map(f32::to_string).collect();
        let sifid = s.sifid.map(|v| v.to_string()).unwrap_or_default();
        let repeat = s.repeat.map(|v| v.to_string()).unwrap_or_default();
        let structure = s.structure.map(|v| v.to_string()).unwrap_or_default();
        // A map set's per-map columns: empty where the row has no score.
        let maps = self.maps.as_ref().map_or(0, |set| set.maps.len());
        let per_map: String = (0..maps)
            .map(|i| {
                let v = s.map_structure.get(i).map(f64::to_string);
                format!(",{}", v.unwrap_or_default())
            })
            .collect();
        writeln!(
            file,
            "{},{},{},{},{},{},{sifid},{repeat},{structure}{per_map}",
            s.iteration,
            s.wasserstein,
            s.penalty,
            s.generator_loss,
            k.join(","),
            s.iterations_per_second
        )
        .map_err(err)
    }
}

pub(super) fn create_dir(dir: &Path) -> Result<&Path> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Runtime(format!("{}: cannot create: {e}", dir.display())))?;
    Ok(dir)
}

/// Header of `metrics.csv` for a run over `dims` axes: one K column per axis, and for a map
/// set one structure column per map (`structure_NAME`). Columns added later go at the end, so
/// the rows of a run from before them still read (as empty there).
pub fn metrics_header(dims: usize, maps: Option<&MapSet>) -> String {
    let k = if dims == 3 {
        "k_depth,k_rows,k_cols"
    } else {
        "k_rows,k_cols"
    };
    let per_map: String = maps
        .map(|set| {
            let column = |name: &str| -> String {
                let safe = name
                    .chars()
                    .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' });
                format!(",structure_{}", safe.collect::<String>())
            };
            set.maps.iter().map(|m| column(&m.name)).collect()
        })
        .unwrap_or_default();
    format!(
        "iteration,wasserstein,penalty,generator_loss,{k},iterations_per_second,sifid,repeat,structure{per_map}\n"
    )
}
