//! Evaluation: SIFID, the seam score of tiles, and the dominant period of a pattern.
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
//! The **seam score** of a tile is the mean gradient magnitude across its wrap seams (last
//! column to first, last row to first) over the mean gradient magnitude of the lines beside the
//! seams, inside the tile: about 1 for a seamless tile, larger where the wrap shows.
//!
//! The **dominant period** of an image along an axis is the lag of the first strong peak of its
//! autocorrelation along that axis, past the central lobe.

use std::sync::OnceLock;

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;
use safetensors::SafeTensors;

use crate::error::{Error, Result};
use crate::generator::fused::matmul_into;
use crate::input_error;

/// The converted stem, embedded in the binary (about 690 KB).
const EMBEDDED_STEM: &[u8] = include_bytes!("../assets/inception_v3_stem.safetensors");

/// Feature channels of the stem (`Conv2d_4a_3x3`).
pub const STEM_FEATURES: usize = 192;

/// Keras' batch-norm epsilon for InceptionV3.
const BATCH_NORM_EPSILON: f64 = 1e-3;

/// The smallest image side the stem accepts (one output position).
pub const MIN_SIDE: usize = 19;

/// One conv + batch norm + ReLU, with the batch norm folded into the weights.
#[derive(Debug, Clone)]
struct ConvBlock {
    /// `[kernel * kernel * cin, cout]`, rows ordered (ky, kx, cin).
    weight: Vec<f32>,
    bias: Vec<f32>,
    cin: usize,
    cout: usize,
    kernel: usize,
    stride: usize,
    /// Zero padding on each side ('same' for a stride-1 3x3 is 1).
    pad: usize,
}

/// A feature map, `[height, width, channels]` row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    pub values: Vec<f32>,
}

impl ConvBlock {
    /// # Shapes
    /// - input: `[h, w, cin]`
    /// - output: `[(h + 2 pad - k) / stride + 1, (w + 2 pad - k) / stride + 1, cout]`
    fn forward(&self, x: &FeatureMap) -> FeatureMap {
        let (k, s, p, cin) = (self.kernel, self.stride, self.pad, self.cin);
        let oh = (x.height + 2 * p - k) / s + 1;
        let ow = (x.width + 2 * p - k) / s + 1;
        let depth = k * k * cin;
        let mut out = vec![0.0f32; oh * ow * self.cout];
        // One output row at a time: im2col for the row, then one GEMM.
        out.par_chunks_mut(ow * self.cout)
            .enumerate()
            .for_each(|(oy, out_row)| {
                let mut cols = vec![0.0f32; ow * depth];
                for ox in 0..ow {
                    let patch = &mut cols[ox * depth..(ox + 1) * depth];
                    for ky in 0..k {
                        let iy = (oy * s + ky) as isize - p as isize;
                        for kx in 0..k {
                            let ix = (ox * s + kx) as isize - p as isize;
                            let dst = &mut patch[(ky * k + kx) * cin..(ky * k + kx + 1) * cin];
                            if iy < 0 || ix < 0 || iy >= x.height as isize || ix >= x.width as isize
                            {
                                dst.fill(0.0);
                            } else {
                                let at = (iy as usize * x.width + ix as usize) * cin;
                                dst.copy_from_slice(&x.values[at..at + cin]);
                            }
                        }
                    }
                }
                matmul_into(out_row, &cols, &self.weight, ow, self.cout, depth);
                for px in out_row.chunks_exact_mut(self.cout) {
                    for (v, b) in px.iter_mut().zip(&self.bias) {
                        *v = (*v + b).max(0.0);
                    }
                }
            });
        FeatureMap {
            height: oh,
            width: ow,
            channels: self.cout,
            values: out,
        }
    }
}

/// 3x3 max-pool with stride 2, no padding.
///
/// # Shapes
/// - input: `[h, w, c]`; output: `[(h - 3) / 2 + 1, (w - 3) / 2 + 1, c]`
fn max_pool_3x3_s2(x: &FeatureMap) -> FeatureMap {
    let (oh, ow, c) = ((x.height - 3) / 2 + 1, (x.width - 3) / 2 + 1, x.channels);
    let mut values = vec![f32::NEG_INFINITY; oh * ow * c];
    for oy in 0..oh {
        for ox in 0..ow {
            let dst = &mut values[(oy * ow + ox) * c..(oy * ow + ox + 1) * c];
            for ky in 0..3 {
                for kx in 0..3 {
                    let at = ((2 * oy + ky) * x.width + 2 * ox + kx) * c;
                    for (d, v) in dst.iter_mut().zip(&x.values[at..at + c]) {
                        *d = d.max(*v);
                    }
                }
            }
        }
    }
    FeatureMap {
        height: oh,
        width: ow,
        channels: c,
        values,
    }
}

/// InceptionV3's stem up to `Conv2d_4a_3x3`: the SIFID feature extractor.
#[derive(Debug, Clone)]
pub struct InceptionStem {
    blocks: Vec<ConvBlock>,
}

impl InceptionStem {
    /// The stem embedded in the binary.
    pub fn embedded() -> &'static InceptionStem {
        static STEM: OnceLock<InceptionStem> = OnceLock::new();
        STEM.get_or_init(|| {
            InceptionStem::from_bytes(EMBEDDED_STEM).expect("the embedded stem is valid")
        })
    }

    /// Reads a stem written by `tools/inception-stem/convert.js`, folding each batch norm
    /// (`scale=False`, so gamma = 1) into its conv: `w / sqrt(var + eps)`, `beta - mean / sqrt(var + eps)`.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let st = SafeTensors::deserialize(bytes)
            .map_err(|e| Error::Runtime(format!("inception stem: {e}")))?;
        let tensor = |name: &str| -> Result<(Vec<usize>, Vec<f32>)> {
            let t = st
                .tensor(name)
                .map_err(|e| Error::Runtime(format!("inception stem: {name}: {e}")))?;
            let values = t
                .data()
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            Ok((t.shape().to_vec(), values))
        };
        // (stride, 'same' padding) of conv2d_1..5.
        const LAYOUT: [(usize, bool); 5] =
            [(2, false), (1, false), (1, true), (1, false), (1, false)];
        let mut blocks = Vec::new();
        for (i, &(stride, same)) in LAYOUT.iter().enumerate() {
            let (shape, w) = tensor(&format!("conv{}.weight", i + 1))?;
            let [cout, cin, kh, kw] = shape[..] else {
                return Err(Error::Runtime(format!(
                    "inception stem: conv{} has shape {shape:?}",
                    i + 1
                )));
            };
            let (_, beta) = tensor(&format!("bn{}.beta", i + 1))?;
            let (_, mean) = tensor(&format!("bn{}.mean", i + 1))?;
            let (_, var) = tensor(&format!("bn{}.variance", i + 1))?;
            let inv: Vec<f64> = var
                .iter()
                .map(|&v| 1.0 / (v as f64 + BATCH_NORM_EPSILON).sqrt())
                .collect();
            // OIHW -> [(ky, kx, cin), cout], scaled by the batch norm.
            let mut weight = vec![0.0f32; kh * kw * cin * cout];
            for o in 0..cout {
                for a in 0..cin {
                    for y in 0..kh {
                        for x in 0..kw {
                            weight[((y * kw + x) * cin + a) * cout + o] =
                                (w[((o * cin + a) * kh + y) * kw + x] as f64 * inv[o]) as f32;
                        }
                    }
                }
            }
            let bias = (0..cout)
                .map(|o| (beta[o] as f64 - mean[o] as f64 * inv[o]) as f32)
                .collect();
            blocks.push(ConvBlock {
                weight,
                bias,
                cin,
                cout,
                kernel: kh,
                stride,
                pad: if same { kh / 2 } else { 0 },
            });
        }
        Ok(Self { blocks })
    }

    /// The stem's features of an RGB image with values in [0, 1].
    ///
    /// # Shapes
    /// - `rgb`: `[height, width, 3]`
    /// - output: `[h5, w5, 192]`, with `h5 = ((height - 3) / 2 - 1 - 3) / 2 - 1` (integer steps)
    pub fn features(&self, rgb: &[f32], height: usize, width: usize) -> Result<FeatureMap> {
        if height < MIN_SIDE || width < MIN_SIDE {
            return Err(input_error!(
                "a {width}x{height} image is too small for SIFID: the Inception stem needs at least {MIN_SIDE}x{MIN_SIDE} pixels"
            ));
        }
        assert_eq!(rgb.len(), height * width * 3);
        let mut x = FeatureMap {
            height,
            width,
            channels: 3,
            values: rgb.iter().map(|v| 2.0 * v - 1.0).collect(),
        };
        for (i, block) in self.blocks.iter().enumerate() {
            x = block.forward(&x); // conv2d_{i+1} + batch norm + ReLU
            if i == 2 {
                x = max_pool_3x3_s2(&x); // max_pooling2d_1
            }
        }
        Ok(x)
    }
}

/// A Gaussian fitted to feature samples: mean and unbiased covariance (as `np.cov`).
#[derive(Debug, Clone)]
pub struct Gaussian {
    pub mean: DVector<f64>,
    pub covariance: DMatrix<f64>,
}

impl Gaussian {
    /// Fits the Gaussian to the positions of a feature map (each position one sample).
    pub fn fit(features: &FeatureMap) -> Result<Self> {
        let c = features.channels;
        let n = features.values.len() / c;
        if n < 2 {
            return Err(input_error!(
                "SIFID needs at least 2 feature positions; the image is too small"
            ));
        }
        let samples = DMatrix::from_row_iterator(n, c, features.values.iter().map(|&v| v as f64));
        let mean = samples.row_mean().transpose();
        let centred = DMatrix::from_fn(n, c, |i, j| samples[(i, j)] - mean[j]);
        let covariance = (centred.transpose() * &centred) / (n as f64 - 1.0);
        Ok(Self { mean, covariance })
    }
}

/// The square root of a symmetric positive semi-definite matrix, by eigendecomposition
/// (negative eigenvalues from rounding are clamped to 0).
pub fn symmetric_sqrt(m: &DMatrix<f64>) -> DMatrix<f64> {
    let sym = (m + m.transpose()) * 0.5;
    let eigen = SymmetricEigen::new(sym);
    let roots = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
    &eigen.eigenvectors * DMatrix::from_diagonal(&roots) * eigen.eigenvectors.transpose()
}

/// The Fréchet distance `|m1 - m2|^2 + tr(S1) + tr(S2) - 2 tr((S1 S2)^(1/2))`, with the trace
/// term computed as `tr((A S2 A)^(1/2))` for `A = S1^(1/2)`: the same eigenvalues, but a
/// symmetric matrix, so no complex parts or non-symmetric square roots are involved.
pub fn frechet_distance(a: &Gaussian, b: &Gaussian) -> f64 {
    let diff = &a.mean - &b.mean;
    let root_a = symmetric_sqrt(&a.covariance);
    let middle = &root_a * &b.covariance * &root_a;
    let eigen = SymmetricEigen::new((&middle + middle.transpose()) * 0.5);
    let tr_covmean: f64 = eigen.eigenvalues.iter().map(|l| l.max(0.0).sqrt()).sum();
    diff.dot(&diff) + a.covariance.trace() + b.covariance.trace() - 2.0 * tr_covmean
}

/// An RGB view of an image in [-1, 1] (`[h, w, channels]`), mapped to [0, 1] for the stem:
/// gray is repeated, alpha and any further channels are dropped (as SinGAN's `[..., 0:3]`).
pub fn to_unit_rgb(values: &[f32], channels: usize) -> Result<Vec<f32>> {
    let unit = |v: f32| ((v + 1.0) * 0.5).clamp(0.0, 1.0);
    match channels {
        1 | 2 => Ok(values
            .chunks_exact(channels)
            .flat_map(|p| [unit(p[0]); 3])
            .collect()),
        c if c >= 3 => Ok(values
            .chunks_exact(c)
            .flat_map(|p| [unit(p[0]), unit(p[1]), unit(p[2])])
            .collect()),
        _ => Err(input_error!("an image with 0 channels has no SIFID")),
    }
}

/// SIFID between two RGB images in [0, 1] (`[h, w, 3]` each; sizes may differ).
pub fn sifid(a: (&[f32], usize, usize), b: (&[f32], usize, usize)) -> Result<f64> {
    let stem = InceptionStem::embedded();
    let fa = Gaussian::fit(&stem.features(a.0, a.1, a.2)?)?;
    let fb = Gaussian::fit(&stem.features(b.0, b.1, b.2)?)?;
    Ok(frechet_distance(&fa, &fb))
}

/// How visible the wrap seams of a tile are.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SeamScore {
    /// Across the vertical seam (last column to first).
    pub columns: f64,
    /// Across the horizontal seam (last row to first).
    pub rows: f64,
    /// Both seams together.
    pub overall: f64,
}

/// Lines on each side of a seam whose steps form the interior it is compared with. Comparing
/// with the whole interior instead would measure where the seam falls in the pattern's period
/// (a periodic pattern's gradient changes with its phase), not whether it shows.
pub const SEAM_BAND: usize = 8;

/// The seam score of a tile `[height, width, channels]` laid 2x2 (so it wraps onto itself):
/// the mean absolute step across each wrap seam over the mean step between the neighbouring
/// lines (up to [`SEAM_BAND`] on each side, inside the tile).
///
/// One tile's score depends on where its seam falls in the pattern: across the lines of a
/// seamless honeycomb tile it ranges from about 0.7 to 1.5 (5th to 95th percentile), while a wrap
/// that does not tile scores 4 to 5. [`seam_score_of_tiles`] averages over tiles cut at
/// different phases.
pub fn seam_score(tile: &[f32], height: usize, width: usize, channels: usize) -> Result<SeamScore> {
    seam_score_of_tiles(&[tile], height, width, channels)
}

/// The seam score of several tiles of one size together: summed seam steps over summed
/// interior steps.
pub fn seam_score_of_tiles(
    tiles: &[&[f32]],
    height: usize,
    width: usize,
    channels: usize,
) -> Result<SeamScore> {
    if height < 4 || width < 4 {
        return Err(input_error!(
            "a {width}x{height} tile is too small for a seam score (at least 4x4)"
        ));
    }
    let (mut seam_c, mut inner_c, mut seam_r, mut inner_r) = (0.0, 0.0, 0.0, 0.0);
    for tile in tiles {
        let at = |y: usize, x: usize, c: usize| tile[(y * width + x) * channels + c] as f64;
        // Mean absolute step between two columns (or rows), over the other axis.
        let col_step = |x0: usize, x1: usize| -> f64 {
            let mut s = 0.0;
            for y in 0..height {
                for c in 0..channels {
                    s += (at(y, x1, c) - at(y, x0, c)).abs();
                }
            }
            s / (height * channels) as f64
        };
        let row_step = |y0: usize, y1: usize| -> f64 {
            let mut s = 0.0;
            for x in 0..width {
                for c in 0..channels {
                    s += (at(y1, x, c) - at(y0, x, c)).abs();
                }
            }
            s / (width * channels) as f64
        };
        // (seam step, mean step of the lines beside it) along an axis of length n.
        let measure = |n: usize, step: &dyn Fn(usize, usize) -> f64| -> (f64, f64) {
            let band = SEAM_BAND.min((n - 2) / 2);
            let inner: f64 = (0..band)
                .map(|i| step(i, i + 1) + step(n - 2 - i, n - 1 - i))
                .sum::<f64>()
                / (2 * band) as f64;
            (step(n - 1, 0), inner)
        };
        let (s, i) = measure(width, &col_step);
        seam_c += s;
        inner_c += i;
        let (s, i) = measure(height, &row_step);
        seam_r += s;
        inner_r += i;
    }
    let ratio = |seam: f64, inner: f64| {
        if inner > 0.0 {
            seam / inner
        } else if seam > 0.0 {
            f64::INFINITY
        } else {
            1.0
        }
    };
    Ok(SeamScore {
        columns: ratio(seam_c, inner_c),
        rows: ratio(seam_r, inner_r),
        overall: ratio(seam_c + seam_r, inner_c + inner_r),
    })
}

/// The dominant period (pixels) along rows (vertical, `[0]`) and columns (horizontal, `[1]`)
/// of an image `[height, width, channels]`: the lag of the first autocorrelation peak after the
/// first minimum that reaches 70% of the highest peak, for lags up to half the side, refined to
/// a fraction of a pixel by a parabola. `None` where there is no such peak.
pub fn dominant_period(
    values: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> [Option<f64>; 2] {
    // Luminance-like mean over channels, with the mean removed.
    let gray: Vec<f64> = values
        .chunks_exact(channels)
        .map(|p| p.iter().map(|&v| v as f64).sum::<f64>() / channels as f64)
        .collect();
    let mean = gray.iter().sum::<f64>() / gray.len().max(1) as f64;
    let g = |y: usize, x: usize| gray[y * width + x] - mean;
    // Normalised autocorrelation along one axis, averaged over the other.
    let along = |len: usize, other: usize, pick: &dyn Fn(usize, usize) -> f64| -> Option<f64> {
        let max_lag = len / 2;
        if max_lag < 3 {
            return None;
        }
        let r: Vec<f64> = (0..=max_lag)
            .map(|lag| {
                let mut s = 0.0;
                for o in 0..other {
                    for i in 0..len - lag {
                        s += pick(o, i) * pick(o, i + lag);
                    }
                }
                s / ((len - lag) * other) as f64
            })
            .collect();
        if r[0] <= 0.0 {
            return None;
        }
        let first_min = (1..max_lag).find(|&l| r[l] <= r[l - 1] && r[l] <= r[l + 1])?;
        let peaks: Vec<usize> = (first_min + 1..max_lag)
            .filter(|&l| r[l] > r[l - 1] && r[l] >= r[l + 1] && r[l] > 0.0)
            .collect();
        let highest = peaks.iter().map(|&l| r[l]).fold(0.0, f64::max);
        // The first peak nearly as high as the highest: a non-integer period's multiples can
        // land closer to whole lags and so stand slightly higher than the period itself.
        let peak = *peaks.iter().find(|&&l| r[l] >= 0.7 * highest)?;
        // Parabolic refinement of the peak's lag.
        let (a, b, c) = (r[peak - 1], r[peak], r[peak + 1]);
        let denom = a - 2.0 * b + c;
        let shift = if denom.abs() > 1e-12 {
            (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        Some(peak as f64 + shift)
    };
    [
        along(height, width, &|x, y| g(y, x)),
        along(width, height, &|y, x| g(y, x)),
    ]
}

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
    /// Seam score of `--tile` samples of the exemplar's size (one per seed), laid 2x2.
    pub seam_model_tile: SeamScore,
    /// Seam score of the exemplar itself laid 2x2, for comparison.
    pub seam_exemplar: SeamScore,
    /// The model's period (octave 0 of the encoding, `|K| * crop` pixels): rows, columns.
    pub period_model: [f64; 2],
    /// The exemplar's dominant period from its autocorrelation: rows, columns.
    pub period_exemplar: [Option<f64>; 2],
    pub width: usize,
    pub height: usize,
    pub seed: u64,
}

/// Evaluates a model against its exemplar (values in [-1, 1], `[h, w, c]`).
pub fn evaluate_model(
    config: &crate::generator::GeneratorConfig,
    weights: &crate::generator::GeneratorWeights,
    exemplar: &crate::io::Exemplar,
    samples: usize,
    seed: u64,
    device: crate::synth::DeviceChoice,
) -> Result<ModelReport> {
    use crate::synth::Synth;
    if samples == 0 {
        return Err(input_error!("--samples 0: need at least one sample"));
    }
    if exemplar.channels != config.channels {
        return Err(input_error!(
            "the exemplar has {} channels but the model paints {}; evaluate a model with the exemplar it was trained on",
            exemplar.channels,
            config.channels
        ));
    }
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    let stem = InceptionStem::embedded();
    let real = Gaussian::fit(&stem.features(&to_unit_rgb(&exemplar.values, c)?, h, w)?)?;
    let mut sifids = Vec::with_capacity(samples);
    for s in 0..samples as u64 {
        let painter = Synth::new(config.clone(), weights.clone())
            .seed(seed.wrapping_add(s))
            .device(device)
            .painter()?;
        let fake = painter.render(0, 0, w, h);
        let fake = Gaussian::fit(&stem.features(&to_unit_rgb(&fake, c)?, h, w)?)?;
        sifids.push(frechet_distance(&real, &fake));
    }
    // One --tile sample per seed, each cut at another phase of the pattern (an offset within
    // the tile's period keeps it a tile), so the seam score does not measure one phase.
    let mut tiles = Vec::with_capacity(samples);
    for s in 0..samples as u64 {
        let golden = |n: usize, k: u64| ((k as f64 * 0.618_033_988_75).fract() * n as f64) as i64;
        let painter = Synth::new(config.clone(), weights.clone())
            .seed(seed.wrapping_add(s))
            .device(device)
            .tile(w, h)
            .offset(golden(w, s), golden(h, s + 7))
            .painter()?;
        tiles.push(painter.render(0, 0, w, h));
    }
    let tiles: Vec<&[f32]> = tiles.iter().map(Vec::as_slice).collect();
    let period = |axis: usize| (weights.k[axis].abs() * config.crop as f32) as f64;
    Ok(ModelReport {
        metric: SIFID_NAME,
        sifid: Summary::of(sifids),
        seam_model_tile: seam_score_of_tiles(&tiles, h, w, c)?,
        seam_exemplar: seam_score(&exemplar.values, h, w, c)?,
        period_model: [period(0), period(1)],
        period_exemplar: dominant_period(&exemplar.values, h, w, c),
        width: w,
        height: h,
        seed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
