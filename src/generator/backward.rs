//! The generator's gradient on the CPU, by hand: given `d loss / d output` at a set of points,
//! the gradient of every weight, bias and K, with every product one `gemm` call.
//!
//! Points are taken in groups of at most [`GROUP_POINTS`], in parallel: each group's forward
//! pass with its activations kept (a [`Pass`]: the caller's, kept from painting the fakes when
//! the batch's fit in memory, or run again here, so memory is bounded by the group), then the
//! backward:
//! through tanh, then per layer `dW += x^T · d`, `db += Σ d`, `d = (d · W^T) ⊙ [x > 0]`; at the
//! input, only the encoding's columns depend on a parameter, K: with `q = p / K` and the
//! encoding's `sin(f q)`, `cos(f q)`, `dq = Σ_j f_j (d_sin cos - d_cos sin)` and
//! `dK = -Σ dq · q / K`. Each group's gradient is its own, and they are summed in the
//! groups' order: the result does not depend on the thread count. `tests` checks it against
//! burn's autodiff of [`super::Generator::forward`].

use super::GeneratorWeights;
use rayon::prelude::*;

use super::fused::{input_rows, matmul_strided};
use crate::encoding::frequency;
use crate::latent::LatentField;

/// Points whose activations one thread keeps at once.
pub const GROUP_POINTS: usize = 1024;

/// Gradients of every parameter, in [`GeneratorWeights`]' layouts.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratorGradients {
    pub k: Vec<f32>,
    /// Per layer: weight `[inputs, outputs]` and bias.
    pub layers: Vec<(Vec<f32>, Vec<f32>)>,
}

impl GeneratorGradients {
    pub fn zeros(w: &GeneratorWeights) -> Self {
        Self {
            k: vec![0.0; w.k.len()],
            layers: w
                .layers
                .iter()
                .map(|l| (vec![0.0; l.weight.len()], vec![0.0; l.bias.len()]))
                .collect(),
        }
    }
}

/// One group's points: coordinates `[n, dims]`, their latent field, guidance values (or
/// empty), and `d loss / d output` `[n, channels]`.
pub struct Group<'a> {
    pub p: &'a [f32],
    pub field: &'a LatentField,
    pub guide: &'a [f32],
    pub d_output: &'a [f32],
}

/// A group's forward pass with every layer's input kept: `inputs[l]` is `[n, inputs of layer
/// l]`, and the last is the output `[n, channels]`.
pub struct Pass {
    inputs: Vec<Vec<f32>>,
}

impl Pass {
    /// The generator's output at the group's points, `[n, channels]`.
    pub fn output(&self) -> &[f32] {
        self.inputs.last().expect("a pass has an output")
    }
}

/// Floats a [`Pass`] keeps per point.
pub fn pass_floats_per_point(w: &GeneratorWeights) -> usize {
    let last = w.layers.last().map_or(0, |l| l.outputs);
    w.layers.iter().map(|l| l.inputs).sum::<usize>() + last
}

/// The gradient of the loss through every group, each on one thread, summed in order. With
/// `passes` (one per group, from [`forward`]), their kept activations are used; without, each
/// group's forward pass is run again.
pub fn gradients(
    w: &GeneratorWeights,
    latent_scale: &[f32],
    groups: &[Group],
    passes: Option<&[Pass]>,
) -> GeneratorGradients {
    debug_assert!(passes.is_none_or(|p| p.len() == groups.len()));
    let parts: Vec<GeneratorGradients> = groups
        .par_iter()
        .enumerate()
        .map(|(i, group)| {
            let mut grads = GeneratorGradients::zeros(w);
            match passes {
                Some(passes) => backward(w, group, &passes[i], &mut grads),
                None => accumulate(w, latent_scale, group, &mut grads),
            }
            grads
        })
        .collect();
    let mut total = GeneratorGradients::zeros(w);
    for part in parts {
        let add = |a: &mut [f32], b: &[f32]| a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        add(&mut total.k, &part.k);
        for ((tw, tb), (pw, pb)) in total.layers.iter_mut().zip(&part.layers) {
            add(tw, pw);
            add(tb, pb);
        }
    }
    total
}

/// Adds the gradient of the loss through `group` (at most [`GROUP_POINTS`] points) to `grads`,
/// on the calling thread, running its forward pass again.
pub fn accumulate(
    w: &GeneratorWeights,
    latent_scale: &[f32],
    group: &Group,
    grads: &mut GeneratorGradients,
) {
    let pass = forward(w, latent_scale, group.p, group.field, group.guide);
    backward(w, group, &pass, grads);
}

/// The forward pass at points `p` `[n, dims]` (their latent field and guidance values, or
/// none), keeping every layer's input, on the calling thread.
pub fn forward(
    w: &GeneratorWeights,
    latent_scale: &[f32],
    p: &[f32],
    field: &LatentField,
    guide: &[f32],
) -> Pass {
    let n = p.len() / w.k.len();
    let mut inputs: Vec<Vec<f32>> = Vec::with_capacity(w.layers.len() + 1);
    let mut rows = vec![0f32; n * w.layers[0].inputs];
    input_rows(w, p, field, latent_scale, guide, &mut rows, &mut Vec::new());
    inputs.push(rows);
    let last = w.layers.len() - 1;
    for (l, layer) in w.layers.iter().enumerate() {
        let (k, m) = (layer.inputs, layer.outputs);
        let mut y = vec![0f32; n * m];
        matmul_strided(
            &mut y,
            (n, m, k),
            &inputs[l],
            (k, 1),
            &layer.weight,
            (m, 1),
            false,
        );
        for row in y.chunks_exact_mut(m) {
            for (v, b) in row.iter_mut().zip(&layer.bias) {
                *v = if l < last {
                    (*v + b).max(0.0)
                } else {
                    (*v + b).tanh()
                };
            }
        }
        inputs.push(y);
    }
    Pass { inputs }
}

/// Adds the gradient of the loss through `group`, whose forward pass is `pass`, to `grads`.
fn backward(w: &GeneratorWeights, group: &Group, pass: &Pass, grads: &mut GeneratorGradients) {
    let xs = &pass.inputs;
    let n = group.p.len() / w.k.len();
    debug_assert!(n <= GROUP_POINTS);
    // d: [n, outputs of layer l]
    let mut d: Vec<f32> = group
        .d_output
        .iter()
        .zip(pass.output())
        .map(|(g, y)| g * (1.0 - y * y))
        .collect();
    for (l, layer) in w.layers.iter().enumerate().rev() {
        let (k, m) = (layer.inputs, layer.outputs);
        let (dw, db) = &mut grads.layers[l];
        matmul_strided(dw, (k, m, n), &xs[l], (1, k), &d, (m, 1), true);
        for row in d.chunks_exact(m) {
            for (b, v) in db.iter_mut().zip(row) {
                *b += v;
            }
        }
        let mut dx = vec![0f32; n * k];
        matmul_strided(&mut dx, (n, k, m), &d, (m, 1), &layer.weight, (1, m), false);
        if l > 0 {
            for (g, x) in dx.iter_mut().zip(&xs[l]) {
                *g = if *x > 0.0 { *g } else { 0.0 }; // through the ReLU, without a branch
            }
        }
        d = dx;
    }
    period_gradient(w, group.p, &xs[0], &d, &mut grads.k);
}

/// `d loss / d K` from `d loss / d input` `d_input` at the input rows `inputs`.
fn period_gradient(
    w: &GeneratorWeights,
    p: &[f32],
    inputs: &[f32],
    d_input: &[f32],
    dk: &mut [f32],
) {
    let (dims, octaves) = (w.k.len(), w.octaves);
    let width = w.layers[0].inputs;
    for (i, point) in p.chunks_exact(dims).enumerate() {
        let (x, g) = (
            &inputs[i * width..][..width],
            &d_input[i * width..][..width],
        );
        for d in 0..dims {
            let base = d * 2 * octaves;
            let dq: f32 = (0..octaves)
                .map(|j| {
                    let (sin, cos) = (x[base + j], x[base + octaves + j]);
                    frequency(j) * (g[base + j] * cos - g[base + octaves + j] * sin)
                })
                .sum();
            let q = point[d] / w.k[d];
            dk[d] -= dq * q / w.k[d];
        }
    }
}

#[cfg(test)]
mod tests {
    use burn::prelude::*;

    use super::*;
    use crate::generator::{Generator, GeneratorConfig};

    /// The hand-written gradient equals burn's autodiff of `Σ output · r` for random `r`, for
    /// every weight, bias and K, in 2 and 3 axes, guided or not, across several groups.
    fn matches_autodiff(dims: usize, guided: bool) {
        let config = GeneratorConfig::new()
            .with_dims(dims)
            .with_hidden_layers(3)
            .with_width(16)
            .with_guidance(guided as usize);
        let mut weights = GeneratorWeights::random(&config, 0);
        weights.k = (0..dims).map(|d| 0.8 + 0.3 * d as f32).collect();
        let n = 300;
        let noise = |i: usize, salt: u64| {
            (crate::latent::derive_seed(salt, &[i as u64]) >> 40) as f32 / 16_777_216.0 * 2.0 - 1.0
        };
        let p: Vec<f32> = (0..n * dims).map(|i| 3.0 * noise(i, 1)).collect();
        let guide: Vec<f32> = if guided {
            (0..n).map(|i| noise(i, 2)).collect()
        } else {
            vec![]
        };
        let r: Vec<f32> = (0..n * config.channels).map(|i| noise(i, 3)).collect();
        let field = LatentField::hashed(7, dims, config.latent_dim).with_sigma(config.sigma);
        let scale = vec![config.latent_scale; dims];

        let device = Device::flex().autodiff();
        let generator = Generator::from_weights(&weights, &device);
        let u: Vec<f32> = p.iter().map(|v| v * config.latent_scale).collect();
        let zw = config.latent_dim + guided as usize;
        let mut z = vec![0f32; n * config.latent_dim];
        field.fill(&u, &mut z);
        let latent: Vec<f32> = (0..n)
            .flat_map(|i| {
                let mut row = z[i * config.latent_dim..(i + 1) * config.latent_dim].to_vec();
                row.extend(guide.get(i));
                row
            })
            .collect();
        let tensor = |v: Vec<f32>, shape: [usize; 2]| {
            Tensor::<2>::from_data(TensorData::new(v, shape), &device)
        };
        let out = generator.forward(tensor(p.clone(), [n, dims]), tensor(latent, [n, zw]));
        let loss = (out * tensor(r.clone(), [n, config.channels])).sum();
        let autodiff = loss.backward();

        let c = config.channels;
        let groups: Vec<Group> = (0..n)
            .step_by(128)
            .map(|start| {
                let end = (start + 128).min(n);
                Group {
                    p: &p[start * dims..end * dims],
                    field: &field,
                    guide: if guided { &guide[start..end] } else { &[] },
                    d_output: &r[start * c..end * c],
                }
            })
            .collect();
        let grads = gradients(&weights, &scale, &groups, None);
        let passes: Vec<Pass> = groups
            .iter()
            .map(|g| forward(&weights, &scale, g.p, g.field, g.guide))
            .collect();
        let kept = gradients(&weights, &scale, &groups, Some(&passes));
        assert_eq!(grads, kept, "kept passes give the recomputed gradient");
        let close = |name: &str, got: &[f32], want: Vec<f32>| {
            crate::testing::assert_gradient_close(&format!("{dims}D {name}"), got, &want);
        };
        let grad = |t: Tensor<2>| t.grad(&autodiff).unwrap().try_into_vec_as::<f32>().unwrap();
        for (l, (layer, (dw, db))) in generator.layers.iter().zip(&grads.layers).enumerate() {
            close(&format!("layer {l} weight"), dw, grad(layer.weight.val()));
            let bias = layer.bias.as_ref().unwrap().val().grad(&autodiff).unwrap();
            close(
                &format!("layer {l} bias"),
                db,
                bias.try_into_vec_as::<f32>().unwrap(),
            );
        }
        let dk = generator
            .k
            .val()
            .grad(&autodiff)
            .unwrap()
            .try_into_vec_as::<f32>()
            .unwrap();
        assert!(
            dk.iter().all(|v| v.abs() > 1e-3),
            "K's gradient is not trivial: {dk:?}"
        );
        close("K", &grads.k, dk);
    }

    #[test]
    fn gradients_match_autodiff_2d() {
        matches_autodiff(2, false);
    }

    #[test]
    fn gradients_match_autodiff_3d_guided() {
        matches_autodiff(3, true);
    }
}
