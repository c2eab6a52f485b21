//! A stage of the periodic network as burn tensors, on any device: the forward pass with its
//! spatial tangents built from ordinary tensor ops (each sine layer's derivative is `cos(·)`
//! times its weights), so first-order autodiff differentiates the Poisson loss with respect to
//! the weights exactly, with no double backward (as the critic's exact penalty does).
//!
//! `ipfn fit --device flex|wgpu|cuda` trains with it, `ipfn synth --device wgpu` renders with it,
//! and the tests check [`super::fused`] against it.

use burn::prelude::*;

use super::fused::{Batch, Stage};
use super::network::view;

/// A stage's parameters as tensors on a device.
struct Tensors {
    phase: Tensor<2>,
    angular: [Tensor<2>; 2],
    layers: Vec<(Tensor<2>, Tensor<2>)>,
}

fn row(values: Vec<f32>, device: &Device) -> Tensor<2> {
    let n = values.len();
    Tensor::<2>::from_data(TensorData::new(values, [1, n]), device)
}

impl Tensors {
    fn new(stage: &Stage, device: &Device, trainable: bool) -> Self {
        let w = view(stage.shape, stage.channels, stage.params);
        let param = |t: Tensor<2>| if trainable { t.require_grad() } else { t };
        let layers = stage
            .shape
            .layers(stage.channels)
            .into_iter()
            .zip(&w.layers)
            .map(|((i, o), (weight, bias))| {
                let weight =
                    Tensor::<2>::from_data(TensorData::new(weight.to_vec(), [i, o]), device);
                (param(weight), param(row(bias.to_vec(), device)))
            })
            .collect();
        Self {
            phase: param(row(w.phase.to_vec(), device)),
            angular: [0, 1].map(|d| row(stage.angular.iter().map(|a| a[d]).collect(), device)),
            layers,
        }
    }

    /// Values and tangents along rows and columns at `n` pixel positions.
    ///
    /// # Shapes
    /// - `rows`, `cols`: `[n, 1]`
    /// - output: `[n, C]` values, and `[n, C]` per axis
    fn forward(
        &self,
        rows: Tensor<2>,
        cols: Tensor<2>,
        omega0: f32,
    ) -> (Tensor<2>, [Tensor<2>; 2]) {
        let [om_r, om_c] = self.angular.clone();
        let theta = rows * om_r.clone() + cols * om_c.clone() + self.phase.clone(); // [n, F]
        let mut h = theta.clone().sin();
        let cos = theta.cos();
        let mut t = [cos.clone() * om_r, cos * om_c]; // [n, F] each
        let last = self.layers.len() - 1;
        for (l, (w, b)) in self.layers.iter().enumerate() {
            let z = h.matmul(w.clone()) + b.clone(); // [n, outputs]
            let a = t.clone().map(|t| t.matmul(w.clone()));
            if l == last {
                return (z, a);
            }
            let q = z * omega0;
            let slope = q.clone().cos() * omega0;
            h = q.sin();
            t = a.map(|a| slope.clone() * a);
        }
        unreachable!("a stage has a head layer")
    }
}

fn column(values: impl Iterator<Item = f32>, device: &Device) -> Tensor<2> {
    let v: Vec<f32> = values.collect();
    let n = v.len();
    Tensor::<2>::from_data(TensorData::new(v, [n, 1]), device)
}

fn read(t: Tensor<2>) -> Vec<f32> {
    t.try_into_vec_as::<f32>()
        .expect("periodic network tensors are readable as f32")
}

/// The summed loss of `batch` (as [`Stage::loss_and_gradient`]) and its gradient with respect to
/// the stage's parameters, by autodiff on `device` (an autodiff device is made from it).
pub fn loss_and_gradient(stage: &Stage, batch: &Batch, device: &Device) -> (f64, Vec<f32>) {
    let device = if device.is_autodiff() {
        device.clone()
    } else {
        device.clone().autodiff()
    };
    let c = stage.channels;
    let n = batch.value_weight.len();
    let p = batch.positions;
    let rows = column(p.iter().step_by(2).copied(), &device);
    let cols = column(p.iter().skip(1).step_by(2).copied(), &device);
    let tensors = Tensors::new(stage, &device, true);
    let (f, t) = tensors.forward(rows, cols, stage.omega0);
    let target = Tensor::<2>::from_data(TensorData::new(batch.values.to_vec(), [n, c]), &device);
    let g = batch.gradients;
    let grad_target = |d: usize| {
        let v: Vec<f32> = (0..n)
            .flat_map(|i| g[(i * 2 + d) * c..(i * 2 + d + 1) * c].iter().copied())
            .collect();
        Tensor::<2>::from_data(TensorData::new(v, [n, c]), &device)
    };
    let wv = column(batch.value_weight.iter().copied(), &device);
    let wg = column(batch.gradient_weight.iter().copied(), &device);
    let [t_r, t_c] = t;
    let value_term = (f - target).powf_scalar(2.0) * wv;
    let gradient_term =
        ((t_r - grad_target(0)).powf_scalar(2.0) + (t_c - grad_target(1)).powf_scalar(2.0)) * wg;
    let loss = (value_term + gradient_term).sum() / c as f32;
    let value = loss
        .clone()
        .try_into_vec_as::<f32>()
        .expect("the loss is readable")[0] as f64;
    let grads = loss.backward();
    let grad_of = |t: &Tensor<2>| read(t.grad(&grads).expect("every parameter has a gradient"));
    let mut out = grad_of(&tensors.phase);
    for (w, b) in &tensors.layers {
        out.extend(grad_of(w));
        out.extend(grad_of(b));
    }
    (value, out)
}

/// Values `[n, C]` and tangents `[n, 2, C]` at `n` pixel positions `[n, 2]` on `device`.
pub fn eval(stage: &Stage, positions: &[f32], device: &Device) -> (Vec<f32>, Vec<f32>) {
    let rows = column(positions.iter().step_by(2).copied(), device);
    let cols = column(positions.iter().skip(1).step_by(2).copied(), device);
    let (f, [t_r, t_c]) = Tensors::new(stage, device, false).forward(rows, cols, stage.omega0);
    let c = stage.channels;
    let (t_r, t_c) = (read(t_r), read(t_c));
    let tangents = t_r
        .chunks_exact(c)
        .zip(t_c.chunks_exact(c))
        .flat_map(|(r, cc)| r.iter().chain(cc).copied())
        .collect();
    (read(f), tangents)
}

/// Values `[n, C]` only (for rendering on a GPU).
pub fn eval_values(stage: &Stage, positions: &[f32], device: &Device) -> Vec<f32> {
    let rows = column(positions.iter().step_by(2).copied(), device);
    let cols = column(positions.iter().skip(1).step_by(2).copied(), device);
    let tensors = Tensors::new(stage, device, false);
    let [om_r, om_c] = tensors.angular.clone();
    let mut h = (rows * om_r + cols * om_c + tensors.phase.clone()).sin();
    let last = tensors.layers.len() - 1;
    for (l, (w, b)) in tensors.layers.iter().enumerate() {
        let z = h.matmul(w.clone()) + b.clone();
        h = if l == last {
            z
        } else {
            (z * stage.omega0).sin()
        };
    }
    read(h)
}
