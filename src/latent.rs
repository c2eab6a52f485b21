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

/// SplitMix64's finaliser: a bijective 64-bit mix with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
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
