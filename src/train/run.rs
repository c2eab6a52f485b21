//! The run folder (`config.toml`, `latest.ipfn`, `checkpoints/`, `previews/`, `metrics.csv`) and
//! the training loop that fills it ([`Trainer::run`]), which the CLI and the examples call.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use super::step::{IterationStats, stream};
use super::{RunKind, Trainer};
use crate::checkpoint::{self, Checkpoint};
use crate::condition::DensityRamp;
use crate::error::{Error, Result};
use crate::io::write_png;
use crate::latent::derive_seed;
use crate::synth::Synth;

/// Checkpoint metadata keys of the training state.
pub(super) const TRAIN_CONFIG_KEY: &str = "train_config";
pub(super) const ITERATION_KEY: &str = "iteration";
pub(super) const EXEMPLAR_KEY: &str = "exemplar";
pub(super) const FINGERPRINT_KEY: &str = "exemplar_fingerprint";
const CRITIC_CONFIG_KEY: &str = "critic_config";

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
    /// saving checkpoints and previews on schedule (and a checkpoint when stopped), and calling
    /// `on_iteration` after each iteration. Prepares the run folder first.
    pub fn run(
        &mut self,
        stop: &AtomicBool,
        mut on_iteration: impl FnMut(&Trainer, &IterationStats),
    ) -> Result<RunEnd> {
        self.prepare_run_dir()?;
        let (total, cfg) = (self.config.iterations, self.config.clone());
        while self.iteration < total {
            let stats = self.step();
            self.append_metrics(&stats)?;
            on_iteration(self, &stats);
            let it = self.iteration;
            let stopped = stop.load(Ordering::SeqCst);
            if it.is_multiple_of(cfg.checkpoint_every) || it == total || stopped {
                self.save_checkpoint()?;
            }
            if it.is_multiple_of(cfg.preview_every) || it == total {
                self.save_preview()?;
            }
            if stopped {
                return Ok(RunEnd::Stopped);
            }
        }
        Ok(RunEnd::Finished)
    }

    /// Writes `latest.ipfn` (full training state, also a synth-ready model) and
    /// `checkpoints/iter-NNNNNN.ipfn` (the generator alone). Both are written atomically.
    pub fn save_checkpoint(&self) -> Result<PathBuf> {
        let (gen_config, weights) = self.model();
        let mut model = Checkpoint::new();
        weights.write_to(&gen_config, &mut model);
        let meta = &mut model.metadata;
        meta.insert(TRAIN_CONFIG_KEY.into(), self.config.to_toml());
        meta.insert(ITERATION_KEY.into(), self.iteration.to_string());
        if let Some(maps) = &self.maps {
            maps.write_to(&mut model);
        }
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
        checkpoint::write_module(&self.critic, "critic", &mut state);
        self.adam_generator.write_to("adam.generator", &mut state);
        self.adam_critic.write_to("adam.critic", &mut state);
        state.save(&self.run_dir.join("latest.ipfn"))?;
        Ok(path)
    }

    /// Writes `previews/iter-NNNNNN.png`: a fixed-seed sample covering 4x the crop's area. A
    /// solid texture or a volume previews its depth-0 slice (a density-controlled volume at the
    /// exemplar's mean density); a map set its first map.
    pub fn save_preview(&self) -> Result<PathBuf> {
        let (config, weights) = self.model();
        let side = 2 * config.crop; // 4x the crop's area, in the model's pixels
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
        let mut kept = metrics_header(self.kind.generator_axes());
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
        .map_err(err)
    }
}

fn create_dir(dir: &Path) -> Result<&Path> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Runtime(format!("{}: cannot create: {e}", dir.display())))?;
    Ok(dir)
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
