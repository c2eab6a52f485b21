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

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3D point with L = 5 has 30 channels, axis-major, sin before cos, then octave; the
    /// tensor encoding (the one K is learned through) gives the same values.
    #[test]
    fn encoding_3d_has_6l_channels_in_the_authors_order() {
        let (p, k, octaves) = ([0.3f32, -1.25, 2.0], [1.5f32, 0.8, 2.5], 5);
        assert_eq!(channels(3, octaves), 30);
        let mut out = vec![0f32; 30];
        encode_into(&p, &k, octaves, &mut out);
        for d in 0..3 {
            for j in 0..octaves {
                let angle = (1u32 << j) as f64 * std::f64::consts::PI * (p[d] / k[d]) as f64;
                let sin = out[d * 2 * octaves + j] as f64;
                let cos = out[d * 2 * octaves + octaves + j] as f64;
                assert!((sin - angle.sin()).abs() < 1e-4, "axis {d} octave {j}");
                assert!((cos - angle.cos()).abs() < 1e-4, "axis {d} octave {j}");
            }
        }
        let device = burn::tensor::Device::flex();
        let q: Vec<f32> = p.iter().zip(&k).map(|(p, k)| p / k).collect();
        let q = Tensor::<2>::from_data(burn::tensor::TensorData::new(q, [1, 3]), &device);
        let tensor: Vec<f32> = encode(q, octaves).into_data().try_to_vec().unwrap();
        for (a, b) in tensor.iter().zip(&out) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }
}
