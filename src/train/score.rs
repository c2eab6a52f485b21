//! Quality you can watch: at each checkpoint an image run scores its generator (SIFID and the
//! structure distance of a few fixed-seed samples at the exemplar's own size against the
//! exemplar), logs the scores in `metrics.csv` and the progress line, and keeps the
//! best-scoring generator as `best.ipfn`.

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

/// A checkpoint's scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// SIFID against the exemplar (lower is better).
    pub sifid: f64,
    /// Structure distance to the exemplar (lower is better; see [`crate::metrics::Autocorrelation`]).
    pub structure: f64,
    /// How strongly the samples repeat (0 to 1); far above the exemplar's, a grid.
    pub repeat: f64,
}

impl Score {
    /// What `best.ipfn` keeps the lowest of: SIFID times structure distance, so that both
    /// must be good and a tenth better on either counts the same, whatever their scales.
    pub fn combined(&self) -> f64 {
        self.sifid * self.structure
    }
}

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

    /// SIFID and structure distance (means over `score_samples` fixed seeds) of the current
    /// generator against the exemplar at its own size, and how strongly those samples repeat
    /// (the mean of [`crate::metrics::repeat_strength`] over rows and columns: a grid the SIFID
    /// does not see shows there); `None` for runs that are not scored.
    pub fn score(&self) -> Result<Option<Score>> {
        let Some(reference) = self.score_reference()? else {
            return Ok(None);
        };
        let (config, weights) = self.model();
        let seed = derive_seed(self.config.seed, &[SCORE_STREAM]);
        let scores = crate::metrics::sample_scores(
            &config,
            &weights,
            &reference,
            self.config.score_samples,
            seed,
            DeviceChoice::Cpu,
        )?;
        Ok(Some(Score {
            sifid: scores.sifid.mean,
            structure: scores.structure.mean,
            repeat: (scores.repeat[0] + scores.repeat[1]) / 2.0,
        }))
    }

    /// The exemplar's structure floor as scoring sees it ([`crate::metrics::structure_floor`]
    /// of the scored reference): the structure distance a generator that paints the
    /// exemplar's own structure can expect. `None` for runs that are not scored.
    pub fn structure_floor(&self) -> Result<Option<f64>> {
        Ok(self
            .score_reference()?
            .map(|r| crate::metrics::structure_floor(&r.values, r.height, r.width, r.channels)))
    }

    /// The best [`Score::combined`] so far and the iteration that reached it.
    pub fn best(&self) -> Option<(f64, u64)> {
        self.best
    }
}
