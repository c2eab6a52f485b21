//! One training iteration (WGAN-GP, paper §3.3): `critic_steps` critic updates on real and
//! generated crops with the exact gradient penalty, then `generator_steps` generator updates.
//! Every random draw is a hash of `(seed, purpose, counters)`, so a resumed run continues bit
//! for bit.

use std::time::Instant;

use burn::module::{Module, ModuleMapper, Param};
use burn::optim::GradientsParams;
use burn::prelude::*;

use super::Trainer;
use crate::generator::fused::FusedGenerator;
use crate::latent::{derive_seed, mix64};

/// Purposes of random draws, so no two share a stream.
pub(crate) mod stream {
    pub const INIT_GENERATOR: u64 = 1;
    pub const INIT_CRITIC: u64 = 2;
    pub const REAL_CROP: u64 = 3;
    pub const SHIFT: u64 = 4;
    pub const LATENT: u64 = 5;
    pub const ALPHA: u64 = 6;
    pub const CRITIC_FAKE: u64 = 7;
    pub const GENERATOR_FAKE: u64 = 8;
    pub const PREVIEW: u64 = 9;
    pub const GUIDE: u64 = 10;
    pub const SLICE_AXIS: u64 = 11;
}

/// Uniform in [0, 1) from a seed and counters.
pub(crate) fn uniform(seed: u64, counters: &[u64]) -> f32 {
    (derive_seed(seed, counters) >> 40) as f32 / 16_777_216.0
}

/// Re-initialises every float parameter except the generator's K with PyTorch's default
/// uniform(-1/sqrt(fan_in), 1/sqrt(fan_in)), from hashed draws.
pub(crate) fn initialise<M: Module>(module: M, seed: u64, stream: u64) -> M {
    struct Init {
        seed: u64,
        stream: u64,
        path: Vec<String>,
        fan_in: usize,
    }
    impl ModuleMapper for Init {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.path.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.path.pop();
        }
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let name = self.path.last().cloned().unwrap_or_default();
            if name == "k" {
                return param;
            }
            let (id, tensor, mapper) = param.consume();
            let shape = tensor.dims();
            if name == "weight" {
                // Linear weights are [in, out]; convolution weights [out, in, kh, kw].
                self.fan_in = if D == 2 {
                    shape[0]
                } else {
                    shape[1..].iter().product()
                };
            }
            let bound = 1.0 / (self.fan_in.max(1) as f32).sqrt();
            let key = self.path.iter().fold(self.seed, |h, p| {
                mix64(h ^ p.bytes().fold(0u64, |a, b| mix64(a ^ b as u64)))
            });
            let n: usize = shape.iter().product();
            let values: Vec<f32> = (0..n as u64)
                .map(|i| (uniform(key, &[self.stream, i]) * 2.0 - 1.0) * bound)
                .collect();
            let fresh = Tensor::<D>::from_data(TensorData::new(values, shape), &tensor.device());
            let fresh = if tensor.is_require_grad() {
                fresh.require_grad()
            } else {
                fresh
            };
            Param::from_mapped_value(id, fresh, mapper)
        }
    }
    module.map(&mut Init {
        seed,
        stream,
        path: Vec::new(),
        fan_in: 1,
    })
}

/// Losses of one iteration (from its last critic and generator steps).
#[derive(Debug, Clone, Default)]
pub struct IterationStats {
    pub iteration: u64,
    /// Critic's Wasserstein estimate: mean D(real) - mean D(fake).
    pub wasserstein: f32,
    pub penalty: f32,
    pub generator_loss: f32,
    /// The learned period K per axis, in axis order (rows, columns; depth first for volumes).
    pub k: Vec<f32>,
    pub iterations_per_second: f32,
    /// The generator's score at a checkpoint (SIFID against the exemplar; lower is better).
    pub sifid: Option<f64>,
    /// Where the iteration's time went.
    pub times: StepTimes,
}

impl IterationStats {
    /// The losses and K for a progress line: `W 0.1234  gp 0.0123  G -0.5678  K 1.0000 1.0000`.
    pub fn summary(&self) -> String {
        let k: Vec<String> = self.k.iter().map(|k| format!("{k:.4}")).collect();
        let sifid = self
            .sifid
            .map(|v| format!("  SIFID {v:.2}"))
            .unwrap_or_default();
        format!(
            "W {:.4}  gp {:.4}  G {:.4}  K {}{sifid}",
            self.wasserstein,
            self.penalty,
            self.generator_loss,
            k.join(" ")
        )
    }
}

/// Seconds spent in each part of an iteration (summed over its steps).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimes {
    /// Real crops and the critic's fake crops (generator forward without gradient).
    pub critic_data: f64,
    /// Critic on real and fake crops, and the exact gradient penalty.
    pub critic_forward: f64,
    pub critic_backward: f64,
    pub critic_update: f64,
    /// Generator forward with gradient, and the critic on its output.
    pub generator_forward: f64,
    pub generator_backward: f64,
    pub generator_update: f64,
}

impl Trainer {
    /// Runs one iteration: critic steps, then generator steps.
    pub fn step(&mut self) -> IterationStats {
        let start = Instant::now();
        let it = self.iteration;
        let cfg = self.config.clone();
        let mut stats = IterationStats {
            iteration: it + 1,
            ..Default::default()
        };
        let times = &mut stats.times;
        // The generator is fixed during the critic's steps: on the CPU its fakes come from the
        // fused evaluator, several times faster than the framework's forward pass.
        let fused = self
            .device
            .clone()
            .inner()
            .eq(&Device::flex())
            .then(|| FusedGenerator::new(self.generator.weights()));
        for step in 0..cfg.critic_steps as u64 {
            let t = Instant::now();
            let real = self.real_batch(&[it, step]);
            let counters = [stream::CRITIC_FAKE, it, step];
            let fake = match &fused {
                Some(g) => self.fake_batch_fused(g, &counters),
                None => Tensor::from_inner(self.fake_batch(
                    &self.generator.valid(),
                    &self.device.clone().inner(),
                    &counters,
                )),
            };
            let alphas: Vec<f32> = (0..cfg.batch as u64)
                .map(|s| uniform(cfg.seed, &[stream::ALPHA, s, it, step]))
                .collect();
            let alpha = Tensor::<1>::from_data(TensorData::new(alphas, [cfg.batch]), &self.device);
            times.critic_data += t.elapsed().as_secs_f64();

            let t = Instant::now();
            let weights = self.critic.weights(); // shared by the scores and the penalty
            let d_real = self.critic.score(&weights, real.clone()).mean();
            let d_fake = self.critic.score(&weights, fake.clone()).mean();
            let penalty = self
                .critic
                .gradient_penalty(&weights, real, fake, alpha, cfg.gp_lambda);
            let loss = d_fake.clone() - d_real.clone() + penalty.clone();
            stats.wasserstein = (d_real - d_fake).into_scalar::<f32>();
            stats.penalty = penalty.into_scalar::<f32>();
            times.critic_forward += t.elapsed().as_secs_f64();

            let t = Instant::now();
            let grads = GradientsParams::from_grads(loss.backward(), &self.critic);
            times.critic_backward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            self.critic = self.adam_critic.step(self.critic.clone(), grads);
            times.critic_update += t.elapsed().as_secs_f64();
        }
        for step in 0..cfg.generator_steps as u64 {
            let t = Instant::now();
            let frozen = self.critic.clone().no_grad();
            let fake = self.fake_batch(
                &self.generator,
                &self.device,
                &[stream::GENERATOR_FAKE, it, step],
            );
            let loss = frozen.forward(fake).mean().neg();
            stats.generator_loss = loss.clone().into_scalar::<f32>();
            times.generator_forward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            let grads = GradientsParams::from_grads(loss.backward(), &self.generator);
            times.generator_backward += t.elapsed().as_secs_f64();
            let t = Instant::now();
            self.generator = self.adam_generator.step(self.generator.clone(), grads);
            times.generator_update += t.elapsed().as_secs_f64();
        }
        self.iteration += 1;
        stats.k = self
            .generator
            .k
            .val()
            .try_into_vec_as::<f32>()
            .expect("K readable");
        stats.iterations_per_second = 1.0 / start.elapsed().as_secs_f32();
        stats
    }
}
