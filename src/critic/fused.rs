//! The critic's training step on the CPU, fused: the loss `mean D(fake) - mean D(real) + P` and
//! its gradient with respect to every weight, by hand, with every product one `gemm` call.
//!
//! Each stride-2 convolution is an im2col followed by one product, on channels-last activations
//! (`[batch · positions, channels]`); the weights stay in the framework's layout
//! (`[out, in · taps]`), read transposed where a product needs it, so nothing is reordered.
//! Products run on rayon's pool through `gemm`, which splits outputs, never sums, between
//! threads: the result, and training, do not depend on the thread count.
//!
//! The penalty is differentiated as [`super::Critic::input_gradient`] builds it: with the
//! LeakyReLU slope masks `M_l` at `x_hat` fixed, the input gradient is a chain of transposed
//! convolutions `g_{l-1} = T_l(M_l ⊙ g_l)` from the head's weight down; its adjoint runs the
//! same layers upwards as plain convolutions (`T_l^T = im2col · W_l`), giving each weight's
//! share of `dP/dW_l = im2col(δ_{l-1})^T · (M_l ⊙ g_l)`. `tests.rs` checks every gradient
//! against burn's autodiff of the framework critic, on 2 and 3 axes.

use burn::prelude::*;
use rayon::prelude::*;

use super::geometry::Geometry;
use super::{Critic, KERNEL};
use crate::checkpoint::{Checkpoint, read_module};
use crate::generator::fused::{matmul_parallel, product_parallel};

/// `x · w^T` for channels-last `x` `[rows, patch]` and the framework's weight `w`
/// `[out, patch]`: `[rows, out]`.
fn times_transposed(x: &[f32], w: &[f32], rows: usize, patch: usize, out: usize) -> Vec<f32> {
    product_parallel((rows, out, patch), (x, (patch, 1)), (w, (1, patch)))
}

/// `d · w` for `d` `[rows, out]` and `w` `[out, patch]`: `[rows, patch]`.
fn times(d: &[f32], w: &[f32], rows: usize, out: usize, patch: usize) -> Vec<f32> {
    product_parallel((rows, patch, out), (d, (out, 1)), (w, (patch, 1)))
}

/// `dw += d^T · x` for `d` `[rows, out]` and `x` `[rows, patch]`: a weight's gradient
/// `[out, patch]`, summed in place (`dw` empty: none yet, so the product is written).
fn add_weight_gradient(dw: &mut Vec<f32>, d: &[f32], x: &[f32], rows: usize, patch: usize) {
    let out = d.len() / rows;
    let (shape, d, x) = ((out, patch, rows), (d, (1, out)), (x, (patch, 1)));
    match dw.is_empty() {
        true => *dw = product_parallel(shape, d, x),
        false => matmul_parallel(dw, shape, d, x, true),
    }
}

/// `[batch, channels, positions...]` to `[batch · positions, channels]`.
fn channels_last(x: &[f32], [batch, channels, depth, rows, cols]: [usize; 5]) -> Vec<f32> {
    let positions = depth * rows * cols;
    let mut out = Vec::with_capacity(batch * channels * positions);
    for sample in x.chunks_exact(channels * positions) {
        for p in 0..positions {
            out.extend((0..channels).map(|c| sample[c * positions + p]));
        }
    }
    out
}

/// The LeakyReLU's derivative where the activation is `a` (its sign is the pre-activation's).
fn slope_at(a: f32, slope: f32) -> f32 {
    if a > 0.0 { 1.0 } else { slope }
}

/// One forward pass: every layer's activations, and (for the score path's backward) every
/// layer's im2col matrix.
struct Pass {
    cols: Vec<Vec<f32>>,
    activations: Vec<Vec<f32>>,
    scores: Vec<f32>,
}

/// The critic's loss, and its gradient in the framework's layouts.
pub struct CriticStep {
    /// Mean D(real) - mean D(fake).
    pub wasserstein: f32,
    pub penalty: f32,
    /// Per convolution: weight `[out, in, depth taps, taps, taps]` and bias, flattened.
    pub convs: Vec<(Vec<f32>, Vec<f32>)>,
    /// The head's weight `[features, 1]` (features in `[channels, positions]` order) and bias.
    pub head: (Vec<f32>, f32),
}

/// A host copy of a critic's weights in the layouts of the fused step.
pub struct FusedCritic {
    layers: Vec<Geometry>,
    /// Per layer, the framework's `[outputs, inputs · taps]`.
    weights: Vec<Vec<f32>>,
    biases: Vec<Vec<f32>>,
    /// The head's weight channels-last: `[positions · channels]`.
    head: Vec<f32>,
    head_bias: f32,
    slope: f32,
    /// Which convolutions, and whether the head, have a bias parameter (a missing one is held
    /// as zeros and never updated).
    has_bias: (Vec<bool>, bool),
}

fn host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.try_into_vec_as::<f32>()
        .expect("critic weights are readable as f32")
}

impl FusedCritic {
    /// `critic`'s weights for inputs of `channels` and spatial `shape` `[depth, rows, cols]`
    /// (depth 1 in 2D).
    pub fn new(critic: &Critic, channels: usize, shape: [usize; 3]) -> Self {
        let volumetric = critic.axes == 3;
        let (mut input, mut inputs) = (shape, channels);
        let mut layers = Vec::new();
        let (mut weights, mut biases) = (Vec::new(), Vec::new());
        for conv in &critic.convs {
            let w = conv.weight.val();
            let [outputs, _, td, th, tw] = w.dims();
            let depth_axis = |v3: usize, v2: usize| if volumetric { v3 } else { v2 };
            let g = Geometry {
                inputs,
                outputs,
                taps: [td, th, tw],
                stride: [depth_axis(2, 1), 2, 2],
                pad: [depth_axis(1, 0), 1, 1],
                input,
                output: [depth_axis(input[0] / 2, 1), input[1] / 2, input[2] / 2],
            };
            debug_assert_eq!([th, tw], [KERNEL, KERNEL]);
            weights.push(host(w));
            biases.push(
                conv.bias
                    .as_ref()
                    .map_or(vec![0.0; outputs], |b| host(b.val())),
            );
            (input, inputs) = (g.output, outputs);
            layers.push(g);
        }
        let positions: usize = input.iter().product();
        let hw = host(critic.head.weight.val()); // [channels · positions, 1]
        let mut head = vec![0f32; hw.len()];
        for c in 0..inputs {
            for p in 0..positions {
                head[p * inputs + c] = hw[c * positions + p];
            }
        }
        let head_bias = critic.head.bias.as_ref().map_or(0.0, |b| host(b.val())[0]);
        let has_bias = (
            critic.convs.iter().map(|c| c.bias.is_some()).collect(),
            critic.head.bias.is_some(),
        );
        Self {
            layers,
            weights,
            biases,
            head,
            head_bias,
            slope: critic.slope as f32,
            has_bias,
        }
    }

    /// The head's weight `values` (or its gradient) reordered between the fused layout
    /// (`[positions, channels]`) and the framework's (`[channels, positions]`).
    fn reorder_head(&self, values: &[f32], to_framework: bool) -> Vec<f32> {
        let last = self.layers.last().expect("critic has convolutions");
        let (channels, positions) = (last.outputs, last.out_positions());
        let mut out = vec![0f32; values.len()];
        for c in 0..channels {
            for p in 0..positions {
                let (framework, fused) = (c * positions + p, p * channels + c);
                if to_framework {
                    out[framework] = values[fused];
                } else {
                    out[fused] = values[framework];
                }
            }
        }
        out
    }

    /// Updates every weight in place: `update(path, values, gradient)` for each parameter, by
    /// its path in the framework critic (`convs.0.weight`, ..., `head.bias`), values and
    /// gradient in the framework's layout. The optimiser's step on the CPU, with no copy of
    /// the weights through the framework.
    pub fn apply(&mut self, step: &CriticStep, mut update: impl FnMut(&str, &mut [f32], &[f32])) {
        for (l, (w, b)) in step.convs.iter().enumerate() {
            update(&format!("convs.{l}.weight"), &mut self.weights[l], w);
            if self.has_bias.0[l] {
                update(&format!("convs.{l}.bias"), &mut self.biases[l], b);
            }
        }
        let mut head = self.reorder_head(&self.head, true);
        update("head.weight", &mut head, &step.head.0);
        self.head = self.reorder_head(&head, false);
        if self.has_bias.1 {
            let mut bias = [self.head_bias];
            update("head.bias", &mut bias, &[step.head.1]);
            self.head_bias = bias[0];
        }
    }

    /// `critic` with these weights (its parameters' identities kept).
    pub fn write_into(&self, critic: Critic) -> Critic {
        let mut weights = Checkpoint::new();
        for (l, g) in self.layers.iter().enumerate() {
            let [td, th, tw] = g.taps;
            let shape = vec![g.outputs, g.inputs, td, th, tw];
            weights.insert(
                format!("c.convs.{l}.weight"),
                shape,
                self.weights[l].clone(),
            );
            let bias = self.biases[l].clone();
            weights.insert(format!("c.convs.{l}.bias"), vec![g.outputs], bias);
        }
        let head = self.reorder_head(&self.head, true);
        weights.insert("c.head.weight", vec![head.len(), 1], head);
        weights.insert("c.head.bias", vec![1], vec![self.head_bias]);
        read_module(critic, "c", &weights).expect("the critic's own shapes")
    }

    /// Scores `x` (channels-last, `[batch · positions, channels]`), keeping what the backward
    /// needs.
    fn forward(&self, x: &[f32], batch: usize, keep_cols: bool) -> Pass {
        let mut pass = Pass {
            cols: Vec::new(),
            activations: Vec::new(),
            scores: Vec::new(),
        };
        for (l, g) in self.layers.iter().enumerate() {
            let input = if l == 0 { x } else { &pass.activations[l - 1] };
            let cols = g.im2col(input, batch); // [batch · out positions, patch]
            let (rows, patch, o) = (batch * g.out_positions(), g.patch(), g.outputs);
            let mut z = times_transposed(&cols, &self.weights[l], rows, patch, o); // [rows, o]
            let slope = self.slope;
            z.par_chunks_mut(o).for_each(|row| {
                for (v, b) in row.iter_mut().zip(&self.biases[l]) {
                    let s = *v + b;
                    *v = if s > 0.0 { s } else { s * slope };
                }
            });
            if keep_cols {
                pass.cols.push(cols);
            }
            pass.activations.push(z);
        }
        let last = pass.activations.last().expect("critic has convolutions");
        let per_sample = self.head.len();
        pass.scores = last
            .chunks_exact(per_sample)
            .map(|a| a.iter().zip(&self.head).map(|(a, w)| a * w).sum::<f32>() + self.head_bias)
            .collect();
        pass
    }

    /// The loss's gradient through the scores of `pass` with `d loss / d score_b = ds[b]`, added
    /// to `grads`. The pass is of real then fake samples, as many of each.
    fn backward_scores(&self, pass: &Pass, ds: &[f32], grads: &mut Gradients) {
        let batch = ds.len();
        let last = pass.activations.last().expect("critic has convolutions");
        let per_sample = self.head.len();
        // d loss / d (last activation) = ds[b] · head, per sample.
        let mut d: Vec<f32> = ds
            .iter()
            .flat_map(|&s| self.head.iter().map(move |w| s * w))
            .collect();
        for (b, a) in last.chunks_exact(per_sample).enumerate() {
            for (h, a) in grads.head.iter_mut().zip(a) {
                *h += ds[b] * a;
            }
        }
        // The real and fake halves' sums cancel exactly, as the framework's do: an Adam step
        // would make a rounding residue a step of about lr.
        let (first, second) = ds.split_at(batch / 2);
        grads.head_bias += first.iter().sum::<f32>() + second.iter().sum::<f32>();
        for (l, g) in self.layers.iter().enumerate().rev() {
            let (rows, o, patch) = (batch * g.out_positions(), g.outputs, g.patch());
            for (d, a) in d.iter_mut().zip(&pass.activations[l]) {
                *d *= slope_at(*a, self.slope); // through the LeakyReLU: d = dz
            }
            add_weight_gradient(&mut grads.weights[l], &d, &pass.cols[l], rows, patch);
            // Each half (real, fake) summed on its own, then added, as the framework's two
            // graphs do: the halves nearly cancel, and Adam's first steps are about
            // g / (|g| + eps), so the residue's rounding matters.
            let (first, second) = d.split_at(rows / 2 * o);
            let sum = |half: &[f32]| {
                let mut total = vec![0f32; o];
                for row in half.chunks_exact(o) {
                    total.iter_mut().zip(row).for_each(|(t, v)| *t += v);
                }
                total
            };
            let (a, b) = (sum(first), sum(second));
            for ((g, a), b) in grads.biases[l].iter_mut().zip(a).zip(b) {
                *g += a + b;
            }
            if l > 0 {
                d = g.col2im(&times(&d, &self.weights[l], rows, o, patch), batch);
            }
        }
    }

    /// dD/dx for each sample of a forward pass whose activations are `masks` (channels-last,
    /// `[batch · positions, channels]`), and each layer's `t_l = M_l ⊙ g_l`.
    fn input_gradient(&self, masks: &[Vec<f32>], batch: usize) -> (Vec<f32>, Vec<Vec<f32>>) {
        let slope = self.slope;
        // Down: t_l = M_l ⊙ g_l, from g_top = the head's weight; g_{l-1} = col2im(t_l · W_l).
        let mut ts = vec![Vec::new(); masks.len()];
        let mut g: Vec<f32> = (0..batch).flat_map(|_| self.head.iter().copied()).collect();
        for (l, geometry) in self.layers.iter().enumerate().rev() {
            for (g, a) in g.iter_mut().zip(&masks[l]) {
                *g *= slope_at(*a, slope);
            }
            let (rows, o, patch) = (
                batch * geometry.out_positions(),
                geometry.outputs,
                geometry.patch(),
            );
            let cols = times(&g, &self.weights[l], rows, o, patch);
            ts[l] = std::mem::replace(&mut g, geometry.col2im(&cols, batch));
        }
        (g, ts)
    }

    /// Scores of `x` (`[batch, channels, depth, rows, cols]`, flattened) and their gradient with
    /// respect to `x`, channels-last (`[batch · positions, channels]`): what the generator's
    /// step needs.
    pub fn scores_and_input_gradient(&self, x: &[f32], shape: [usize; 5]) -> (Vec<f32>, Vec<f32>) {
        let batch = shape[0];
        let x = channels_last(x, shape);
        let pass = self.forward(&x, batch, false);
        let (g, _) = self.input_gradient(&pass.activations, batch);
        (pass.scores, g)
    }

    /// The penalty `lambda · mean_b (||dD/dx (x_hat_b)|| - 1)^2` and its gradient, added to
    /// `grads`.
    fn penalty(&self, x_hat: &[f32], batch: usize, lambda: f32, grads: &mut Gradients) -> f32 {
        let masks = self.forward(x_hat, batch, false).activations;
        let (g, ts) = self.input_gradient(&masks, batch);
        // g is dD/dx at x_hat, [batch · positions, channels].
        let per_sample = g.len() / batch;
        let mut penalty = 0.0;
        let mut delta = g;
        for sample in delta.chunks_exact_mut(per_sample) {
            let norm = (sample.iter().map(|v| v * v).sum::<f32>() + 1e-12).sqrt();
            penalty += (norm - 1.0).powi(2);
            let scale = lambda / batch as f32 * 2.0 * (norm - 1.0) / norm;
            sample.iter_mut().for_each(|v| *v *= scale);
        }
        // Up: dP/dt_l = im2col(δ_{l-1}) · W_l; dP/dW_l += im2col(δ_{l-1})^T · t_l;
        // δ_l = M_l ⊙ dP/dt_l.
        for (l, geometry) in self.layers.iter().enumerate() {
            let (rows, o, patch) = (
                batch * geometry.out_positions(),
                geometry.outputs,
                geometry.patch(),
            );
            let cols = geometry.im2col(&delta, batch);
            add_weight_gradient(&mut grads.weights[l], &ts[l], &cols, rows, patch);
            delta = times_transposed(&cols, &self.weights[l], rows, patch, o);
            for (d, a) in delta.iter_mut().zip(&masks[l]) {
                *d *= slope_at(*a, self.slope);
            }
        }
        // t_top = M_top ⊙ head: the head's share is the sum of δ_top over the batch.
        debug_assert_eq!(delta.len(), batch * self.head.len());
        for sample in delta.chunks_exact(self.head.len()) {
            for (h, v) in grads.head.iter_mut().zip(sample) {
                *h += v;
            }
        }
        lambda * penalty / batch as f32
    }

    /// The critic's WGAN-GP loss at `real` and `fake` (`[batch, channels, depth, rows, cols]`,
    /// flattened) with the penalty at `alpha · real + (1 - alpha) · fake` weighted by `lambda`
    /// (none: no penalty), and its gradient.
    pub fn step(
        &self,
        real: &[f32],
        fake: &[f32],
        alpha: &[f32],
        shape: [usize; 5],
        lambda: Option<f32>,
    ) -> CriticStep {
        let [batch, channels, ..] = shape;
        let positions = shape[2..].iter().product::<usize>();
        let mut both = channels_last(real, shape);
        both.extend(channels_last(fake, shape));
        let x_hat: Vec<f32> = (0..batch)
            .flat_map(|b| {
                let n = channels * positions;
                let (r, f) = (&both[b * n..][..n], &both[(batch + b) * n..][..n]);
                r.iter()
                    .zip(f)
                    .map(move |(r, f)| alpha[b] * r + (1.0 - alpha[b]) * f)
            })
            .collect();
        let inv = 1.0 / batch as f32;
        let ds: Vec<f32> = (0..2 * batch)
            .map(|i| if i < batch { -inv } else { inv })
            .collect();
        // The scores' and the penalty's shares are independent: each fills the other's idle
        // moments; they are summed in that order, whatever the threads.
        let ((pass, mut grads), penalty) = rayon::join(
            || {
                let mut grads = Gradients::new(self);
                let pass = self.forward(&both, 2 * batch, true);
                self.backward_scores(&pass, &ds, &mut grads);
                (pass, grads)
            },
            || {
                lambda.map(|lambda| {
                    let mut grads = Gradients::new(self);
                    let penalty = self.penalty(&x_hat, batch, lambda, &mut grads);
                    (penalty, grads)
                })
            },
        );
        let penalty = penalty.map_or(0.0, |(penalty, share)| {
            grads.add(&share);
            penalty
        });
        let mean = |s: &[f32]| s.iter().sum::<f32>() * inv;
        CriticStep {
            wasserstein: mean(&pass.scores[..batch]) - mean(&pass.scores[batch..]),
            penalty,
            ..grads.into_framework(self)
        }
    }
}

/// Gradients in the fused layouts while they are summed.
struct Gradients {
    weights: Vec<Vec<f32>>,
    biases: Vec<Vec<f32>>,
    head: Vec<f32>,
    head_bias: f32,
}

impl Gradients {
    /// No weight's gradient yet (empty, see [`add_weight_gradient`]), zero for the rest.
    fn new(critic: &FusedCritic) -> Self {
        Self {
            weights: vec![Vec::new(); critic.weights.len()],
            biases: critic.biases.iter().map(|b| vec![0.0; b.len()]).collect(),
            head: vec![0.0; critic.head.len()],
            head_bias: 0.0,
        }
    }

    /// Adds `other`'s gradients, value by value.
    fn add(&mut self, other: &Gradients) {
        let add = |a: &mut Vec<f32>, b: &[f32]| match a.is_empty() {
            true => a.extend_from_slice(b),
            false => a
                .par_chunks_mut(1 << 14)
                .zip(b.par_chunks(1 << 14))
                .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b)),
        };
        let pairs = self.weights.iter_mut().zip(&other.weights);
        let pairs = pairs.chain(self.biases.iter_mut().zip(&other.biases));
        for (a, b) in pairs {
            add(a, b);
        }
        add(&mut self.head, &other.head);
        self.head_bias += other.head_bias;
    }

    /// The gradients in the framework critic's layouts (see [`CriticStep`]).
    fn into_framework(self, critic: &FusedCritic) -> CriticStep {
        let head = critic.reorder_head(&self.head, true);
        let convs = self.weights.into_iter().zip(self.biases).collect();
        CriticStep {
            wasserstein: 0.0,
            penalty: 0.0,
            convs,
            head: (head, self.head_bias),
        }
    }
}
