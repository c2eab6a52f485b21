//! Quality you can watch: at each checkpoint an image run scores its generator (SIFID and the
//! structure distance of a few fixed-seed samples at the exemplar's own size against the
//! exemplar), logs the scores in `metrics.csv` and the progress line, and keeps the
//! best-scoring generator as `best.ipfn`. A map set is scored as an image is, its SIFID on its
//! colour map and its structure distance the mean of its maps'.

use super::{ExemplarSource, RunKind, Trainer};
use crate::error::Result;
use crate::exemplar::{Exemplar, read_exemplar};
use crate::latent::derive_seed;
use crate::maps::MapSet;
use crate::metrics::Samples;

/// Scoring reads at most this many pixels a side of the exemplar (its centre), so a checkpoint
/// of a large photo stays well under a second.
pub const SCORE_SIDE: usize = 384;

/// Seed stream of the scored samples (distinct from every training stream).
const SCORE_STREAM: u64 = 12;

/// A checkpoint's scores.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    /// SIFID against the exemplar (lower is better).
    pub sifid: f64,
    /// Structure distance to the exemplar (lower is better; see [`crate::metrics::Autocorrelation`]).
    pub structure: f64,
    /// How strongly the samples repeat (0 to 1); far above the exemplar's, a grid.
    pub repeat: f64,
    /// A map set's structure distance per map, in the set's order (`structure` is their
    /// mean); empty for an image.
    pub maps: Vec<f64>,
}

/// The exemplar's structure floor as scoring sees it ([`Trainer::structure_floor`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StructureFloor {
    /// The floor (a map set's: the mean of its maps').
    pub mean: f64,
    /// A map set's floor per map, named, in the set's order; empty for an image.
    pub maps: Vec<(String, f64)>,
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
    /// gray run, its centre at most [`SCORE_SIDE`] a side; a map set's maps stacked, with the
    /// set. `None` where a run is not scored: volumes, solid textures, guided runs, or
    /// `score_samples = 0`.
    fn score_reference(&self) -> Result<Option<(Exemplar, Option<MapSet>)>> {
        if !matches!(self.kind, RunKind::Image { guide: None }) || self.config.score_samples == 0 {
            return Ok(None);
        }
        match &self.source {
            ExemplarSource::Image(path) => {
                let mut exemplar = read_exemplar(path)?;
                if self.config.gray && exemplar.channels >= 3 {
                    exemplar = exemplar.to_gray();
                }
                Ok(Some((exemplar.centre(SCORE_SIDE), None)))
            }
            ExemplarSource::Maps(files) => {
                let (stacked, set) = files.load()?;
                Ok(Some((stacked.centre(SCORE_SIDE), Some(set))))
            }
            ExemplarSource::Volume(_) => Ok(None),
        }
    }

    /// SIFID and structure distance (means over `score_samples` fixed seeds) of the current
    /// generator against the exemplar at its own size, and how strongly those samples repeat
    /// (the mean of [`crate::metrics::repeat_strength`] over rows and columns: a grid the SIFID
    /// does not see shows there); `None` for runs that are not scored. A map set's SIFID and
    /// repeat are its colour map's, its structure distance the mean of its maps'
    /// ([`crate::metrics::map_set_scores`]).
    pub fn score(&self) -> Result<Option<Score>> {
        let Some((reference, set)) = self.score_reference()? else {
            return Ok(None);
        };
        let (config, weights) = self.model();
        let seed = derive_seed(self.config.seed, &[SCORE_STREAM]);
        let samples = Samples::cpu(&config, &weights, self.config.score_samples, seed);
        let (scores, structure, maps) = match &set {
            None => {
                let scores = crate::metrics::sample_scores(samples, &reference)?;
                let structure = scores.structure.mean;
                (scores, structure, Vec::new())
            }
            Some(set) => {
                let scores = crate::metrics::map_set_scores(samples, &reference, set)?;
                let maps: Vec<f64> = scores.structure.iter().map(|s| s.mean).collect();
                (scores.colour, mean(maps.iter().copied()), maps)
            }
        };
        Ok(Some(Score {
            sifid: scores.sifid.mean,
            structure,
            repeat: (scores.repeat[0] + scores.repeat[1]) / 2.0,
            maps,
        }))
    }

    /// The exemplar's structure floor as scoring sees it ([`crate::metrics::structure_floor`]
    /// of the scored reference; a map set's, the mean of its maps'): the structure distance a
    /// generator that paints the exemplar's own structure can expect. `None` for runs that are
    /// not scored.
    pub fn structure_floor(&self) -> Result<Option<StructureFloor>> {
        let Some((r, set)) = self.score_reference()? else {
            return Ok(None);
        };
        let floor = |v: &[f32], c| crate::metrics::structure_floor(v, r.height, r.width, c);
        Ok(Some(match set {
            None => StructureFloor {
                mean: floor(&r.values, r.channels),
                maps: Vec::new(),
            },
            Some(set) => {
                let maps: Vec<(String, f64)> = (set.maps.iter().zip(set.ranges()))
                    .map(|(m, range)| {
                        let values = r.select(range.clone()).values;
                        (m.name.clone(), floor(&values, range.len()))
                    })
                    .collect();
                StructureFloor {
                    mean: mean(maps.iter().map(|(_, f)| *f)),
                    maps,
                }
            }
        }))
    }

    /// The best [`Score::combined`] so far and the iteration that reached it.
    pub fn best(&self) -> Option<(f64, u64)> {
        self.best
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    sum / n.max(1) as f64
}
