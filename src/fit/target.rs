//! What a fit matches: the photo's colours inside the tile and its gradients near the border
//! (the Poisson seam term), per stage a blurred level of the photo, less what the stages below
//! already paint; and the batches of pixels each step draws.

use super::fused::Batch;
use crate::exemplar::Exemplar;
use crate::latent::derive_seed;

/// `λ` of the seam term at every pixel `[H, W]`: 0 inside, rising smoothly (smoothstep) to 1 at
/// the border over the outer `band` of the distance from the centre to the border (the
/// larger of the two axes' distances, each over its half-size). The value term has weight
/// `1 - λ`, so at the border only the photo's gradients are matched and the colours are free
/// to bend to meet the other side.
pub fn seam_mask(height: usize, width: usize, band: f32) -> Vec<f32> {
    let mut lambda = Vec::with_capacity(height * width);
    let r = |i: usize, n: usize| ((2.0 * (i as f32 + 0.5) / n as f32) - 1.0).abs();
    for y in 0..height {
        for x in 0..width {
            let d = r(y, height).max(r(x, width));
            let t = if band <= 0.0 {
                0.0
            } else {
                ((d - (1.0 - band)) / band).clamp(0.0, 1.0)
            };
            lambda.push(t * t * (3.0 - 2.0 * t));
        }
    }
    lambda
}

/// The photo's gradients by a Sobel filter (per pixel, edges clamped: the border's gradients
/// are the photo's own, not the jump to the opposite side), `[H, W, 2, C]`, along rows then
/// columns.
pub fn sobel(image: &Exemplar) -> Vec<f32> {
    let (h, w, c) = (image.height, image.width, image.channels);
    let at = |y: isize, x: isize, ch: usize| {
        let y = y.clamp(0, h as isize - 1) as usize;
        let x = x.clamp(0, w as isize - 1) as usize;
        image.values[(y * w + x) * c + ch]
    };
    let mut out = vec![0f32; h * w * 2 * c];
    for y in 0..h as isize {
        for x in 0..w as isize {
            for ch in 0..c {
                let mut g = [0f32; 2];
                for (o, k) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                    g[0] += k * (at(y + 1, x + o, ch) - at(y - 1, x + o, ch));
                    g[1] += k * (at(y + o, x + 1, ch) - at(y + o, x - 1, ch));
                }
                let i = (y as usize * w + x as usize) * 2 * c;
                out[i + ch] = g[0] / 8.0;
                out[i + c + ch] = g[1] / 8.0;
            }
        }
    }
    out
}

/// A separable Gaussian blur of `sigma` pixels per axis `[rows, cols]` (edges clamped).
pub fn blur(image: &Exemplar, sigma: [f32; 2]) -> Exemplar {
    let (h, w, c) = (image.height, image.width, image.channels);
    let kernel = |s: f32| -> Vec<f32> {
        if s <= 0.0 {
            return vec![1.0];
        }
        let r = (3.0 * s).ceil() as isize;
        let k: Vec<f32> = (-r..=r)
            .map(|i| (-(i * i) as f32 / (2.0 * s * s)).exp())
            .collect();
        let total: f32 = k.iter().sum();
        k.iter().map(|v| v / total).collect()
    };
    let pass = |src: &[f32], k: &[f32], along_rows: bool| -> Vec<f32> {
        let r = (k.len() / 2) as isize;
        let mut out = vec![0f32; src.len()];
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let mut v = 0.0;
                    for (i, kv) in k.iter().enumerate() {
                        let o = i as isize - r;
                        let (yy, xx) = if along_rows {
                            ((y as isize + o).clamp(0, h as isize - 1) as usize, x)
                        } else {
                            (y, (x as isize + o).clamp(0, w as isize - 1) as usize)
                        };
                        v += kv * src[(yy * w + xx) * c + ch];
                    }
                    out[(y * w + x) * c + ch] = v;
                }
            }
        }
        out
    };
    let rows = pass(&image.values, &kernel(sigma[0]), true);
    let values = pass(&rows, &kernel(sigma[1]), false);
    Exemplar {
        values,
        ..image.clone()
    }
}

/// One stage's targets over the whole tile: what is left for this stage to paint.
pub struct StageTarget {
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    /// `[H, W, C]`: the stage's level of the photo less the stages below.
    pub values: Vec<f32>,
    /// `[H, W, 2, C]`: the level's gradients less the stages below'.
    pub gradients: Vec<f32>,
    /// `[H, W]`: λ of the seam term.
    pub lambda: Vec<f32>,
    /// The pixels in the loss (mask white), seam pixels (`λ > 0`) first.
    pub pixels: Vec<u32>,
    /// How many of `pixels` have `λ > 0`.
    pub seam_pixels: usize,
}

impl StageTarget {
    /// `level`: the photo at this stage's level of detail; `below`: values `[H, W, C]` and
    /// tangents `[H, W, 2, C]` the stages below paint; `mask`: `[H, W]`, pixels at or below 0.5
    /// left out.
    pub fn new(
        level: &Exemplar,
        below: Option<(&[f32], &[f32])>,
        lambda: Vec<f32>,
        mask: Option<&[f32]>,
    ) -> Self {
        let mut values = level.values.clone();
        let mut gradients = sobel(level);
        if let Some((v, t)) = below {
            values.iter_mut().zip(v).for_each(|(a, b)| *a -= b);
            gradients.iter_mut().zip(t).for_each(|(a, b)| *a -= b);
        }
        let kept = |i: usize| mask.is_none_or(|m| m[i] > 0.5);
        let n = level.width * level.height;
        let mut pixels: Vec<u32> = (0..n)
            .filter(|&i| kept(i) && lambda[i] > 0.0)
            .map(|i| i as u32)
            .collect();
        let seam_pixels = pixels.len();
        pixels.extend(
            (0..n)
                .filter(|&i| kept(i) && lambda[i] <= 0.0)
                .map(|i| i as u32),
        );
        Self {
            height: level.height,
            width: level.width,
            channels: level.channels,
            values,
            gradients,
            lambda,
            pixels,
            seam_pixels,
        }
    }

    /// The batch of step `step`: `size` pixels drawn uniformly from those in the loss, seam
    /// pixels first, each a hash of `(seed, step, i)`.
    pub fn batch(&self, size: usize, seed: u64, step: u64) -> OwnedBatch {
        let c = self.channels;
        let mut picked: Vec<u32> = (0..size as u64)
            .map(|i| {
                let r = derive_seed(seed, &[step, i]) % self.pixels.len() as u64;
                r as u32
            })
            .collect();
        picked.sort_unstable();
        let mut b = OwnedBatch::default();
        for &slot in &picked {
            let p = self.pixels[slot as usize] as usize;
            let (y, x) = (p / self.width, p % self.width);
            b.positions.extend([y as f32 + 0.5, x as f32 + 0.5]);
            b.values.extend_from_slice(&self.values[p * c..(p + 1) * c]);
            b.gradients
                .extend_from_slice(&self.gradients[p * 2 * c..(p + 1) * 2 * c]);
            let l = self.lambda[p];
            b.value_weight.push(1.0 - l);
            b.gradient_weight.push(l);
        }
        b
    }
}

/// A batch's data, owned.
#[derive(Default)]
pub struct OwnedBatch {
    pub positions: Vec<f32>,
    pub values: Vec<f32>,
    pub gradients: Vec<f32>,
    pub value_weight: Vec<f32>,
    pub gradient_weight: Vec<f32>,
}

impl OwnedBatch {
    pub fn view(&self) -> Batch<'_> {
        Batch {
            positions: &self.positions,
            values: &self.values,
            gradients: &self.gradients,
            value_weight: &self.value_weight,
            gradient_weight: &self.gradient_weight,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seam_mask_is_zero_inside_and_one_at_the_border() {
        let m = seam_mask(64, 32, 0.25);
        assert_eq!(m[32 * 32 + 16], 0.0);
        assert!(m[0] > 0.9 && m[63 * 32 + 31] > 0.9);
        assert!(m.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn sobel_of_a_ramp_is_its_slope() {
        let values: Vec<f32> = (0..8 * 8).map(|i| (i % 8) as f32 * 0.1).collect();
        let ramp = Exemplar {
            width: 8,
            height: 8,
            depth: 1,
            channels: 1,
            values,
        };
        let g = sobel(&ramp);
        let i = (3 * 8 + 4) * 2;
        assert!(g[i].abs() < 1e-6 && (g[i + 1] - 0.1).abs() < 1e-6);
    }
}
