//! The periodic sinusoidal network of Paz, Novello and Velho: a stack of stages (MR-Net's
//! levels of detail), each an MLP whose first layer is `sin(2π k·u + φ)` with integer
//! frequencies `k` and `u = p / P` (the pixel position over the tile's period), so every stage,
//! and their sum, is exactly periodic with period `P` (their Theorem 1). Hidden layers are
//! SIREN's `sin(ω0 (W h + b))`; the head is linear.
//!
//! Parameters of a stage are one flat vector (for the optimiser and the checkpoint), laid out
//! as: phases `[F]`, then per hidden layer `W [inputs, outputs]` (row-major) and `b [outputs]`,
//! then the head's `W [last, channels]` and `b [channels]`. Frequencies are frozen.

use serde::{Deserialize, Serialize};

use crate::checkpoint::Checkpoint;
use crate::error::Result;
use crate::input_error;
use crate::latent::derive_seed;

/// Metadata key of a periodic network's model file, and its value.
pub const KIND_KEY: &str = "model_kind";
pub const KIND: &str = "periodic-tile";
const SHAPE_KEY: &str = "periodic_shape";

/// The shape of one stage: its frozen frequencies and its layer widths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageShape {
    /// Integer frequencies `[k_rows, k_cols]` (cycles per period along each axis).
    pub frequencies: Vec<[i32; 2]>,
    /// Widths of the hidden sine layers.
    pub hidden: Vec<usize>,
}

impl StageShape {
    /// `(inputs, outputs)` of each dense layer, head included.
    pub fn layers(&self, channels: usize) -> Vec<(usize, usize)> {
        let mut widths = vec![self.frequencies.len()];
        widths.extend(&self.hidden);
        widths.push(channels);
        widths.windows(2).map(|w| (w[0], w[1])).collect()
    }

    /// The number of parameters (phases, weights and biases).
    pub fn parameters(&self, channels: usize) -> usize {
        self.frequencies.len()
            + self
                .layers(channels)
                .iter()
                .map(|(i, o)| i * o + o)
                .sum::<usize>()
    }

    /// The largest layer width (the scratch a point needs).
    pub fn widest(&self, channels: usize) -> usize {
        self.hidden
            .iter()
            .copied()
            .chain([self.frequencies.len(), channels])
            .max()
            .unwrap_or(1)
    }
}

/// The network's shape: the period, the channels, ω0 and its stages.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NetworkShape {
    /// The period in pixels, `[rows, cols]`: the fitted tile's size.
    pub period: [usize; 2],
    pub channels: usize,
    /// SIREN's ω0 of the hidden layers.
    pub omega0: f32,
    pub stages: Vec<StageShape>,
}

impl NetworkShape {
    pub fn parameters(&self) -> usize {
        self.stages
            .iter()
            .map(|s| s.parameters(self.channels))
            .sum()
    }
}

/// A periodic network: its shape and each stage's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct PeriodicNet {
    pub shape: NetworkShape,
    pub params: Vec<Vec<f32>>,
}

/// Frequencies of the half band `lower < max(|k_r|, |k_c|) <= upper` (rows first), one of each
/// pair `k`, `-k`: `k_c > 0`, or `k_c = 0` and `k_r > 0`. `count` of them drawn without
/// repetition (all of them if the band holds fewer), lowest first.
pub fn half_band(lower: usize, upper: usize, count: usize, seed: u64) -> Vec<[i32; 2]> {
    let (lo, hi) = (lower as i32, upper as i32);
    let mut all = Vec::new();
    for kc in 0..=hi {
        for kr in -hi..=hi {
            let band = kr.abs().max(kc);
            if band > lo && band <= hi && (kc > 0 || kr > 0) {
                all.push([kr, kc]);
            }
        }
    }
    // A partial Fisher-Yates shuffle with a hash per position: deterministic for the seed.
    let take = count.min(all.len());
    for i in 0..take {
        let j = i + (derive_seed(seed, &[i as u64]) % (all.len() - i) as u64) as usize;
        all.swap(i, j);
    }
    all.truncate(take);
    all.sort_by_key(|k| (k[0].abs().max(k[1]), k[1], k[0]));
    all
}

/// A uniform value in `[-bound, bound)` from a hash of `(seed, index)`.
fn uniform(seed: u64, index: u64, bound: f32) -> f32 {
    (2.0 * crate::latent::unit_uniform(seed, &[index]) - 1.0) * bound
}

impl PeriodicNet {
    /// A network with SIREN's initialisation (hidden and head weights uniform in
    /// `±sqrt(6 / inputs) / ω0`, biases in `±1 / sqrt(inputs)`) and phases uniform in `±π`.
    pub fn init(shape: NetworkShape, seed: u64) -> Self {
        let params = shape
            .stages
            .iter()
            .enumerate()
            .map(|(s, stage)| {
                let seed = derive_seed(seed, &[s as u64]);
                let mut p = Vec::with_capacity(stage.parameters(shape.channels));
                for _ in 0..stage.frequencies.len() {
                    p.push(uniform(seed, p.len() as u64, std::f32::consts::PI));
                }
                for (inputs, outputs) in stage.layers(shape.channels) {
                    let w = (6.0 / inputs as f32).sqrt() / shape.omega0;
                    for _ in 0..inputs * outputs {
                        p.push(uniform(seed, p.len() as u64, w));
                    }
                    let b = 1.0 / (inputs as f32).sqrt();
                    for _ in 0..outputs {
                        p.push(uniform(seed, p.len() as u64, b));
                    }
                }
                p
            })
            .collect();
        Self { shape, params }
    }

    /// Writes the network into `checkpoint` (tensors `stage.S`, shape in the metadata).
    pub fn write_to(&self, checkpoint: &mut Checkpoint) {
        checkpoint.metadata.insert(KIND_KEY.into(), KIND.into());
        checkpoint.metadata.insert(
            SHAPE_KEY.into(),
            serde_json::to_string(&self.shape).expect("the shape serialises"),
        );
        for (s, p) in self.params.iter().enumerate() {
            checkpoint.insert(format!("stage.{s}"), vec![p.len()], p.clone());
        }
    }

    /// Whether `checkpoint` holds a periodic network.
    pub fn is_in(checkpoint: &Checkpoint) -> bool {
        checkpoint.metadata.get(KIND_KEY).map(String::as_str) == Some(KIND)
    }

    /// Reads a network written by [`PeriodicNet::write_to`].
    pub fn read_from(checkpoint: &Checkpoint) -> Result<Self> {
        let file = checkpoint.source.display();
        let shape: NetworkShape = serde_json::from_str(checkpoint.meta(SHAPE_KEY)?)
            .map_err(|e| input_error!("{file}: the periodic network's shape is damaged: {e}"))?;
        if shape.period.contains(&0) || shape.channels == 0 || shape.stages.is_empty() {
            return Err(input_error!(
                "{file}: the periodic network has an empty period, no channels or no stages"
            ));
        }
        let params = shape
            .stages
            .iter()
            .enumerate()
            .map(|(s, stage)| {
                let n = stage.parameters(shape.channels);
                Ok(checkpoint.tensor(&format!("stage.{s}"), &[n])?.to_vec())
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self { shape, params })
    }

    /// The number of stages.
    pub fn stages(&self) -> usize {
        self.shape.stages.len()
    }

    /// Stage gains for level of detail `lod` (in stages, `0..=stages`): stages below
    /// `floor(lod)` at 1, the next at the fraction, the rest at 0.
    pub fn lod_gains(&self, lod: f32) -> Vec<f32> {
        (0..self.stages())
            .map(|s| (lod - s as f32).clamp(0.0, 1.0))
            .collect()
    }
}

/// A stage's parameters split by layer: phases, then `(W, b)` per dense layer.
pub struct StageView<'a> {
    pub phase: &'a [f32],
    pub layers: Vec<(&'a [f32], &'a [f32])>,
}

/// Splits `params` of `stage` into its phases and layers.
pub fn view<'a>(stage: &StageShape, channels: usize, params: &'a [f32]) -> StageView<'a> {
    let (phase, mut rest) = params.split_at(stage.frequencies.len());
    let layers = stage
        .layers(channels)
        .into_iter()
        .map(|(i, o)| {
            let (w, r) = rest.split_at(i * o);
            let (b, r) = r.split_at(o);
            rest = r;
            (w, b)
        })
        .collect();
    StageView { phase, layers }
}

/// The angular frequency per pixel of each frequency, per axis: `2π k_d / P_d`.
pub fn angular(stage: &StageShape, period: [usize; 2]) -> Vec<[f32; 2]> {
    let tau = std::f64::consts::TAU;
    stage
        .frequencies
        .iter()
        .map(|k| {
            [
                (tau * k[0] as f64 / period[0] as f64) as f32,
                (tau * k[1] as f64 / period[1] as f64) as f32,
            ]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_band_holds_one_of_each_pair_inside_the_band() {
        let k = half_band(2, 5, 1000, 7);
        assert!(!k.is_empty());
        for f in &k {
            let band = f[0].abs().max(f[1]);
            assert!(band > 2 && band <= 5, "{f:?} outside (2, 5]");
            assert!(!k.contains(&[-f[0], -f[1]]), "{f:?} and its negative");
        }
        // The whole half band: ((2*5+1)^2 - (2*2+1)^2) / 2.
        assert_eq!(k.len(), (121 - 25) / 2);
        assert_eq!(half_band(0, 8, 10, 3), half_band(0, 8, 10, 3));
        assert_eq!(half_band(0, 8, 10, 3).len(), 10);
    }
}
