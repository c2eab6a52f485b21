//! The latent random field (paper §3.2, eq. 4).
//!
//! Random vectors sit on an integer lattice; the field at a point `u` blends the vectors at the
//! corners of the lattice cell around `u` with weights `softmax(-distance / sigma)`. The
//! generator looks the field up at `u = p * latent_scale` (the authors use `p / 2`).
//!
//! Two sources of lattice vectors:
//! - [`LatentSource::Hashed`]: the vector at lattice point `(i, j[, k])` is a pure function of
//!   `(seed, i, j[, k])` (a counter-based hash, no sequential RNG state), so the field is infinite
//!   and any region renders the same pixels in any order or chunking. An optional period wraps the
//!   lattice indices, which makes the field exactly periodic (used for tileable output).
//! - [`LatentSource::Grid`]: an explicit finite grid, indexed as the authors' code does
//!   (`floor(u) + n / 2`, clamped to the grid), used to reproduce their numbers.

use burn::prelude::*;
use burn::tensor::activation::softmax;

/// Default softmax temperature of the corner blend (paper eq. 4).
pub const DEFAULT_SIGMA: f32 = 0.2;

/// Largest supported number of latent channels.
pub const MAX_LATENT_DIM: usize = 64;

/// Where the lattice vectors come from.
#[derive(Debug, Clone, PartialEq)]
pub enum LatentSource {
    /// Infinite lattice of uniform(-1, 1) vectors hashed from `(seed, index)`.
    Hashed {
        seed: u64,
        /// Lattice period per axis (indices wrap modulo it), or `None` for a non-repeating field.
        period: Option<Vec<i64>>,
    },
    /// Explicit grid `[latent_dim, n_0, n_1, ...]` (row-major), indexed with the authors'
    /// centring and clamping.
    Grid { shape: Vec<usize>, values: Vec<f32> },
}

/// A latent random field over `dims` spatial axes with `latent_dim` channels.
#[derive(Debug, Clone, PartialEq)]
pub struct LatentField {
    dims: usize,
    latent_dim: usize,
    sigma: f32,
    source: LatentSource,
}

impl LatentField {
    /// An infinite, non-repeating field drawn from `seed`.
    pub fn hashed(seed: u64, dims: usize, latent_dim: usize) -> Self {
        assert!((1..=3).contains(&dims), "latent field supports 1 to 3 axes");
        assert!(
            latent_dim <= MAX_LATENT_DIM,
            "latent_dim above {MAX_LATENT_DIM}"
        );
        Self {
            dims,
            latent_dim,
            sigma: DEFAULT_SIGMA,
            source: LatentSource::Hashed { seed, period: None },
        }
    }

    /// The same field with lattice indices wrapped modulo `period` (one entry per axis, each
    /// at least 1), so that `at(u + period) == at(u)` exactly in lattice units.
    pub fn periodic(mut self, period: &[i64]) -> Self {
        assert_eq!(period.len(), self.dims, "one period per axis");
        assert!(period.iter().all(|&n| n >= 1), "periods must be at least 1");
        if let LatentSource::Hashed { period: p, .. } = &mut self.source {
            *p = Some(period.to_vec());
        }
        self
    }

    /// A field read from an explicit grid of shape `[latent_dim, n_0, .., n_{dims-1}]`, as the
    /// authors' code stores it (`latent_grid.npy`).
    pub fn from_grid(shape: &[usize], values: Vec<f32>) -> Self {
        assert!(
            shape.len() >= 2 && shape.len() <= 4,
            "grid is [latent_dim, n_0, ...]"
        );
        assert_eq!(
            shape.iter().product::<usize>(),
            values.len(),
            "grid shape and data disagree"
        );
        assert!(
            shape[0] <= MAX_LATENT_DIM,
            "latent_dim above {MAX_LATENT_DIM}"
        );
        Self {
            dims: shape.len() - 1,
            latent_dim: shape[0],
            sigma: DEFAULT_SIGMA,
            source: LatentSource::Grid {
                shape: shape.to_vec(),
                values,
            },
        }
    }

    /// Sets the softmax temperature of the corner blend.
    pub fn with_sigma(mut self, sigma: f32) -> Self {
        self.sigma = sigma;
        self
    }

    pub fn dims(&self) -> usize {
        self.dims
    }

    pub fn latent_dim(&self) -> usize {
        self.latent_dim
    }

    /// The softmax temperature of the corner blend.
    pub fn sigma(&self) -> f32 {
        self.sigma
    }

    pub fn source(&self) -> &LatentSource {
        &self.source
    }

    /// Writes the lattice vector at integer point `index` into `out` (`latent_dim` values).
    pub fn lattice_vector(&self, index: &[i64], out: &mut [f32]) {
        debug_assert_eq!(index.len(), self.dims);
        match &self.source {
            LatentSource::Hashed { seed, period } => {
                let mut key = mix64(seed ^ 0x1f83_d9ab_fb41_bd6b);
                for (axis, &i) in index.iter().enumerate() {
                    let i = match period {
                        Some(p) => i.rem_euclid(p[axis]),
                        None => i,
                    };
                    key = mix64(key ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
                }
                for (c, o) in out.iter_mut().enumerate() {
                    let bits =
                        mix64(key.wrapping_add((c as u64 + 1).wrapping_mul(0xd1b5_4a32_d192_ed03)));
                    // 24 random bits -> uniform in [-1, 1).
                    *o = (bits >> 40) as f32 * (2.0 / 16_777_216.0) - 1.0;
                }
            }
            LatentSource::Grid { shape, values } => {
                // Authors' indexing: floor(u) + n/2, clamped to [0, n-1].
                let mut offset = 0usize;
                let mut plane = 1usize;
                for axis in (0..self.dims).rev() {
                    let n = shape[axis + 1];
                    let i = (index[axis] + (n / 2) as i64).clamp(0, n as i64 - 1) as usize;
                    offset += i * plane;
                    plane *= n;
                }
                for (c, o) in out.iter_mut().enumerate() {
                    *o = values[c * plane + offset];
                }
            }
        }
    }

    /// The blended latent vector at lattice-space point `u` (`dims` values), written to `out`
    /// (`latent_dim` values).
    pub fn at(&self, u: &[f32], out: &mut [f32]) {
        let dims = self.dims;
        debug_assert_eq!(u.len(), dims);
        let mut base = [0i64; 3];
        let mut frac = [0f32; 3];
        for (d, &ud) in u.iter().enumerate() {
            let f = ud.floor();
            base[d] = f as i64;
            frac[d] = ud - f;
        }
        let corners = 1usize << dims;
        let mut weight = [0f32; 8];
        for (corner, w) in weight.iter_mut().enumerate().take(corners) {
            let mut dist2 = 0f32;
            for (d, &f) in frac[..dims].iter().enumerate() {
                let t = if corner >> d & 1 == 1 { 1.0 - f } else { f };
                dist2 += t * t;
            }
            *w = -dist2.sqrt() / self.sigma;
        }
        let max = weight[..corners]
            .iter()
            .cloned()
            .fold(f32::NEG_INFINITY, f32::max);
        let mut total = 0f32;
        for w in &mut weight[..corners] {
            *w = (*w - max).exp();
            total += *w;
        }
        out.iter_mut().for_each(|o| *o = 0.0);
        let mut scratch = [0f32; MAX_LATENT_DIM];
        let vector = &mut scratch[..self.latent_dim];
        let mut index = [0i64; 3];
        for (corner, &w) in weight[..corners].iter().enumerate() {
            for (d, (i, b)) in index.iter_mut().zip(&base).take(dims).enumerate() {
                *i = b + (corner >> d & 1) as i64;
            }
            self.lattice_vector(&index[..dims], vector);
            let w = w / total;
            for (o, v) in out.iter_mut().zip(vector.iter()) {
                *o += w * v;
            }
        }
    }

    /// Fills `out` (`n x latent_dim`, row-major) with the field at `n` points `u`
    /// (`n x dims`, row-major, already in lattice units).
    pub fn fill(&self, u: &[f32], out: &mut [f32]) {
        let (dims, ld) = (self.dims, self.latent_dim);
        debug_assert_eq!(u.len() / dims, out.len() / ld);
        for (point, o) in u.chunks_exact(dims).zip(out.chunks_exact_mut(ld)) {
            self.at(point, o);
        }
    }
}

/// The lattice-space bounds `(lo, hi)` of the grid `axes[0] x axes[1] (x axes[2])` looked up at
/// `u = p * latent_scale`, for [`LatticeBox::new`] and [`DeviceLattice::new`]. GPUs compute
/// `u` as here (one f32 product), so the bounds hold there.
pub fn grid_lattice_bounds(axes: &[Vec<f32>], latent_scale: &[f32]) -> (Vec<f32>, Vec<f32>) {
    axes.iter()
        .zip(latent_scale)
        .map(|(a, &s)| {
            a.iter()
                .map(|&v| v * s)
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), u| {
                    (l.min(u), h.max(u))
                })
        })
        .unzip()
}

/// The lattice vectors that a batch of regions touches, on the host: what [`DeviceLattice`]
/// and the GPU generator kernel upload.
#[derive(Debug, Clone)]
pub struct LatticeBox {
    /// `[fields * cells, latent_dim]`, row-major over each field's box.
    pub values: Vec<f32>,
    /// Lowest lattice index per axis, per field: `[fields, dims]`.
    pub lows: Vec<i64>,
    /// Index strides of a box (row-major), per axis.
    pub strides: Vec<i64>,
    /// Lattice points in one field's box.
    pub cells: i64,
}

impl LatticeBox {
    /// The lattice points around every `u` with `lo[d] <= u[d] <= hi[d]`, one box per field.
    ///
    /// # Shapes
    /// - `fields`: per field, `(field, lo, hi)` with `dims` entries each (lattice units)
    pub fn new(fields: &[(&LatentField, Vec<f32>, Vec<f32>)]) -> Self {
        let (first, _, _) = fields.first().expect("at least one field");
        let (dims, ld, sigma) = (first.dims, first.latent_dim, first.sigma);
        let lows: Vec<Vec<i64>> = fields
            .iter()
            .map(|(_, lo, _)| lo.iter().map(|v| v.floor() as i64).collect())
            .collect();
        // Lattice points per axis: the cells from floor(lo) to floor(hi), plus their far corner.
        let extent: Vec<i64> = (0..dims)
            .map(|d| {
                fields
                    .iter()
                    .zip(&lows)
                    .map(|((_, _, hi), low)| hi[d].floor() as i64 - low[d] + 2)
                    .max()
                    .unwrap_or(2)
            })
            .collect();
        let mut strides = vec![1i64; dims];
        for d in (0..dims.saturating_sub(1)).rev() {
            strides[d] = strides[d + 1] * extent[d + 1];
        }
        let cells = extent.iter().product::<i64>();
        let mut values = vec![0f32; fields.len() * cells as usize * ld];
        let mut index = vec![0i64; dims];
        for (f, ((field, _, _), low)) in fields.iter().zip(&lows).enumerate() {
            assert!(
                field.dims == dims && field.latent_dim == ld && field.sigma == sigma,
                "fields of one lattice box share their shape"
            );
            for cell in 0..cells {
                for d in 0..dims {
                    index[d] = low[d] + cell / strides[d] % extent[d];
                }
                let at = (f * cells as usize + cell as usize) * ld;
                field.lattice_vector(&index, &mut values[at..at + ld]);
            }
        }
        Self {
            values,
            lows: lows.concat(),
            strides,
            cells,
        }
    }
}

/// The lattice vectors that a batch of regions touches, held on a burn device, with the blend
/// of eq. 4 evaluated there: GPU synthesis and training send a few hundred lattice vectors to
/// the device instead of `latent_dim` floats per point.
///
/// Each field (one per generated sample in training; one for a synthesis) gets the same-sized
/// box of lattice indices; point `i` belongs to field `field[i]`. The blend computes what
/// [`LatentField::at`] computes: `floor` and `u - floor(u)` are exact in f32 on every backend,
/// so points select the same cell as on the CPU and values differ only by the rounding of
/// `sqrt` and `exp`.
#[derive(Debug, Clone)]
pub struct DeviceLattice {
    /// `[fields * cells, latent_dim]`, row-major over each field's box.
    table: Tensor<2>,
    /// Lowest lattice index per axis, per field: `[fields, dims]`.
    lows: Tensor<2, Int>,
    /// Index strides of a box (row-major), per axis.
    strides: Vec<i64>,
    cells: i64,
    dims: usize,
    latent_dim: usize,
    sigma: f32,
}

impl DeviceLattice {
    /// The lattice points around every `u` with `lo[d] <= u[d] <= hi[d]`, one box per field.
    ///
    /// # Shapes
    /// - `bounds`: per field, `(lo, hi)` with `dims` entries each (lattice units)
    pub fn new(fields: &[(&LatentField, Vec<f32>, Vec<f32>)], device: &Device) -> Self {
        let (first, _, _) = fields.first().expect("at least one field");
        let lattice = LatticeBox::new(fields);
        let n = fields.len();
        Self {
            table: Tensor::from_data(
                TensorData::new(
                    lattice.values,
                    [n * lattice.cells as usize, first.latent_dim],
                ),
                device,
            ),
            lows: Tensor::from_data(TensorData::new(lattice.lows, [n, first.dims]), device),
            strides: lattice.strides,
            cells: lattice.cells,
            dims: first.dims,
            latent_dim: first.latent_dim,
            sigma: first.sigma,
        }
    }

    /// The blended latent vectors at lattice-space points `u`.
    ///
    /// # Shapes
    /// - `u`: `[n, dims]`, inside the bounds given to [`DeviceLattice::new`] for its field
    /// - `field`: `[n]`, the field of each point (`None`: all points belong to field 0)
    /// - output: `[n, latent_dim]`
    pub fn blend(&self, u: Tensor<2>, field: Option<Tensor<1, Int>>) -> Tensor<2> {
        let [n, dims] = u.dims();
        assert_eq!(
            dims, self.dims,
            "points have one coordinate per lattice axis"
        );
        let device = u.device();
        let base = u.clone().floor(); // [n, dims]
        let frac = u - base.clone(); // [n, dims], exact
        let (low, offset) = match field {
            Some(f) => (
                self.lows.clone().select(0, f.clone()), // [n, dims]
                f.mul_scalar(self.cells),               // [n]
            ),
            None => (
                self.lows.clone().slice([0..1, 0..dims]).expand([n, dims]),
                Tensor::zeros([n], &device),
            ),
        };
        let strides =
            Tensor::<2, Int>::from_data(TensorData::new(self.strides.clone(), [1, dims]), &device);
        // Flat table row of each point's low corner.
        let local = (base.int() - low) * strides; // [n, dims]
        let row = local.sum_dim(1).reshape([n]) + offset; // [n]
        let corners = 1usize << dims;
        let mut logits = Vec::with_capacity(corners);
        let mut rows = Vec::with_capacity(corners);
        for corner in 0..corners {
            let mut dist2: Option<Tensor<2>> = None;
            let mut shift = 0i64;
            for d in 0..dims {
                let f = frac.clone().slice([0..n, d..d + 1]); // [n, 1]
                let t = if corner >> d & 1 == 1 {
                    shift += self.strides[d];
                    f.neg().add_scalar(1.0)
                } else {
                    f
                };
                let t2 = t.clone() * t;
                dist2 = Some(match dist2 {
                    Some(s) => s + t2,
                    None => t2,
                });
            }
            let dist = dist2.expect("at least one axis").sqrt(); // [n, 1]
            logits.push(dist.div_scalar(-self.sigma));
            rows.push(row.clone().add_scalar(shift));
        }
        let weights = softmax(Tensor::cat(logits, 1), 1); // [n, corners]
        let mut out: Option<Tensor<2>> = None;
        for (corner, r) in rows.into_iter().enumerate() {
            let w = weights.clone().slice([0..n, corner..corner + 1]); // [n, 1]
            let v = self.table.clone().select(0, r) * w; // [n, latent_dim]
            out = Some(match out {
                Some(o) => o + v,
                None => v,
            });
        }
        out.expect("at least one corner")
    }

    pub fn latent_dim(&self) -> usize {
        self.latent_dim
    }
}

/// SplitMix64's finaliser: a bijective 64-bit mix with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Uniform in [0, 1) from a seed and counters: the top 24 bits of [`derive_seed`], so every
/// random draw of the project is a pure function of where it is made.
pub fn unit_uniform(seed: u64, counters: &[u64]) -> f32 {
    (derive_seed(seed, counters) >> 40) as f32 / 16_777_216.0
}

/// A seed derived from a parent seed and a stream of counters (for per-sample fields).
pub fn derive_seed(parent: u64, counters: &[u64]) -> u64 {
    counters
        .iter()
        .fold(mix64(parent ^ 0x5851_f42d_4c95_7f2d), |k, &c| {
            mix64(k ^ c.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_vectors_are_pure_functions_of_seed_and_index() {
        let a = LatentField::hashed(7, 2, 5);
        let b = LatentField::hashed(7, 2, 5);
        let c = LatentField::hashed(8, 2, 5);
        let (mut va, mut vb, mut vc) = ([0f32; 5], [0f32; 5], [0f32; 5]);
        a.lattice_vector(&[3, -1000000007], &mut va);
        b.lattice_vector(&[3, -1000000007], &mut vb);
        c.lattice_vector(&[3, -1000000007], &mut vc);
        assert_eq!(va, vb);
        assert_ne!(va, vc);
        assert!(va.iter().all(|v| (-1.0..1.0).contains(v)));
    }

    #[test]
    fn hashed_values_are_uniform_in_minus_one_one() {
        let f = LatentField::hashed(1, 2, 4);
        let mut v = [0f32; 4];
        let (mut sum, mut sum2, mut n) = (0f64, 0f64, 0f64);
        for i in -50..50 {
            for j in -50..50 {
                f.lattice_vector(&[i, j], &mut v);
                for &x in &v {
                    sum += x as f64;
                    sum2 += (x * x) as f64;
                    n += 1.0;
                }
            }
        }
        let mean = sum / n;
        let var = sum2 / n - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0 / 3.0).abs() < 0.01, "variance {var}");
    }

    #[test]
    fn periodic_field_repeats_exactly() {
        let f = LatentField::hashed(3, 2, 5).periodic(&[4, 6]);
        let (mut a, mut b) = ([0f32; 5], [0f32; 5]);
        for &(y, x) in &[(0.375f32, 0.75f32), (1.875, 5.5), (-2.25, 3.0)] {
            f.at(&[y, x], &mut a);
            f.at(&[y + 4.0, x - 12.0], &mut b);
            assert_eq!(a, b);
        }
    }

    #[test]
    fn blend_is_the_corner_vector_at_lattice_points_softly() {
        // At a lattice point the nearest corner dominates: weights exp(0), exp(-5), exp(-5),
        // exp(-sqrt2 / 0.2).
        let f = LatentField::hashed(9, 2, 3);
        let (mut at, mut corner) = ([0f32; 3], [0f32; 3]);
        f.at(&[2.0, -3.0], &mut at);
        f.lattice_vector(&[2, -3], &mut corner);
        for (a, c) in at.iter().zip(corner.iter()) {
            assert!((a - c).abs() < 0.05, "{a} vs {c}");
        }
    }

    /// In 3D the blend runs over the cell's 8 corners with weights softmax(-distance / sigma),
    /// checked against the formula written out from the corner positions, in f64.
    #[test]
    fn blend_3d_is_the_softmax_over_the_cells_8_corners() {
        let sigma = 0.3;
        let f = LatentField::hashed(11, 3, 4).with_sigma(sigma);
        for u in [[0.25f32, -1.6, 7.9], [-3.5, 0.01, 2.5], [10.0, 10.5, -0.75]] {
            let mut ours = [0f32; 4];
            f.at(&u, &mut ours);
            let base: Vec<i64> = u.iter().map(|v| v.floor() as i64).collect();
            let mut expected = [0f64; 4];
            let mut total = 0f64;
            let mut vector = [0f32; 4];
            for corner in 0..8 {
                let c: Vec<i64> = (0..3).map(|d| base[d] + (corner >> d & 1) as i64).collect();
                let distance = (0..3)
                    .map(|d| (u[d] as f64 - c[d] as f64).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let w = (-distance / sigma as f64).exp();
                total += w;
                f.lattice_vector(&c, &mut vector);
                for (e, v) in expected.iter_mut().zip(vector) {
                    *e += w * v as f64;
                }
            }
            for (o, e) in ours.iter().zip(expected) {
                assert!(
                    (*o as f64 - e / total).abs() < 1e-5,
                    "{u:?}: {o} vs {}",
                    e / total
                );
            }
        }
        // A periodic 3D field repeats on every axis.
        let p = LatentField::hashed(11, 3, 4).periodic(&[3, 4, 5]);
        let (mut a, mut b) = ([0f32; 4], [0f32; 4]);
        p.at(&[0.375, 1.75, -2.25], &mut a);
        p.at(&[3.375, -2.25, 7.75], &mut b);
        assert_eq!(a, b);
    }

    #[test]
    fn grid_source_clamps_like_the_authors() {
        // 1 channel, 4x4 grid holding its own flat index.
        let f = LatentField::from_grid(&[1, 4, 4], (0..16).map(|v| v as f32).collect());
        let mut v = [0f32];
        f.lattice_vector(&[0, 0], &mut v); // (0 + 2, 0 + 2)
        assert_eq!(v[0], 10.0);
        f.lattice_vector(&[-9, 100], &mut v); // clamped to (0, 3)
        assert_eq!(v[0], 3.0);
    }
}
