//! A stage of the periodic network on the CPU: forward with exact spatial tangents, and the
//! hand-written backward of the Poisson loss, each layer one `gemm` over a chunk of points.
//!
//! A chunk's rows are its points' values, followed (with tangents) by their tangents along
//! rows and along columns: `S = 1` or `3` streams of `n` rows. One product per layer moves all
//! streams through `W` at once, since a tangent goes through a layer as `t' = ω0 cos(ω0 z) ⊙ (t W)`:
//! - first layer: `h = sin(θ)`, `θ = ω·p + φ`; `t_d = cos(θ) ω_d`;
//! - hidden: `q = ω0 (h W + b)`, `h' = sin q`; `a_d = t_d W`, `t'_d = ω0 cos(q) ⊙ a_d`;
//! - head: `f = h W + b`, `t_d' = t_d W`.
//!
//! The loss of a point is `(wv |f - I|² + wg Σ_d |t_d - U_d|²) / C` (`wv = (1 - λ)·mask`,
//! `wg = λ·mask`), and its backward through a hidden layer is
//! `dz = ω0 cos q ⊙ dh' - ω0² sin q ⊙ Σ_d dt'_d ⊙ a_d`, `da_d = ω0 cos q ⊙ dt'_d`,
//! `dW += [h; t]ᵀ [dz; da]`, `[dh; dt] = [dz; da] Wᵀ`. [`super::reference`] computes the same
//! with burn's autodiff; a test compares them.

use rayon::prelude::*;

use super::network::{StageShape, angular, view};
use crate::generator::fused::matmul_strided as product;

/// Points per chunk: a chunk's activations stay in cache.
pub const CHUNK: usize = 128;
/// The batch is cut into this many parts whatever the thread count, and their gradients are
/// summed in order, so a step is the same on any machine.
const PARTS: usize = 16;

/// One stage and what its evaluation needs.
pub struct Stage<'a> {
    pub shape: &'a StageShape,
    pub params: &'a [f32],
    pub channels: usize,
    pub omega0: f32,
    /// `2π k / P` per frequency and axis.
    pub angular: Vec<[f32; 2]>,
}

impl<'a> Stage<'a> {
    pub fn new(
        shape: &'a StageShape,
        params: &'a [f32],
        channels: usize,
        omega0: f32,
        period: [usize; 2],
    ) -> Self {
        Self {
            shape,
            params,
            channels,
            omega0,
            angular: angular(shape, period),
        }
    }
}

/// Targets of a batch of points.
///
/// # Shapes
/// - `positions`: `[n, 2]` pixel positions (row, column)
/// - `values`: `[n, C]`; `gradients`: `[n, 2, C]` (per row axis then column axis)
/// - `value_weight`, `gradient_weight`: `[n]`
pub struct Batch<'a> {
    pub positions: &'a [f32],
    pub values: &'a [f32],
    pub gradients: &'a [f32],
    pub value_weight: &'a [f32],
    pub gradient_weight: &'a [f32],
}

/// The activations of one chunk, kept for the backward pass.
#[derive(Default)]
struct Tape {
    /// Per dense layer, its input rows `[S n, inputs]` (layer 0's is the first layer's output).
    inputs: Vec<Vec<f32>>,
    /// Per hidden layer, `[q; a_d]`: the values' pre-activation `ω0 (hW + b)` and the tangents'
    /// `t W`, `[S n, outputs]`.
    products: Vec<Vec<f32>>,
    /// Per hidden layer, `cos q`, `[n, outputs]` (`sin q` is the next layer's input).
    cos: Vec<Vec<f32>>,
    /// The first layer's `cos θ`, `[n, F]` (`sin θ` is layer 0's input).
    cos_theta: Vec<f32>,
    /// The head's outputs `[S n, C]`.
    out: Vec<f32>,
}

impl Stage<'_> {
    /// Runs `n` points forward with `streams` (1: values; 3: values and tangents) into `tape`.
    fn forward(&self, positions: &[f32], streams: usize, tape: &mut Tape) {
        let n = positions.len() / 2;
        let w = view(self.shape, self.channels, self.params);
        let f = self.shape.frequencies.len();
        let layers = w.layers.len();
        tape.inputs.resize_with(layers, Vec::new);
        tape.products.resize_with(layers - 1, Vec::new);
        tape.cos.resize_with(layers - 1, Vec::new);
        tape.cos_theta.resize(n * f, 0.0);
        let x = &mut tape.inputs[0];
        x.resize(streams * n * f, 0.0);
        for (i, p) in positions.chunks_exact(2).enumerate() {
            for (j, (om, phase)) in self.angular.iter().zip(w.phase).enumerate() {
                let theta = om[0] * p[0] + om[1] * p[1] + phase;
                let (s, c) = theta.sin_cos();
                tape.cos_theta[i * f + j] = c;
                x[i * f + j] = s;
                if streams == 3 {
                    x[(n + i) * f + j] = c * om[0];
                    x[(2 * n + i) * f + j] = c * om[1];
                }
            }
        }
        let rows = streams * n;
        let dims = self.shape.layers(self.channels);
        for (l, &(weight, bias)) in w.layers.iter().enumerate() {
            let (inputs, outputs) = dims[l];
            let (head, rest) = tape.inputs.split_at_mut(l + 1);
            let x = &head[l];
            let y = if l + 1 < layers {
                &mut tape.products[l]
            } else {
                &mut tape.out
            };
            y.resize(rows * outputs, 0.0);
            product(
                y,
                (rows, outputs, inputs),
                x,
                (inputs, 1),
                weight,
                (outputs, 1),
                false,
            );
            for row in y[..n * outputs].chunks_exact_mut(outputs) {
                for (v, b) in row.iter_mut().zip(bias) {
                    *v += b;
                }
            }
            if l + 1 == layers {
                break;
            }
            let om = self.omega0;
            for v in &mut y[..n * outputs] {
                *v *= om;
            }
            let next = &mut rest[0];
            next.resize(rows * outputs, 0.0);
            let cos = &mut tape.cos[l];
            cos.resize(n * outputs, 0.0);
            let (q, a) = y.split_at(n * outputs);
            let (h, t) = next.split_at_mut(n * outputs);
            for ((h, c), q) in h.iter_mut().zip(cos.iter_mut()).zip(q) {
                (*h, *c) = q.sin_cos();
            }
            for (s, t) in t.chunks_exact_mut(n * outputs).enumerate() {
                let a = &a[s * n * outputs..(s + 1) * n * outputs];
                for ((t, a), c) in t.iter_mut().zip(a).zip(cos.iter()) {
                    *t = om * c * a;
                }
            }
        }
    }

    /// Evaluates `n` points: values `[n, C]` and, when `tangents` is given, `[n, 2, C]`
    /// derivatives along rows and columns (per pixel).
    pub fn eval(&self, positions: &[f32], values: &mut [f32], tangents: Option<&mut [f32]>) {
        let c = self.channels;
        let streams = if tangents.is_some() { 3 } else { 1 };
        let mut tangents = tangents;
        let mut tape = Tape::default();
        for (chunk, (p, v)) in positions
            .chunks(2 * CHUNK)
            .zip(values.chunks_mut(CHUNK * c))
            .enumerate()
        {
            let n = p.len() / 2;
            self.forward(p, streams, &mut tape);
            v.copy_from_slice(&tape.out[..n * c]);
            if let Some(t) = tangents.as_deref_mut() {
                let t = &mut t[chunk * CHUNK * 2 * c..][..n * 2 * c];
                for i in 0..n {
                    for d in 0..2 {
                        let from = &tape.out[((1 + d) * n + i) * c..][..c];
                        t[(i * 2 + d) * c..][..c].copy_from_slice(from);
                    }
                }
            }
        }
    }

    /// The loss summed over `batch` and its gradient with respect to this stage's parameters
    /// (summed, not averaged), on rayon's pool. Tangents are computed only for chunks where some
    /// point has a gradient weight: give points with `gradient_weight > 0` first for speed.
    pub fn loss_and_gradient(&self, batch: &Batch) -> (f64, Vec<f32>) {
        let n = batch.value_weight.len();
        let per_part = n.div_ceil(PARTS).div_ceil(CHUNK) * CHUNK;
        let parts: Vec<(f64, Vec<f32>)> = (0..PARTS)
            .into_par_iter()
            .map(|part| {
                let mut grad = vec![0f32; self.params.len()];
                let mut tape = Tape::default();
                let mut loss = 0.0;
                let range = (part * per_part).min(n)..((part + 1) * per_part).min(n);
                for start in range.clone().step_by(CHUNK) {
                    let end = (start + CHUNK).min(range.end);
                    loss += self.chunk_backward(batch, start..end, &mut tape, &mut grad);
                }
                (loss, grad)
            })
            .collect();
        let mut total = vec![0f32; self.params.len()];
        let mut loss = 0.0;
        for (l, g) in parts {
            loss += l;
            for (t, g) in total.iter_mut().zip(g) {
                *t += g;
            }
        }
        (loss, total)
    }

    /// One chunk's loss, its gradient added to `grad`.
    fn chunk_backward(
        &self,
        batch: &Batch,
        range: std::ops::Range<usize>,
        tape: &mut Tape,
        grad: &mut [f32],
    ) -> f64 {
        let (n, c) = (range.len(), self.channels);
        let tangents = batch.gradient_weight[range.clone()]
            .iter()
            .any(|&w| w > 0.0);
        let streams = if tangents { 3 } else { 1 };
        self.forward(
            &batch.positions[2 * range.start..2 * range.end],
            streams,
            tape,
        );

        // The loss and its gradient at the head's outputs: [S n, C].
        let mut g = vec![0f32; streams * n * c];
        let mut loss = 0.0f64;
        for i in 0..n {
            let at = range.start + i;
            let (wv, wg) = (batch.value_weight[at], batch.gradient_weight[at]);
            for ch in 0..c {
                let e = tape.out[i * c + ch] - batch.values[at * c + ch];
                loss += (wv * e * e) as f64;
                g[i * c + ch] = 2.0 * wv * e / c as f32;
                if tangents {
                    for d in 0..2 {
                        let r = (1 + d) * n + i;
                        let e = tape.out[r * c + ch] - batch.gradients[(at * 2 + d) * c + ch];
                        loss += (wg * e * e) as f64;
                        g[r * c + ch] = 2.0 * wg * e / c as f32;
                    }
                }
            }
        }

        let shape = self.shape;
        let w = view(shape, c, self.params);
        let f = shape.frequencies.len();
        let layers = shape.layers(c);
        let offsets = layer_offsets(shape, c);
        let rows = streams * n;
        for l in (0..layers.len()).rev() {
            let (inputs, outputs) = layers[l];
            if l + 1 < layers.len() {
                // g holds [dh'; dt'] of this hidden layer's output: turn it into [dz; da].
                let om = self.omega0;
                let a = &tape.products[l][n * outputs..];
                let (sin, cos) = (&tape.inputs[l + 1][..n * outputs], &tape.cos[l]);
                let (gq, ga) = g.split_at_mut(n * outputs);
                for j in 0..n * outputs {
                    let (s, co) = (sin[j], cos[j]);
                    let mut cross = 0.0;
                    for d in 0..streams - 1 {
                        let k = d * n * outputs + j;
                        cross += ga[k] * a[k];
                        ga[k] *= om * co;
                    }
                    // dz = ω0 dq, with dq = cos q dh' - ω0 sin q Σ_d dt'_d a_d.
                    gq[j] = om * (co * gq[j] - om * s * cross);
                }
            }
            let (w_off, b_off) = offsets[l];
            let x = &tape.inputs[l];
            let gw = &mut grad[w_off..w_off + inputs * outputs];
            product(
                gw,
                (inputs, outputs, rows),
                x,
                (1, inputs),
                &g,
                (outputs, 1),
                true,
            );
            for row in g[..n * outputs].chunks_exact(outputs) {
                for (gb, v) in grad[b_off..b_off + outputs].iter_mut().zip(row) {
                    *gb += v;
                }
            }
            let mut gx = vec![0f32; rows * inputs];
            let weight = w.layers[l].0;
            product(
                &mut gx,
                (rows, inputs, outputs),
                &g,
                (outputs, 1),
                weight,
                (1, outputs),
                false,
            );
            g = gx;
        }
        // The first layer: dφ = Σ dh cos θ - Σ_d dt_d sin θ ω_d.
        for i in 0..n {
            for j in 0..f {
                let (s, co) = (tape.inputs[0][i * f + j], tape.cos_theta[i * f + j]);
                let mut d = g[i * f + j] * co;
                if tangents {
                    let om = self.angular[j];
                    d -= s * (g[(n + i) * f + j] * om[0] + g[(2 * n + i) * f + j] * om[1]);
                }
                grad[j] += d;
            }
        }
        loss / c as f64
    }
}

/// Offsets of each dense layer's `W` and `b` in a stage's flat parameters.
pub fn layer_offsets(shape: &StageShape, channels: usize) -> Vec<(usize, usize)> {
    let mut at = shape.frequencies.len();
    shape
        .layers(channels)
        .into_iter()
        .map(|(i, o)| {
            let w = at;
            at += i * o + o;
            (w, w + i * o)
        })
        .collect()
}
