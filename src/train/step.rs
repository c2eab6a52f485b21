//! One training iteration (WGAN-GP, paper §3.3): `critic_steps` critic updates on real and
//! generated crops with the exact gradient penalty, then `generator_steps` generator updates.
//! Every random draw is a hash of `(seed, purpose, counters)`, so a resumed run continues bit
//! for bit.

use std::time::Instant;

use burn::optim::GradientsParams;
use burn::prelude::*;

use super::adam::Adam;
use super::coarse::Scale;
use super::draws::uniform;
use super::fakes::FakeSample;
use super::{Trainer, diversity};
use crate::critic::fused::FusedCritic;
use crate::generator::backward::{self, GeneratorGradients};
use crate::generator::fused::FusedGenerator;

/// Which critic step of which iteration, and its penalty's weight (`None`: no penalty).
#[derive(Debug, Clone, Copy)]
struct CriticStepInput {
    it: u64,
    step: u64,
    lambda: Option<f64>,
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
    /// The structure distance of the scored samples at a checkpoint (lower is better; see
    /// `Trainer::score`).
    pub structure: Option<f64>,
    /// How strongly the scored samples repeat at a checkpoint (0 to 1; see `Trainer::score`).
    pub repeat: Option<f64>,
    /// A map set's structure distance per map at a checkpoint, in the set's order (empty
    /// otherwise; `structure` is their mean).
    pub map_structure: Vec<f64>,
    /// Where the iteration's time went.
    pub times: StepTimes,
}

impl IterationStats {
    /// The losses and K for a progress line: `W 0.1234  gp 0.0123  G -0.5678  K 1.0000 1.0000`,
    /// and at a checkpoint its scores (`  SIFID 12.34  structure 0.123  repeat 0.45`).
    pub fn summary(&self) -> String {
        let k: Vec<String> = self.k.iter().map(|k| format!("{k:.4}")).collect();
        let scores: String = [
            self.sifid.map(|v| format!("  SIFID {v:.2}")),
            self.structure.map(|v| format!("  structure {v:.3}")),
            self.repeat.map(|v| format!("  repeat {v:.2}")),
        ]
        .into_iter()
        .flatten()
        .collect();
        format!(
            "W {:.4}  gp {:.4}  G {:.4}  K {}{scores}",
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
    /// Through the framework: the critic on real and fake crops, and the exact gradient
    /// penalty. Fused (CPU): the critic's weights and the crops read into host buffers.
    pub critic_forward: f64,
    /// Through the framework: autodiff. Fused: the loss, penalty and every gradient.
    pub critic_backward: f64,
    pub critic_update: f64,
    /// Generator forward (with gradient, through the framework), and the critic on its output
    /// (fused: with its input gradient).
    pub generator_forward: f64,
    pub generator_backward: f64,
    pub generator_update: f64,
}

impl StepTimes {
    /// Adds `other`'s seconds to these.
    fn add(&mut self, other: &StepTimes) {
        self.critic_data += other.critic_data;
        self.critic_forward += other.critic_forward;
        self.critic_backward += other.critic_backward;
        self.critic_update += other.critic_update;
        self.generator_forward += other.generator_forward;
        self.generator_backward += other.generator_backward;
        self.generator_update += other.generator_update;
    }
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
        let lr = super::adam::scheduled_lr(cfg.lr, cfg.lr_decay, it, cfg.iterations);
        self.adam_critic.lr = lr;
        if let Some(coarse) = &mut self.coarse {
            coarse.adam.lr = lr;
        }
        self.adam_generator.lr = lr;
        self.adam_generator.k_lr = cfg.k_lr;
        // The generator is fixed during the critic's steps: on the CPU its fakes come from the
        // fused evaluator, several times faster than the framework's forward pass.
        let fused = self
            .fused_steps()
            .then(|| FusedGenerator::new(self.generator.weights()));
        // On the CPU the critics' weights stay on the host through their steps (Adam updates
        // them in place), and go back into the framework's critics once, after them.
        let mut host_critics: Option<Vec<FusedCritic>> = fused.is_some().then(|| {
            let (channels, shape) = (self.critic_channels(), self.crop_shape());
            let critics = self.scales().iter().map(|&scale| self.critic_at(scale));
            critics
                .map(|critic| FusedCritic::new(critic, channels, shape))
                .collect()
        });
        for step in 0..cfg.critic_steps as u64 {
            // Lazy regularisation: the penalty on every `penalty_every`-th critic step.
            let counted = it * cfg.critic_steps as u64 + step;
            let lambda = counted
                .is_multiple_of(cfg.penalty_every as u64)
                .then_some(cfg.gp_lambda * cfg.penalty_every as f64);
            for (i, &scale) in self.scales().iter().enumerate() {
                let host = host_critics.as_mut().map(|c| &mut c[i]);
                let step = CriticStepInput { it, step, lambda };
                self.critic_step(scale, step, fused.as_ref(), host, &mut stats);
            }
        }
        if let Some(critics) = &host_critics {
            let t = Instant::now();
            for (&scale, host) in self.scales().iter().zip(critics) {
                let critic = host.write_into(self.critic_at(scale).clone());
                *self.critic_and_adam(scale).0 = critic;
            }
            stats.times.critic_update += t.elapsed().as_secs_f64();
        }
        // The critics are fixed during the generator's steps.
        let frozen = host_critics;
        for step in 0..cfg.generator_steps as u64 {
            match &frozen {
                Some(critics) => self.generator_step_fused(critics, [it, step], &mut stats),
                None => self.generator_step_framework([it, step], &mut stats),
            }
        }
        self.iteration += 1;
        if let Some(average) = &mut self.average {
            let d = super::average::decay_at(cfg.average, self.iteration);
            super::average::update(average, &self.generator.weights(), d);
        }
        stats.k = self
            .generator
            .k
            .val()
            .try_into_vec_as::<f32>()
            .expect("K readable");
        stats.iterations_per_second = 1.0 / start.elapsed().as_secs_f32();
        stats
    }

    /// The critic at `scale`.
    fn critic_at(&self, scale: Scale) -> &crate::critic::Critic {
        match (scale, &self.coarse) {
            (Scale::Coarse, Some(coarse)) => &coarse.critic,
            _ => &self.critic,
        }
    }

    /// The critic at `scale` and its optimiser.
    fn critic_and_adam(&mut self, scale: Scale) -> (&mut crate::critic::Critic, &mut Adam) {
        match (scale, &mut self.coarse) {
            (Scale::Coarse, Some(coarse)) => (&mut coarse.critic, &mut coarse.adam),
            _ => (&mut self.critic, &mut self.adam_critic),
        }
    }

    /// One update of the critic at `scale`: its real and generated crops, then the fused step
    /// (`host`, on the CPU) or the framework's. The fine critic's losses go into `stats`.
    fn critic_step(
        &mut self,
        scale: Scale,
        input: CriticStepInput,
        fused: Option<&FusedGenerator>,
        host: Option<&mut FusedCritic>,
        stats: &mut IterationStats,
    ) {
        let CriticStepInput { it, step, lambda } = input;
        let t = Instant::now();
        let batch = self.config.batch;
        let real = self.real_batch(&[it, step], scale);
        let counters = [scale.critic_fake_stream(), it, step];
        let fake = match fused {
            Some(g) => self.fake_batch_fused(g, &counters, scale),
            None => Tensor::from_inner(self.fake_batch(
                &self.generator.valid(),
                &self.device.clone().inner(),
                &counters,
                0,
                scale,
            )),
        };
        let alphas: Vec<f32> = (0..batch as u64)
            .map(|s| uniform(self.config.seed, &[scale.alpha_stream(), s, it, step]))
            .collect();
        stats.times.critic_data += t.elapsed().as_secs_f64();
        let mut losses = IterationStats::default();
        if let Some(critic) = host {
            self.critic_step_fused(scale, critic, real, fake, &alphas, lambda, &mut losses);
        } else {
            let alpha = Tensor::<1>::from_data(TensorData::new(alphas, [batch]), &self.device);
            self.critic_step_framework(scale, real, fake, alpha, lambda, &mut losses);
        }
        stats.times.add(&losses.times);
        if scale == Scale::Fine {
            stats.wasserstein = losses.wasserstein;
            if lambda.is_some() {
                stats.penalty = losses.penalty;
            }
        }
    }

    /// One generator update through the framework: fakes with gradient, the frozen critics'
    /// scores, autodiff, Adam.
    fn generator_step_framework(&mut self, [it, step]: [u64; 2], stats: &mut IterationStats) {
        let t = Instant::now();
        // The critics' share (the loss reported), then the diversity hinge's.
        let (mut loss, mut hinge) = (Tensor::<1>::zeros([1], &self.device), None);
        for &scale in self.scales() {
            let counters = [scale.generator_fake_stream(), it, step];
            let frozen = self.critic_at(scale).clone().no_grad();
            let fake = self.fake_batch(&self.generator, &self.device, &counters, 0, scale);
            loss = loss + frozen.forward(fake.clone()).mean().neg();
            if scale == Scale::Fine && self.config.diversity > 0.0 {
                hinge = Some(self.diversity_framework(fake, &counters));
            }
        }
        stats.generator_loss = loss.clone().into_scalar::<f32>();
        if let Some(hinge) = hinge {
            loss = loss + hinge;
        }
        stats.times.generator_forward += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let grads = GradientsParams::from_grads(loss.backward(), &self.generator);
        stats.times.generator_backward += t.elapsed().as_secs_f64();
        let t = Instant::now();
        self.generator = self.adam_generator.step(self.generator.clone(), grads);
        stats.times.generator_update += t.elapsed().as_secs_f64();
    }

    /// The diversity hinge (see `diversity`) through autodiff: the crops `fake` and their twins.
    fn diversity_framework(&self, fake: Tensor<5>, counters: &[u64]) -> Tensor<1> {
        let twin = self.fake_batch(&self.generator, &self.device, counters, 1, Scale::Fine);
        let [b, _, d, h, w] = fake.dims();
        let c = self.exemplar.channels;
        let diff = fake.narrow(1, 0, c) - twin.narrow(1, 0, c); // [b, c, d, h, w]
        let squared = (diff.clone() * diff).reshape([b, c * d * h * w]).sum_dim(1); // [b, 1]
        let distance = squared.add_scalar(1e-24).sqrt();
        distance
            .neg()
            .add_scalar(self.diversity_target())
            .clamp_min(0.0)
            .mean()
            .mul_scalar(self.config.diversity)
    }

    /// One generator update on the CPU: fakes from the fused evaluator, the critics' scores and
    /// input gradients from the fused critics, the generator's gradient by hand
    /// ([`crate::generator::backward`]), then Adam: the same update as
    /// [`Trainer::generator_step_framework`].
    fn generator_step_fused(
        &mut self,
        critics: &[FusedCritic],
        [it, step]: [u64; 2],
        stats: &mut IterationStats,
    ) {
        let t = Instant::now();
        let weights = self.generator.weights();
        // The passes that paint the crops are kept for the backward when they fit in memory;
        // otherwise the fused evaluator paints, and the backward runs them again.
        let keep = self.keeps_passes(&weights);
        let fused = (!keep).then(|| FusedGenerator::new(weights.clone()));
        let paint = |samples: &[FakeSample]| match &fused {
            None => self.paint_kept(&weights, samples),
            Some(fused) => {
                let (planar, shape) = self.paint_fused(fused, samples);
                (planar, shape, Vec::new())
            }
        };
        let c = self.exemplar.channels;
        let n = self.crop_points();
        // Every painted sample (the fine crops, their twins, the coarse crops, in that order),
        // the loss's gradient on each one's output `[points, c]`, and the kept passes.
        let (mut all, mut d_output, mut passes) = (Vec::new(), Vec::new(), Vec::new());
        let mut loss = 0.0;
        for (&scale, critic) in self.scales().iter().zip(critics) {
            let counters = [scale.generator_fake_stream(), it, step];
            let samples = self.fake_samples(&counters, 0, scale);
            let (fake, shape, kept) = paint(&samples);
            passes.extend(kept);
            let (scores, dx) = critic.scores_and_input_gradient(&fake, shape); // dx: [b · n, cg]
            let (b, cg) = (scores.len(), shape[1]);
            loss += -scores.iter().sum::<f32>() / b as f32;
            // d loss / d output = -dD/dx / b, without the condition's channel: [b · n, c]
            let mut d: Vec<f32> = dx
                .chunks_exact(cg)
                .flat_map(|px| px[..c].iter().map(|v| -v / b as f32))
                .collect();
            all.extend(samples);
            // The diversity hinge: the fine crops' twins, and the hinge's gradient on both.
            if scale == Scale::Fine && self.config.diversity > 0.0 {
                let twins = self.fake_samples(&counters, 1, scale);
                let (twin, _, twin_passes) = paint(&twins);
                passes.extend(twin_passes);
                let (target, weight) = (self.diversity_target(), self.config.diversity as f32);
                let h = diversity::hinge(&fake, &twin, [b, cg, n], c, target, weight);
                d.iter_mut().zip(&h.d_a).for_each(|(d, h)| *d += h);
                d.extend(h.d_b); // the twins' rows follow the crops'
                all.extend(twins);
            }
            d_output.extend(d);
        }
        stats.generator_loss = loss;
        stats.times.generator_forward += t.elapsed().as_secs_f64();

        let t = Instant::now();
        let dims = self.kind.generator_axes();
        let scale = vec![self.config.latent_scale; dims];
        let groups: Vec<backward::Group> = self
            .point_groups(all.len())
            .into_iter()
            .map(|(i, start, end)| backward::Group {
                p: &all[i].p[start * dims..end * dims],
                field: &all[i].field,
                guide: all[i].condition.get(start..end).unwrap_or(&[]),
                d_output: &d_output[(i * n + start) * c..(i * n + end) * c],
            })
            .collect();
        let grads = backward::gradients(&weights, &scale, &groups, keep.then_some(&passes[..]));
        let grads = self.generator_gradients(&grads);
        stats.times.generator_backward += t.elapsed().as_secs_f64();
        let t = Instant::now();
        self.generator = self.adam_generator.step(self.generator.clone(), grads);
        stats.times.generator_update += t.elapsed().as_secs_f64();
    }

    /// Host gradients as the optimiser takes them, by parameter of the generator.
    fn generator_gradients(&self, grads: &GeneratorGradients) -> GradientsParams {
        let device = self.device.clone().inner();
        let tensor1 =
            |v: &[f32]| Tensor::<1>::from_data(TensorData::new(v.to_vec(), [v.len()]), &device);
        let mut params = GradientsParams::new();
        params.register(self.generator.k.id, tensor1(&grads.k));
        for (layer, (w, b)) in self.generator.layers.iter().zip(&grads.layers) {
            let shape = layer.weight.val().dims();
            let w = Tensor::<2>::from_data(TensorData::new(w.clone(), shape), &device);
            params.register(layer.weight.id, w);
            if let Some(bias) = &layer.bias {
                params.register(bias.id, tensor1(b));
            }
        }
        params
    }

    /// One critic update through the framework: scores, the exact penalty, autodiff, Adam.
    fn critic_step_framework(
        &mut self,
        scale: Scale,
        real: Tensor<5>,
        fake: Tensor<5>,
        alpha: Tensor<1>,
        lambda: Option<f64>,
        stats: &mut IterationStats,
    ) {
        let t = Instant::now();
        let (critic, adam) = self.critic_and_adam(scale);
        let weights = critic.weights(); // shared by the scores and the penalty
        let d_real = critic.score(&weights, real.clone()).mean();
        let d_fake = critic.score(&weights, fake.clone()).mean();
        let mut loss = d_fake.clone() - d_real.clone();
        if let Some(lambda) = lambda {
            let penalty = critic.gradient_penalty(&weights, real, fake, alpha, lambda);
            loss = loss + penalty.clone();
            stats.penalty = penalty.into_scalar::<f32>();
        }
        stats.wasserstein = (d_real - d_fake).into_scalar::<f32>();
        stats.times.critic_forward += t.elapsed().as_secs_f64();

        let t = Instant::now();
        let grads = GradientsParams::from_grads(loss.backward(), &*critic);
        stats.times.critic_backward += t.elapsed().as_secs_f64();
        let t = Instant::now();
        *critic = adam.step(critic.clone(), grads);
        stats.times.critic_update += t.elapsed().as_secs_f64();
    }

    /// One critic update on the CPU with the fused step ([`FusedCritic`]): the same loss and
    /// gradients as [`Trainer::critic_step_framework`], then Adam on the host weights. Its time
    /// counts as the critic's backward, apart from reading the crops (forward).
    #[allow(clippy::too_many_arguments)]
    fn critic_step_fused(
        &mut self,
        scale: Scale,
        critic: &mut FusedCritic,
        real: Tensor<5>,
        fake: Tensor<5>,
        alpha: &[f32],
        lambda: Option<f64>,
        stats: &mut IterationStats,
    ) {
        let t = Instant::now();
        let shape = real.dims();
        let host = |x: Tensor<5>| x.try_into_vec_as::<f32>().expect("crops readable as f32");
        let (real, fake) = (host(real), host(fake));
        stats.times.critic_forward += t.elapsed().as_secs_f64();

        let t = Instant::now();
        let step = critic.step(&real, &fake, alpha, shape, lambda.map(|l| l as f32));
        stats.wasserstein = step.wasserstein;
        if lambda.is_some() {
            stats.penalty = step.penalty;
        }
        stats.times.critic_backward += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let adam = self.critic_and_adam(scale).1;
        adam.begin_step();
        critic.apply(&step, |path, values, grad| {
            adam.update_host(path, values, grad)
        });
        stats.times.critic_update += t.elapsed().as_secs_f64();
    }
}
