//! Adam (Kingma & Ba), as PyTorch's `torch.optim.Adam` computes it, with its moments held by
//! parameter path so they can be saved in a checkpoint and restored bit for bit.

use std::collections::BTreeMap;

use burn::module::{Module, ParamId};
use burn::optim::GradientsParams;
use burn::prelude::*;
use rayon::prelude::*;

use crate::checkpoint::{Checkpoint, MapByPath, map_by_path};

/// Adam's hyper-parameters and state for one module.
#[derive(Debug, Clone)]
pub struct Adam {
    pub lr: f64,
    /// Parameters named `k` (the generator's K) step at `lr * k_lr`.
    pub k_lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
    /// Steps taken so far (for bias correction).
    pub steps: u64,
    /// First and second moments by parameter path, flattened.
    moments: BTreeMap<String, Moments>,
}

/// One parameter's moments: on the device that trains it, or on the host for the CPU, where
/// parameters are updated in one pass over host copies ([`Adam::update_host`]).
#[derive(Debug, Clone)]
enum Moments {
    Device(Box<(Tensor<1>, Tensor<1>)>),
    Host(Vec<f32>, Vec<f32>),
}

impl Moments {
    fn into_host(self) -> (Vec<f32>, Vec<f32>) {
        match self {
            Moments::Host(m, v) => (m, v),
            Moments::Device(mv) => (host(mv.0), host(mv.1)),
        }
    }
}

fn host(t: Tensor<1>) -> Vec<f32> {
    t.try_into_vec_as::<f32>().expect("readable as f32")
}

/// The learning rate of step `iteration` (from 0) of a run of `total`: `lr`, then falling
/// linearly over the last `decay` fraction of the run, to `lr / (decay · total)` at its last
/// step.
pub fn scheduled_lr(lr: f64, decay: f64, iteration: u64, total: u64) -> f64 {
    let (t, total) = (iteration as f64, total as f64);
    let start = total * (1.0 - decay);
    if decay <= 0.0 || t < start {
        return lr;
    }
    lr * ((total - t) / (total - start)).clamp(0.0, 1.0)
}

impl Adam {
    pub fn new(lr: f64, beta1: f64, beta2: f64) -> Self {
        Self {
            lr,
            k_lr: 1.0,
            beta1,
            beta2,
            eps: 1e-8,
            steps: 0,
            moments: BTreeMap::new(),
        }
    }

    /// One update of every parameter of `module` that has a gradient in `grads`.
    pub fn step<M: Module>(&mut self, module: M, grads: GradientsParams) -> M {
        self.begin_step();
        map_by_path(module, &mut AdamMapper { adam: self, grads })
    }

    /// Counts one step: the step's parameters are then updated by [`Adam::update_host`].
    pub fn begin_step(&mut self) {
        self.steps += 1;
    }

    /// The learning rate of the parameter at `path`.
    fn rate(&self, path: &str) -> f64 {
        if path == "k" || path.ends_with(".k") {
            self.lr * self.k_lr
        } else {
            self.lr
        }
    }

    /// Updates the parameter at `path` (host values, flattened) by its gradient, in one pass,
    /// for the step counted by the last [`Adam::begin_step`]. The same formula as the device
    /// path (rounding may differ in the last bit).
    pub fn update_host(&mut self, path: &str, param: &mut [f32], grad: &[f32]) {
        let n = grad.len();
        debug_assert_eq!(param.len(), n);
        let t = self.steps as i32;
        let (bias1, bias2) = (1.0 - self.beta1.powi(t), 1.0 - self.beta2.powi(t));
        let (b1, b2, eps) = (self.beta1 as f32, self.beta2 as f32, self.eps as f32);
        let (root2, step) = (bias2.sqrt() as f32, (self.rate(path) / bias1) as f32);
        let (mut m, mut v) = match self.moments.remove(path) {
            Some(moments) => moments.into_host(),
            None => (vec![0.0; n], vec![0.0; n]),
        };
        // Each value on its own: the pool's split cannot change a result.
        const CHUNK: usize = 1 << 14;
        param
            .par_chunks_mut(CHUNK)
            .zip(m.par_chunks_mut(CHUNK).zip(v.par_chunks_mut(CHUNK)))
            .zip(grad.par_chunks(CHUNK))
            .for_each(|((param, (m, v)), grad)| {
                for (((p, m), v), g) in param.iter_mut().zip(m).zip(v).zip(grad) {
                    *m = *m * b1 + g * (1.0 - b1);
                    *v = *v * b2 + g * g * (1.0 - b2);
                    *p -= *m / (v.sqrt() / root2 + eps) * step;
                }
            });
        self.moments.insert(path.to_string(), Moments::Host(m, v));
    }

    /// Stores the step count and moments under `{prefix}.m.{path}` / `{prefix}.v.{path}`.
    pub fn write_to(&self, prefix: &str, checkpoint: &mut Checkpoint) {
        checkpoint
            .metadata
            .insert(format!("{prefix}.steps"), self.steps.to_string());
        for (path, moments) in &self.moments {
            let (m, v) = moments.clone().into_host();
            for (kind, values) in [("m", m), ("v", v)] {
                checkpoint.insert(
                    format!("{prefix}.{kind}.{path}"),
                    vec![values.len()],
                    values,
                );
            }
        }
    }

    /// Restores what [`Adam::write_to`] stored, for parameters on `device`.
    pub fn read_from(
        &mut self,
        prefix: &str,
        checkpoint: &Checkpoint,
        device: &Device,
    ) -> crate::Result<()> {
        self.steps = checkpoint
            .meta(&format!("{prefix}.steps"))?
            .parse()
            .map_err(|_| crate::file_error!(&checkpoint.source, "unreadable {prefix}.steps"))?;
        self.moments.clear();
        let m_prefix = format!("{prefix}.m.");
        for (name, m) in checkpoint.tensors.range(m_prefix.clone()..) {
            let Some(path) = name.strip_prefix(&m_prefix) else {
                break;
            };
            let v = checkpoint.tensor(&format!("{prefix}.v.{path}"), &m.shape)?;
            let moments = if *device == Device::flex() {
                Moments::Host(m.values.clone(), v.to_vec())
            } else {
                let tensor = |values: &[f32]| {
                    Tensor::<1>::from_data(TensorData::new(values.to_vec(), [values.len()]), device)
                };
                Moments::Device(Box::new((tensor(&m.values), tensor(v))))
            };
            self.moments.insert(path.to_string(), moments);
        }
        Ok(())
    }
}

struct AdamMapper<'a> {
    adam: &'a mut Adam,
    grads: GradientsParams,
}

impl MapByPath for AdamMapper<'_> {
    fn map<const D: usize>(&mut self, path: &str, id: ParamId, tensor: Tensor<D>) -> Tensor<D> {
        let Some(grad) = self.grads.remove::<D>(id) else {
            return tensor;
        };
        let a = &mut *self.adam;
        let shape = grad.dims();
        let n: usize = shape.iter().product();
        let grad = grad.reshape([n]);
        let device = tensor.device();
        if grad.device() == Device::flex() {
            let mut values = tensor
                .inner()
                .try_into_vec_as::<f32>()
                .expect("parameters readable as f32");
            a.update_host(path, &mut values, &host(grad));
            Tensor::from_data(TensorData::new(values, shape), &device)
        } else {
            let t = a.steps as i32;
            let (bias1, bias2) = (1.0 - a.beta1.powi(t), 1.0 - a.beta2.powi(t));
            let (m, v) = match a.moments.remove(path) {
                Some(Moments::Device(mv)) => *mv,
                _ => (grad.zeros_like(), grad.zeros_like()),
            };
            let m = m * a.beta1 + grad.clone() * (1.0 - a.beta1);
            let v = v * a.beta2 + grad.powi_scalar(2) * (1.0 - a.beta2);
            let denom = v.clone().sqrt() / bias2.sqrt() + a.eps;
            let update = (m.clone() / denom * (a.rate(path) / bias1)).reshape(shape);
            a.moments
                .insert(path.to_string(), Moments::Device(Box::new((m, v))));
            Tensor::from_inner(tensor.inner() - update)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::scheduled_lr;

    #[test]
    fn the_rate_holds_then_falls_linearly_to_the_last_step() {
        // Off: constant.
        assert_eq!(scheduled_lr(1e-3, 0.0, 99, 100), 1e-3);
        // The second half of 100 iterations: constant to 49, then 50/50, 49/50, ..., 1/50.
        assert_eq!(scheduled_lr(1e-3, 0.5, 49, 100), 1e-3);
        assert_eq!(scheduled_lr(1e-3, 0.5, 50, 100), 1e-3);
        assert!((scheduled_lr(1e-3, 0.5, 75, 100) - 0.5e-3).abs() < 1e-15);
        assert!((scheduled_lr(1e-3, 0.5, 99, 100) - 1e-3 / 50.0).abs() < 1e-15);
        // The whole run decays from the first step.
        assert!((scheduled_lr(1.0, 1.0, 1, 4) - 0.75).abs() < 1e-15);
    }
}
