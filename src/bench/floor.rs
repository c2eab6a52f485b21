//! The floor of one training iteration on the CPU: the matrix products of both networks (the
//! generator's forward and backward, the critic's forward, exact penalty and backward), as
//! bare `gemm` calls of the same shapes on all cores, and nothing else (no im2col, activations,
//! encoding or Adam). With the diversity hinge, each generator step's twins add a generator
//! forward and backward. The shapes are the fused step's ([`crate::critic::fused`],
//! [`crate::generator::backward`]), less the generator's forward that its backward runs again
//! when the step cannot keep its passes (`paper.toml`'s batch, volumes).

use crate::generator::fused::matmul_parallel;
use crate::train::{RunKind, TrainConfig};

/// `(m, n, k)` of every product of one iteration of `config` on an exemplar of `channels`.
pub fn iteration_products(
    config: &TrainConfig,
    kind: &RunKind,
    channels: usize,
) -> Vec<(usize, usize, usize)> {
    let critic = config.critic_config(kind, channels);
    let generator = config.generator_config(kind, channels);
    let b = config.batch;
    let points = b * config.crop.pow(kind.crop_axes() as u32);
    // Per convolution: output positions per sample, im2col columns, output channels.
    let taps = 4usize.pow(critic.axes as u32);
    let (mut side, mut inputs, mut layers) = (config.crop, critic.channels, Vec::new());
    for &w in &critic.widths {
        side /= 2;
        layers.push((side.pow(critic.axes as u32), inputs * taps, w));
        inputs = w;
    }
    let forward = |n: usize| -> Vec<_> { layers.iter().map(|&(p, c, o)| (n * p, o, c)).collect() };
    let transposed =
        |n: usize| -> Vec<_> { layers.iter().map(|&(p, c, o)| (n * p, c, o)).collect() };
    let weights = |n: usize| -> Vec<_> { layers.iter().map(|&(p, c, o)| (o, c, n * p)).collect() };
    let mlp = generator.layer_shapes();
    let g_forward: Vec<_> = mlp.iter().map(|&(i, o)| (points, o, i)).collect();
    let g_backward: Vec<_> = mlp
        .iter()
        .flat_map(|&(i, o)| [(i, o, points), (points, i, o)])
        .collect();
    let mut critic_step = g_forward.clone(); // the fakes
    critic_step.extend(forward(2 * b)); // scores of real and fake crops
    critic_step.extend(weights(2 * b)); // their backward
    critic_step.extend(transposed(2 * b).into_iter().skip(1));
    let mut penalty = forward(b); // the penalty: masks at x_hat,
    penalty.extend(transposed(b)); // dD/dx down the layers,
    penalty.extend(weights(b)); // and its adjoint up them
    penalty.extend(forward(b));
    let mut generator_step = g_forward.clone();
    generator_step.extend(forward(b)); // scores of the fakes
    generator_step.extend(transposed(b)); // dD/dx
    generator_step.extend(&g_backward);
    if config.diversity > 0.0 {
        // The diversity hinge: the fakes' twins, painted and taken back through the generator.
        generator_step.extend(g_forward);
        generator_step.extend(g_backward);
    }
    let mut all = Vec::new();
    for step in 0..config.critic_steps {
        all.extend(&critic_step);
        if step.is_multiple_of(config.penalty_every) {
            all.extend(&penalty); // as in the first iteration
        }
    }
    for _ in 0..config.generator_steps {
        all.extend(&generator_step);
    }
    all
}

/// FLOPs of `products`.
pub fn flops(products: &[(usize, usize, usize)]) -> f64 {
    products
        .iter()
        .map(|&(m, n, k)| 2.0 * (m * n * k) as f64)
        .sum()
}

/// Runs every product once on buffers allocated up front (each `gemm` call on all cores).
pub fn run_products(products: &[(usize, usize, usize)]) -> impl FnMut() + '_ {
    let largest =
        |f: fn(&(usize, usize, usize)) -> usize| products.iter().map(f).max().unwrap_or(0);
    let mut dst = vec![0f32; largest(|&(m, n, _)| m * n)];
    let lhs = vec![0.5f32; largest(|&(m, _, k)| m * k)];
    let rhs = vec![0.01f32; largest(|&(_, n, k)| n * k)];
    move || {
        for &(m, n, k) in products {
            matmul_parallel(&mut dst, (m, n, k), (&lhs, (k, 1)), (&rhs, (n, 1)), false);
        }
    }
}
