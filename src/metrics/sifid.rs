//! SIFID: the Fréchet distance between Gaussians fitted to InceptionV3 stem features of two
//! images (see the module above for which weights and why).

use std::sync::OnceLock;

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;
use safetensors::SafeTensors;

use crate::error::{Error, Result};
use crate::generator::fused::matmul_into;
use crate::input_error;

/// The converted stem, embedded in the binary (about 690 KB).
const EMBEDDED_STEM: &[u8] = include_bytes!("../../assets/inception_v3_stem.safetensors");

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
