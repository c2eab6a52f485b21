//! The periodic encoding (paper §3.1): sin and cos of `2^j * pi * q_d` for octaves
//! `j = 0..L`, where `q = p / K` is the coordinate scaled by the learnable period.
//!
//! Channel order follows the authors' code: axis-major, then sin before cos, then octave:
//! channel `d * 2L + s * L + j`. A 2D encoding with L = 5 has 20 channels, 3D has 30.

use burn::tensor::Tensor;

/// Number of encoding channels for `dims` axes and `octaves` octaves.
pub fn channels(dims: usize, octaves: usize) -> usize {
    2 * octaves * dims
}

/// Angular frequency of octave `j`: `2^j * pi`.
#[inline]
pub fn frequency(j: usize) -> f32 {
    (1u32 << j) as f32 * std::f32::consts::PI
}

/// Encodes one point `p` with period scale `k` into `out` (`2 * octaves * p.len()` values).
#[inline]
pub fn encode_into(p: &[f32], k: &[f32], octaves: usize, out: &mut [f32]) {
    for (d, (&pd, &kd)) in p.iter().zip(k).enumerate() {
        let q = pd / kd;
        let base = d * 2 * octaves;
        for j in 0..octaves {
            let (s, c) = (frequency(j) * q).sin_cos();
            out[base + j] = s;
            out[base + octaves + j] = c;
        }
    }
}

/// The encoding of scaled coordinates `q`, as a tensor op (differentiable with respect to `q`,
/// hence to K).
///
/// # Shapes
/// - `q`: `[n, dims]`
/// - output: `[n, 2 * octaves * dims]`
pub fn encode(q: Tensor<2>, octaves: usize) -> Tensor<2> {
    let [n, dims] = q.dims();
    let device = q.device();
    let freqs: Vec<f32> = (0..octaves).map(frequency).collect();
    let freqs = Tensor::<1>::from_floats(freqs.as_slice(), &device).reshape([1, 1, octaves]);
    let angles = q.reshape([n, dims, 1]) * freqs; // [n, dims, octaves]
    let sc = Tensor::cat(vec![angles.clone().sin(), angles.cos()], 2); // [n, dims, 2 * octaves]
    sc.reshape([n, dims * 2 * octaves])
}
