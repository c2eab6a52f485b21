//! Evaluation: SIFID, the structure distance, the seam score of tiles, and the dominant period
//! of a pattern.
//!
//! **SIFID** (Shaham et al., SinGAN, 2019) is the Fréchet distance between the Gaussians fitted
//! to the deep features of two images, where every spatial position of the feature map is one
//! sample. Following SinGAN's `SIFID/sifid_score.py`, the features are InceptionV3's stem up to
//! `Conv2d_4a_3x3` (192 channels, before the second max-pool), the input is in [0, 1] mapped to
//! `2x - 1`, and nothing is resized.
//!
//! The weights are Keras' ImageNet InceptionV3 (from the npm package `nsfwjs@4.4.0`, converted
//! by `tools/inception-stem/convert.js`; see `assets/README.md`), not torchvision's, so absolute
//! values are **not comparable** with papers that used torchvision's weights (SinGAN, IPFN's
//! Table 1). We call the metric "SIFID (Keras InceptionV3)" wherever we print it.
//!
//! The **structure distance** ([`Autocorrelation`]) compares how the pattern is arranged, which
//! SIFID does not see: the mean absolute difference of two normalised autocorrelations of the
//! luminance, beside the exemplar's own **floor** (its halves against the whole).
//!
//! The **seam score** of a tile is the mean gradient magnitude across its wrap seams (last
//! column to first, last row to first) over the mean gradient magnitude of the lines beside the
//! seams, inside the tile: about 1 for a seamless tile, larger where the wrap shows.
//!
//! The **dominant period** of an image along an axis is the lag of the first strong peak of its
//! autocorrelation along that axis, past the central lobe; the peak's height over the
//! autocorrelation at lag 0 is the repeat's **strength**: near 1 for a regular pattern, near 0
//! for a stochastic one. A model whose samples repeat far more strongly than its exemplar paints
//! a visible grid.

mod fft;
mod map_set;
mod sifid;
mod structure;
mod tiles;

pub use map_set::*;
pub use sifid::*;
pub use structure::*;
pub use tiles::*;

use crate::error::Result;
use crate::input_error;

/// Mean and sample standard deviation of some values.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    pub mean: f64,
    pub std: f64,
    pub values: Vec<f64>,
}

impl Summary {
    pub fn of(values: Vec<f64>) -> Self {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let std = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Self { mean, std, values }
    }
}

/// The name we print for the metric, so no one compares it with torchvision-based SIFIDs.
pub const SIFID_NAME: &str = "SIFID (Keras ImageNet InceptionV3 stem; not comparable with torchvision-based values such as the paper's)";

/// What `ipfn eval --model M --exemplar X` reports.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ModelReport {
    pub metric: &'static str,
    /// SIFID of samples (seeds `seed..seed + samples`, at the exemplar's size) to the exemplar.
    pub sifid: Summary,
    /// Structure distance of the same samples to the exemplar (lower is better).
    pub structure: Summary,
    /// The exemplar's own structure distance ([`structure_floor`]): what a model that paints
    /// the exemplar's structure can expect.
    pub structure_floor: f64,
    /// Seam score of `--tile` samples of the exemplar's size (one per seed), laid 2x2.
    pub seam_model_tile: SeamScore,
    /// Seam score of the exemplar itself laid 2x2, for comparison.
    pub seam_exemplar: SeamScore,
    /// The model's period (octave 0 of the encoding, `|K| * crop` pixels): rows, columns.
    pub period_model: [f64; 2],
    /// The exemplar's dominant period from its autocorrelation: rows, columns.
    pub period_exemplar: [Option<f64>; 2],
    /// Strength of the samples' strongest repeat (rows, columns; mean over the SIFID samples, 0
    /// where a sample has none).
    pub repeat_model: [f64; 2],
    /// Strength of the exemplar's strongest repeat (rows, columns; 0 where it has none).
    pub repeat_exemplar: [f64; 2],
    pub width: usize,
    pub height: usize,
    pub seed: u64,
}

/// Evaluates a model against its exemplar (values in [-1, 1], `[h, w, c]`).
pub fn evaluate_model(
    samples: Samples<'_>,
    exemplar: &crate::exemplar::Exemplar,
) -> Result<ModelReport> {
    use crate::synth::Synth;
    let Samples {
        config,
        weights,
        count,
        seed,
        device,
    } = samples;
    if count == 0 {
        return Err(input_error!("--samples 0: need at least one sample"));
    }
    let gray;
    let exemplar = if exemplar.channels != config.channels && exemplar.is_gray() {
        gray = exemplar.to_gray(); // a model trained as gray on a gray photo stored as RGB
        &gray
    } else {
        exemplar
    };
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let scores = sample_scores(samples, exemplar)?;
    let exemplar_repeats = repeats(&exemplar.values, h, w, c);
    // One --tile sample per seed, each cut at another phase of the pattern (an offset within
    // the tile's period keeps it a tile), so the seam score does not measure one phase.
    let mut tiles = Vec::with_capacity(count);
    for s in 0..count as u64 {
        let golden = |n: usize, k: u64| ((k as f64 * 0.618_033_988_75).fract() * n as f64) as i64;
        let painter = Synth::new(config.clone(), weights.clone())
            .seed(seed.wrapping_add(s))
            .device(device)
            .tile(&[h, w])
            .offset(&[golden(h, s + 7), golden(w, s)])
            .painter()?;
        tiles.push(painter.render(&[0, 0], &[h, w]));
    }
    let tiles: Vec<&[f32]> = tiles.iter().map(Vec::as_slice).collect();
    let period = |axis: usize| (weights.k[axis].abs() * config.crop as f32) as f64;
    Ok(ModelReport {
        metric: SIFID_NAME,
        sifid: scores.sifid,
        structure: scores.structure,
        structure_floor: structure_floor(&exemplar.values, h, w, c),
        seam_model_tile: seam_score_of_tiles(&tiles, h, w, c)?,
        seam_exemplar: seam_score(&exemplar.values, h, w, c)?,
        period_model: [period(0), period(1)],
        period_exemplar: exemplar_repeats.map(|r| r.map(|r| r.period)),
        repeat_model: scores.repeat,
        repeat_exemplar: exemplar_repeats.map(|r| r.map_or(0.0, |r| r.strength)),
        width: w,
        height: h,
        seed,
    })
}

/// The strength of an image's strongest repeat along rows and columns (`[h, w, c]`; 0 where it
/// has none).
pub fn repeat_strength(image: &[f32], h: usize, w: usize, c: usize) -> [f64; 2] {
    repeats(image, h, w, c).map(|r| r.map_or(0.0, |r| r.strength))
}

/// How a model's samples score against its exemplar ([`sample_scores`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SampleScores {
    /// SIFID of each sample to the exemplar.
    pub sifid: Summary,
    /// Structure distance of each sample to the exemplar, with the exemplar's
    /// [`structure_lags`].
    pub structure: Summary,
    /// The samples' mean [`repeat_strength`] along rows and columns.
    pub repeat: [f64; 2],
}

/// Scores a model's samples against the exemplar (values in [-1, 1], `[h, w, c]`): SIFID,
/// structure distance and repeat strength.
pub fn sample_scores(
    samples: Samples<'_>,
    exemplar: &crate::exemplar::Exemplar,
) -> Result<SampleScores> {
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let real = exemplar_features(samples.config, exemplar)?;
    let lags = structure_lags(h, w);
    let real_structure = Autocorrelation::of(&exemplar.values, h, w, c, lags);
    let n = samples.count;
    let (mut sifids, mut structures) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut repeat = [0.0; 2];
    samples.for_each(exemplar, |sample| {
        sifids.push(sifid_against(&real, sample, exemplar)?);
        structures.push(real_structure.distance(&Autocorrelation::of(sample, h, w, c, lags)));
        let s = repeat_strength(sample, h, w, c);
        (0..2).for_each(|axis| repeat[axis] += s[axis] / n as f64);
        Ok(())
    })?;
    Ok(SampleScores {
        sifid: Summary::of(sifids),
        structure: Summary::of(structures),
        repeat,
    })
}

/// The samples of a model that are scored: `count` of them (seeds `seed`, `seed + 1`, ...),
/// each painted on `device` at the exemplar's size.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a> {
    pub config: &'a crate::generator::GeneratorConfig,
    pub weights: &'a crate::generator::GeneratorWeights,
    pub count: usize,
    pub seed: u64,
    pub device: crate::device::DeviceChoice,
}

impl<'a> Samples<'a> {
    /// `count` samples from seed `seed`, painted on the fused CPU path.
    pub fn cpu(
        config: &'a crate::generator::GeneratorConfig,
        weights: &'a crate::generator::GeneratorWeights,
        count: usize,
        seed: u64,
    ) -> Self {
        Self {
            config,
            weights,
            count,
            seed,
            device: crate::device::DeviceChoice::Cpu,
        }
    }

    /// Paints each sample at the exemplar's size and hands it (`[h, w, c]`) to `each`, one at
    /// a time, so memory holds one sample.
    fn for_each(
        &self,
        exemplar: &crate::exemplar::Exemplar,
        mut each: impl FnMut(&[f32]) -> Result<()>,
    ) -> Result<()> {
        use crate::synth::Synth;
        for s in 0..self.count as u64 {
            let painter = Synth::new(self.config.clone(), self.weights.clone())
                .seed(self.seed.wrapping_add(s))
                .device(self.device)
                .painter()?;
            each(&painter.render(&[0, 0], &[exemplar.height, exemplar.width]))?;
        }
        Ok(())
    }
}

/// The Gaussian of the exemplar's stem features (values in [-1, 1], `[h, w, c]`), for a model
/// that paints its channels.
fn exemplar_features(
    config: &crate::generator::GeneratorConfig,
    exemplar: &crate::exemplar::Exemplar,
) -> Result<Gaussian> {
    if exemplar.channels != config.channels {
        return Err(input_error!(
            "the exemplar has {} channels but the model paints {}; evaluate a model with the exemplar it was trained on",
            exemplar.channels,
            config.channels
        ));
    }
    stem_gaussian(exemplar)
}

/// The Gaussian of an image's stem features (values in [-1, 1], `[h, w, c]`).
fn stem_gaussian(exemplar: &crate::exemplar::Exemplar) -> Result<Gaussian> {
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let features = InceptionStem::embedded().features(&to_unit_rgb(&exemplar.values, c)?, h, w)?;
    Gaussian::fit(&features)
}

/// SIFID of `fake` (`[h, w, c]`, the exemplar's size) against the exemplar's features `real`.
fn sifid_against(
    real: &Gaussian,
    fake: &[f32],
    exemplar: &crate::exemplar::Exemplar,
) -> Result<f64> {
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let fake = InceptionStem::embedded().features(&to_unit_rgb(fake, c)?, h, w)?;
    Ok(frechet_distance(real, &Gaussian::fit(&fake)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn frechet_distance_of_a_gaussian_with_itself_is_zero_and_matches_closed_form() {
        // Diagonal covariances: d = |dm|^2 + sum (sqrt(a) - sqrt(b))^2.
        let a = Gaussian {
            mean: DVector::from_vec(vec![1.0, 2.0, 0.0]),
            covariance: DMatrix::from_diagonal(&DVector::from_vec(vec![4.0, 1.0, 9.0])),
        };
        let b = Gaussian {
            mean: DVector::from_vec(vec![0.0, 2.0, 1.0]),
            covariance: DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 1.0, 4.0])),
        };
        assert!(frechet_distance(&a, &a).abs() < 1e-9);
        let expected = 2.0 + 1.0 + 0.0 + 1.0;
        assert!((frechet_distance(&a, &b) - expected).abs() < 1e-9);
    }

    #[test]
    fn symmetric_sqrt_squares_back() {
        let m = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let r = symmetric_sqrt(&m);
        assert!((&r * &r - &m).abs().max() < 1e-10);
    }

    #[test]
    fn seam_score_is_one_for_a_periodic_tile_and_large_for_a_ramp() {
        let (h, w) = (32, 48);
        let periodic: Vec<f32> = (0..h * w)
            .map(|i| {
                let (y, x) = ((i / w) as f32, (i % w) as f32);
                // Diagonal waves: every phase crosses each seam, as in a stationary texture.
                let (u, v) = (x / w as f32, y / h as f32);
                (std::f32::consts::TAU * (u + v)).sin()
                    + (std::f32::consts::TAU * (2.0 * u - 3.0 * v)).cos()
            })
            .collect();
        let s = seam_score(&periodic, h, w, 1).unwrap();
        assert!((s.columns - 1.0).abs() < 0.02, "{s:?}");
        assert!((s.rows - 1.0).abs() < 0.02, "{s:?}");
        let ramp: Vec<f32> = (0..h * w).map(|i| (i % w) as f32 / w as f32).collect();
        assert!(seam_score(&ramp, h, w, 1).unwrap().columns > 20.0);
    }

    #[test]
    fn a_photos_own_lines_score_about_one_and_its_wrap_does_not() {
        // Noise on a ramp across the columns: every inner line is like its neighbours, the wrap
        // (ramp's end to its start) is a step.
        let (h, w) = (48, 64);
        let mut state = 7u64;
        let v: Vec<f32> = (0..h * w)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = (state >> 40) as f32 / (1u64 << 24) as f32;
                0.2 * noise + (i % w) as f32 / w as f32
            })
            .collect();
        let spread = line_score_spread(&v, h, w, 1).unwrap();
        assert!(
            spread.p5 < spread.median && spread.median < spread.p95,
            "{spread:?}"
        );
        assert!((spread.median - 1.0).abs() < 0.1, "{spread:?}");
        assert!(spread.holds(spread.median));
        let wrap = seam_score(&v, h, w, 1).unwrap().overall;
        assert!(
            !spread.holds(wrap) && wrap > spread.p95,
            "{wrap} {spread:?}"
        );
        assert!(line_score_spread(&v[..17 * w], 17, w, 1).is_none());
    }

    #[test]
    fn dominant_period_finds_the_stripe_spacing() {
        let (h, w) = (64, 128);
        let v: Vec<f32> = (0..h * w)
            .map(|i| {
                let (y, x) = ((i / w) as f32, (i % w) as f32);
                (std::f32::consts::TAU * x / 12.5).sin()
                    + 0.5 * (std::f32::consts::TAU * y / 9.0).sin()
            })
            .collect();
        let [rows, cols] = dominant_period(&v, h, w, 1);
        assert!((cols.unwrap() - 12.5).abs() < 0.3, "{cols:?}");
        assert!((rows.unwrap() - 9.0).abs() < 0.3, "{rows:?}");
    }

    #[test]
    fn stripes_repeat_strongly_and_noise_hardly() {
        let (h, w) = (64, 96);
        let stripes: Vec<f32> = (0..h * w)
            .map(|i| (std::f32::consts::TAU * (i % w) as f32 / 12.0).sin())
            .collect();
        let [rows, cols] = repeats(&stripes, h, w, 1);
        assert!(rows.is_none(), "constant down the rows: {rows:?}");
        let cols = cols.unwrap();
        assert!(
            (cols.period - 12.0).abs() < 0.3 && cols.strength > 0.8,
            "{cols:?}"
        );
        // White noise (splitmix64 of the index): any "peak" is a small fraction of the variance.
        let splitmix = |i: u64| {
            let mut z = i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let noise: Vec<f32> = (0..(h * w) as u64)
            .map(|i| (splitmix(i) >> 40) as f32 / (1u64 << 24) as f32 - 0.5)
            .collect();
        for r in repeats(&noise, h, w, 1).into_iter().flatten() {
            assert!(r.strength < 0.2, "{r:?}");
        }
    }

    #[test]
    fn stem_output_has_the_documented_shape() {
        let (h, w) = (40, 64);
        let rgb = vec![0.5f32; h * w * 3];
        let f = InceptionStem::embedded().features(&rgb, h, w).unwrap();
        // 40 -> 19 -> 17 -> 17 -> pool 8 -> 8 -> 6; 64 -> 31 -> 29 -> 29 -> 14 -> 14 -> 12.
        assert_eq!((f.height, f.width, f.channels), (6, 12, STEM_FEATURES));
        assert!(
            InceptionStem::embedded()
                .features(&rgb[..18 * 18 * 3], 18, 18)
                .is_err()
        );
    }
}
