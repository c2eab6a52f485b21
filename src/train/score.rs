//! Quality you can watch: at each checkpoint an image run scores its generator (SIFID of a few
//! fixed-seed samples at the exemplar's own size against the exemplar), logs the score in
//! `metrics.csv` and the progress line, and keeps the best-scoring generator as `best.ipfn`.

use super::{ExemplarSource, RunKind, Trainer};
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::exemplar::{Exemplar, read_exemplar};
use crate::latent::derive_seed;

/// Scoring reads at most this many pixels a side of the exemplar (its centre), so a checkpoint
/// of a large photo stays well under a second.
pub const SCORE_SIDE: usize = 384;

/// Seed stream of the scored samples (distinct from every training stream).
const SCORE_STREAM: u64 = 12;

impl Trainer {
    /// The exemplar as scoring sees it: at its own scale (the model paints there), gray for a
    /// gray run, its centre at most [`SCORE_SIDE`] a side. `None` where a run is not scored:
    /// volumes, solid textures, map sets, or `score_samples = 0`.
    fn score_reference(&self) -> Result<Option<Exemplar>> {
        let ExemplarSource::Image(path) = &self.source else {
            return Ok(None);
        };
        if !matches!(self.kind, RunKind::Image { guide: None }) || self.config.score_samples == 0 {
            return Ok(None);
        }
        let mut exemplar = read_exemplar(path)?;
        if self.config.gray && exemplar.channels >= 3 {
            exemplar = exemplar.to_gray();
        }
        Ok(Some(exemplar.centre(SCORE_SIDE)))
    }

    /// SIFID (mean over `score_samples` fixed seeds) of the current generator against the
    /// exemplar at its own size; `None` for runs that are not scored.
    pub fn score(&self) -> Result<Option<f64>> {
        let Some(reference) = self.score_reference()? else {
            return Ok(None);
        };
        let (config, weights) = self.model();
        let seed = derive_seed(self.config.seed, &[SCORE_STREAM]);
        let summary = crate::metrics::sifid_of_model(
            &config,
            &weights,
            &reference,
            self.config.score_samples,
            seed,
            DeviceChoice::Cpu,
        )?;
        Ok(Some(summary.mean))
    }

    /// The best score so far and the iteration that reached it.
    pub fn best(&self) -> Option<(f64, u64)> {
        self.best
    }
}
