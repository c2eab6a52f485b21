//! The generator evaluated on the CPU as one fused loop per chunk of points.
//!
//! Per chunk the periodic encoding and the latent blend are computed in place, then each layer is
//! one GEMM (`gemm` crate, single-threaded per chunk) followed by bias and ReLU on the same
//! cache-resident buffer; chunks run in parallel on rayon's pool. This computes exactly what the
//! burn [`Generator`](super::Generator) computes, without materialising activations for the whole
//! image (memory is bounded by the chunk) and without a framework call per layer.

use super::GeneratorWeights;
use crate::encoding::encode_into;
use crate::latent::LatentField;

/// Points per chunk: 512 x 128 floats per activation buffer (256 KiB) stays in L2.
pub const CHUNK_POINTS: usize = 512;

/// `dst[m, n] = lhs[m, k] · rhs[k, n]`, all row-major, on the calling thread (`gemm` crate):
/// the one matrix product of the CPU paths (the fused generator, the SIFID stem, the GEMM
/// floor of the benches).
pub fn matmul_into(dst: &mut [f32], lhs: &[f32], rhs: &[f32], m: usize, n: usize, k: usize) {
    matmul_strided(dst, (m, n, k), lhs, (k, 1), rhs, (n, 1), false);
}

/// `dst[m, n] (+)= lhs[m, k] · rhs[k, n]` on the calling thread, `dst` row-major, `lhs` and
/// `rhs` read at the given `(row, column)` strides (so either may be a transposed row-major
/// matrix); with `accumulate` the product is added to `dst`. `ipfn fit`'s backward uses the
/// strides and the accumulation.
#[allow(clippy::too_many_arguments)]
pub fn matmul_strided(
    dst: &mut [f32],
    shape: (usize, usize, usize),
    lhs: &[f32],
    lhs_strides: (usize, usize),
    rhs: &[f32],
    rhs_strides: (usize, usize),
    accumulate: bool,
) {
    let parallelism = gemm::Parallelism::None;
    let (lhs, rhs) = ((lhs, lhs_strides), (rhs, rhs_strides));
    matmul_threads(dst, shape, lhs, rhs, accumulate, parallelism);
}

/// [`matmul_strided`] on rayon's pool: `gemm` splits the output's rows and columns between
/// threads, never the sum over `k`, so the result does not depend on the thread count. For
/// products too large for one core (the fused critic's).
pub fn matmul_parallel(
    dst: &mut [f32],
    shape: (usize, usize, usize),
    lhs: (&[f32], (usize, usize)),
    rhs: (&[f32], (usize, usize)),
    accumulate: bool,
) {
    matmul_threads(
        dst,
        shape,
        lhs,
        rhs,
        accumulate,
        gemm::Parallelism::Rayon(0),
    );
}

/// `lhs · rhs` (strides as [`matmul_strided`]) into a new row-major `[m, n]` on rayon's pool,
/// written once by `gemm` (no zeroing pass first): the fused critic's products.
pub fn product_parallel(
    (m, n, k): (usize, usize, usize),
    lhs: (&[f32], (usize, usize)),
    rhs: (&[f32], (usize, usize)),
) -> Vec<f32> {
    if k == 0 {
        return vec![0.0; m * n];
    }
    let mut dst = Vec::with_capacity(m * n);
    let out = dst.spare_capacity_mut().as_mut_ptr().cast::<f32>();
    // SAFETY: `out` has room for m · n values, and a product that does not accumulate writes
    // every one of them (k > 0), without reading any.
    unsafe {
        gemm_raw(
            out,
            m * n,
            (m, n, k),
            lhs,
            rhs,
            false,
            gemm::Parallelism::Rayon(0),
        );
        dst.set_len(m * n);
    }
    dst
}

fn matmul_threads(
    dst: &mut [f32],
    shape: (usize, usize, usize),
    lhs: (&[f32], (usize, usize)),
    rhs: (&[f32], (usize, usize)),
    accumulate: bool,
    parallelism: gemm::Parallelism,
) {
    // SAFETY: `dst` is a unique borrow of initialised values, so it aliases neither input.
    unsafe {
        gemm_raw(
            dst.as_mut_ptr(),
            dst.len(),
            shape,
            lhs,
            rhs,
            accumulate,
            parallelism,
        )
    }
}

/// # Safety
/// `dst` is valid for writes of `dst_len` values (and, with `accumulate`, reads of
/// initialised ones) and aliases neither input.
unsafe fn gemm_raw(
    dst: *mut f32,
    dst_len: usize,
    (m, n, k): (usize, usize, usize),
    (lhs, (lhs_rs, lhs_cs)): (&[f32], (usize, usize)),
    (rhs, (rhs_rs, rhs_cs)): (&[f32], (usize, usize)),
    accumulate: bool,
    parallelism: gemm::Parallelism,
) {
    if m == 0 || n == 0 || k == 0 {
        return;
    }
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| (rows - 1) * rs + (cols - 1) * cs;
    assert!(
        dst_len >= m * n
            && lhs.len() > last(m, k, lhs_rs, lhs_cs)
            && rhs.len() > last(k, n, rhs_rs, rhs_cs),
        "matmul: buffers smaller than {m}x{k} . {k}x{n}"
    );
    // SAFETY: the assert bounds every access to the inputs at the strides given, and to `dst`
    // (the caller's guarantee covers the rest).
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst,
            1,
            n as isize,
            accumulate,
            lhs.as_ptr(),
            lhs_cs as isize,
            lhs_rs as isize,
            rhs.as_ptr(),
            rhs_cs as isize,
            rhs_rs as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism,
        );
    }
}

/// Per-thread working memory for [`FusedGenerator::eval`].
#[derive(Default)]
pub struct Scratch {
    a: Vec<f32>,
    b: Vec<f32>,
    u: Vec<f32>,
}

/// A CPU evaluator holding a host copy of the generator's weights.
#[derive(Debug, Clone)]
pub struct FusedGenerator {
    weights: GeneratorWeights,
}

impl FusedGenerator {
    pub fn new(weights: GeneratorWeights) -> Self {
        Self { weights }
    }

    pub fn weights(&self) -> &GeneratorWeights {
        &self.weights
    }

    /// Evaluates the generator at `n` points, looking the latent field up at
    /// `u = p * latent_scale` (per axis).
    ///
    /// # Shapes
    /// - `p`: `[n, dims]` coordinates (row-major)
    /// - `guide`: `[n]` guidance values, for a guided model (else empty)
    /// - `out`: `[n, channels]`, written with tanh outputs in [-1, 1]
    pub fn eval(
        &self,
        p: &[f32],
        field: &LatentField,
        latent_scale: &[f32],
        guide: &[f32],
        out: &mut [f32],
        scratch: &mut Scratch,
    ) {
        let w = &self.weights;
        let dims = w.k.len();
        let n = p.len() / dims;
        let widest = w
            .layers
            .iter()
            .map(|l| l.outputs.max(l.inputs))
            .max()
            .unwrap_or(0);
        scratch.a.resize(n * widest, 0.0);
        scratch.b.resize(n * widest, 0.0);

        input_rows(
            w,
            p,
            field,
            latent_scale,
            guide,
            &mut scratch.a,
            &mut scratch.u,
        );
        let (mut src, mut dst) = (&mut scratch.a, &mut scratch.b);
        let last = w.layers.len() - 1;
        for (l, layer) in w.layers.iter().enumerate() {
            let (k, m) = (layer.inputs, layer.outputs);
            matmul_into(dst, src, &layer.weight, n, m, k); // dst[n, m] = src[n, k] . W[k, m]
            let rows = &mut dst[..n * m];
            if l < last {
                for row in rows.chunks_exact_mut(m) {
                    for (v, b) in row.iter_mut().zip(&layer.bias) {
                        *v = (*v + b).max(0.0);
                    }
                }
            } else {
                for (row, o) in rows.chunks_exact(m).zip(out.chunks_exact_mut(m)) {
                    for ((v, b), o) in row.iter().zip(&layer.bias).zip(o.iter_mut()) {
                        *o = (v + b).tanh();
                    }
                }
            }
            std::mem::swap(&mut src, &mut dst);
        }
    }
}

/// The MLP's input rows at `n` points: `[encoding(p / K), latent(p * latent_scale), guide]`,
/// written to `rows` `[n, input]` (`u` is working memory).
pub(crate) fn input_rows(
    w: &GeneratorWeights,
    p: &[f32],
    field: &LatentField,
    latent_scale: &[f32],
    guide: &[f32],
    rows: &mut [f32],
    u: &mut Vec<f32>,
) {
    let dims = w.k.len();
    let n = p.len() / dims;
    let enc = w.octaves * 2 * dims;
    let guided = !guide.is_empty();
    let input = enc + field.latent_dim() + guided as usize;
    debug_assert_eq!(w.layers[0].inputs, input);
    debug_assert!(!guided || guide.len() == n);
    u.resize(n * dims, 0.0);
    for (i, point) in p.chunks_exact(dims).enumerate() {
        let row = &mut rows[i * input..(i + 1) * input];
        encode_into(point, &w.k, w.octaves, &mut row[..enc]);
        for d in 0..dims {
            u[i * dims + d] = point[d] * latent_scale[d];
        }
    }
    let ld = field.latent_dim();
    let rows = rows[..n * input].chunks_exact_mut(input);
    for (i, (u, row)) in u.chunks_exact(dims).zip(rows).enumerate() {
        let row = &mut row[enc..];
        field.at(u, &mut row[..ld]);
        if guided {
            row[ld] = guide[i];
        }
    }
}
