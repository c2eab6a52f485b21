//! The structure measure: how far a sample's autocorrelation is from its exemplar's.
//!
//! SIFID compares statistics of local features and so does not see how those features are
//! arranged: cells laid on a square grid and cells laid on a hexagonal lattice can score
//! alike. The autocorrelation of the luminance sees exactly that arrangement: its peaks sit at
//! the offsets where the pattern repeats. The **structure distance** of two images is the mean
//! absolute difference of their normalised autocorrelations over lags up to
//! [`structure_lags`] of the exemplar in each direction: 0 for the same arrangement, wherever
//! it starts (a shifted copy scores near 0), and larger the more the arrangements differ.
//!
//! No sample matches its exemplar exactly, and neither do two parts of the exemplar itself:
//! [`structure_floor`], the distance of the exemplar's two halves to the whole, is what a
//! model that paints the exemplar's own structure can expect.

use super::fft::{Complex, fft};

/// The normalised autocorrelation of an image's luminance for lags `-lags..=lags` on each
/// axis: at each lag (`dy`, `dx`), the mean product of the mean-removed luminances of the
/// pixel pairs that far apart, over the pairs that lie inside the image (zero-padded, not
/// wrapped), divided by the value at lag 0 (so 1 there).
///
/// A constant image has no structure: its map is all zeros (lag 0 included), and so is the
/// map at a lag where no pixels overlap (one as long as the image's side or longer).
#[derive(Debug, Clone, PartialEq)]
pub struct Autocorrelation {
    lags: usize,
    /// Row-major over `dy` then `dx`, each from `-lags` to `lags`.
    map: Vec<f64>,
}

/// The largest lag the structure measure compares, for an exemplar of `height` x `width`: a
/// quarter of its shorter side: far enough to see how neighbouring features are arranged,
/// near enough that most pixels pair up at every lag, including in the exemplar's halves that
/// [`structure_floor`] compares.
pub fn structure_lags(height: usize, width: usize) -> usize {
    height.min(width) / 4
}

impl Autocorrelation {
    /// The map of `values` (`[height, width, channels]`, interleaved) for lags up to `lags`.
    pub fn of(values: &[f32], height: usize, width: usize, channels: usize, lags: usize) -> Self {
        let gray = centred_luminance(values, height, width, channels);
        let side = 2 * lags + 1;
        let Some(gray) = gray else {
            return Self {
                lags,
                map: vec![0.0; side * side],
            };
        };
        let sums = lag_sums(&gray, height, width, lags);
        let mean_at = |dy: usize, dx: usize| {
            let overlap = |n: usize, d: usize| n.saturating_sub(d.abs_diff(lags));
            let pairs = overlap(height, dy) * overlap(width, dx);
            if pairs == 0 {
                0.0
            } else {
                sums[dy * side + dx] / pairs as f64
            }
        };
        let zero = mean_at(lags, lags);
        let map = (0..side * side)
            .map(|i| mean_at(i / side, i % side) / zero)
            .collect();
        Self { lags, map }
    }

    /// The largest lag on each axis.
    pub fn lags(&self) -> usize {
        self.lags
    }

    /// The map at lag (`dy`, `dx`), each within `-lags..=lags`.
    pub fn at(&self, dy: isize, dx: isize) -> f64 {
        let (l, side) = (self.lags as isize, 2 * self.lags + 1);
        assert!(dy.abs() <= l && dx.abs() <= l, "lag ({dy}, {dx}) past {l}");
        self.map[(dy + l) as usize * side + (dx + l) as usize]
    }

    /// The structure distance: the mean absolute difference of the two maps over every lag.
    /// Both must have the same `lags`.
    pub fn distance(&self, other: &Self) -> f64 {
        assert_eq!(self.lags, other.lags, "maps over different lags");
        let sum: f64 = self
            .map
            .iter()
            .zip(&other.map)
            .map(|(a, b)| (a - b).abs())
            .sum();
        sum / self.map.len() as f64
    }
}

/// The exemplar's structure floor: split `values` (`[height, width, channels]`) into two
/// halves across its longer side, and average the structure distance of each half to the
/// whole, all with the whole's [`structure_lags`].
pub fn structure_floor(values: &[f32], height: usize, width: usize, channels: usize) -> f64 {
    let lags = structure_lags(height, width);
    let whole = Autocorrelation::of(values, height, width, channels, lags);
    let halves = if height >= width {
        let (top, bottom) = values.split_at(height / 2 * width * channels);
        [
            (top.to_vec(), height / 2),
            (bottom.to_vec(), height - height / 2),
        ]
        .map(|(v, h)| (v, h, width))
    } else {
        let (left, right) = split_columns(values, width, channels);
        [(left, width / 2), (right, width - width / 2)].map(|(v, w)| (v, height, w))
    };
    halves
        .iter()
        .map(|(v, h, w)| whole.distance(&Autocorrelation::of(v, *h, *w, channels, lags)))
        .sum::<f64>()
        / 2.0
}

/// The left `width / 2` columns of `values` (`[height, width, channels]`) and the rest.
fn split_columns(values: &[f32], width: usize, channels: usize) -> (Vec<f32>, Vec<f32>) {
    let cut = width / 2 * channels;
    let (mut left, mut right) = (Vec::new(), Vec::new());
    for row in values.chunks_exact(width * channels) {
        left.extend_from_slice(&row[..cut]);
        right.extend_from_slice(&row[cut..]);
    }
    (left, right)
}

/// Luminance (0.299 R + 0.587 G + 0.114 B for three channels or more, the first channel for
/// one or two) with its mean removed; `None` where it is the same everywhere.
fn centred_luminance(
    values: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> Option<Vec<f64>> {
    let luminance = |p: &[f32]| match channels {
        1 | 2 => p[0] as f64,
        _ => 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64,
    };
    let gray: Vec<f64> = values
        .chunks_exact(channels)
        .take(height * width)
        .map(luminance)
        .collect();
    let (lo, hi) = gray
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if gray.is_empty() || lo == hi {
        return None;
    }
    let mean = gray.iter().sum::<f64>() / gray.len() as f64;
    Some(gray.into_iter().map(|v| v - mean).collect())
}

/// The linear autocorrelation sums `sum g(y, x) g(y + dy, x + dx)` of `gray` (`[height, width]`)
/// for `dy`, `dx` in `-lags..=lags`, row-major, through an FFT of the image zero-padded to at
/// least `(height + lags) x (width + lags)`, so no lag wraps around.
fn lag_sums(gray: &[f64], height: usize, width: usize, lags: usize) -> Vec<f64> {
    let (ph, pw) = (fft_len(height + lags), fft_len(width + lags));
    // Rows, then columns (as rows of the transpose); the padding rows stay zero.
    let mut rows = vec![Complex::default(); ph * pw];
    for (y, line) in gray.chunks_exact(width).enumerate() {
        let row = &mut rows[y * pw..y * pw + width];
        row.iter_mut().zip(line).for_each(|(r, &g)| r.re = g);
        fft(&mut rows[y * pw..(y + 1) * pw], false);
    }
    let mut cols = transpose(&rows, ph, pw);
    cols.chunks_exact_mut(ph).for_each(|c| fft(c, false));
    // The power spectrum, back through the columns, then only the rows of the lags we keep.
    cols.iter_mut().for_each(|v| {
        *v = Complex {
            re: v.norm_sqr(),
            im: 0.0,
        }
    });
    cols.chunks_exact_mut(ph).for_each(|c| fft(c, true));
    let wrap = |d: usize, n: usize| (d + n - lags) % n; // lag index -lags..=lags into 0..n
    let scale = (ph * pw) as f64;
    let side = 2 * lags + 1;
    let mut sums = Vec::with_capacity(side * side);
    for dy in 0..side {
        let y = wrap(dy, ph);
        let mut row: Vec<Complex> = (0..pw).map(|x| cols[x * ph + y]).collect();
        fft(&mut row, true);
        sums.extend((0..side).map(|dx| row[wrap(dx, pw)].re / scale));
    }
    sums
}

/// `m` (`rows x cols`, row-major) transposed.
fn transpose(m: &[Complex], rows: usize, cols: usize) -> Vec<Complex> {
    (0..rows * cols)
        .map(|i| m[(i % rows) * cols + i / rows])
        .collect()
}

/// The smallest power of two of at least `n` (the FFT's lengths).
fn fft_len(n: usize) -> usize {
    n.max(1).next_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sums `lag_sums` computes, pair by pair.
    fn brute_sums(gray: &[f64], height: usize, width: usize, lags: usize) -> Vec<f64> {
        let l = lags as isize;
        let mut sums = Vec::new();
        for dy in -l..=l {
            for dx in -l..=l {
                let mut s = 0.0;
                for y in 0..height as isize {
                    for x in 0..width as isize {
                        let (y2, x2) = (y + dy, x + dx);
                        if (0..height as isize).contains(&y2) && (0..width as isize).contains(&x2) {
                            s += gray[(y * width as isize + x) as usize]
                                * gray[(y2 * width as isize + x2) as usize];
                        }
                    }
                }
                sums.push(s);
            }
        }
        sums
    }

    #[test]
    fn fft_sums_match_brute_force_without_wrapping() {
        let (h, w, lags) = (12, 9, 4);
        // A known, non-symmetric pattern: a diagonal ramp, a bright corner, a dark column.
        let gray: Vec<f64> = (0..h * w)
            .map(|i| {
                let (y, x) = (i / w, i % w);
                let corner = if y < 3 && x < 2 { 1.5 } else { 0.0 };
                let column = if x == 6 { -1.0 } else { 0.0 };
                0.1 * (y as f64) - 0.07 * (x * x) as f64 + corner + column
            })
            .collect();
        let fast = lag_sums(&gray, h, w, lags);
        let slow = brute_sums(&gray, h, w, lags);
        assert_eq!(fast.len(), slow.len());
        for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
            assert!((a - b).abs() < 1e-9, "lag {i}: fft {a}, direct {b}");
        }
        // The edge lags must see zero padding, not the far side of the image: a circular
        // correlation at (0, 4) of a 12x9 image would add the pairs wrapping past column 8.
        assert!(slow[lags * (2 * lags + 1)].abs() > 1.0);
    }

    #[test]
    fn hand_computed_maps_and_distance() {
        // 2 x 4, one channel, lags 1.
        // A: a checkerboard, mean 0: every horizontal or vertical neighbour is opposite (-1),
        // every diagonal one equal (+1).
        let a = [1.0, -1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0];
        // B: two bright columns then two dark ones; minus its mean 0.5, +-0.5.
        // Lag 0: 8 * 0.25 / 8 = 0.25. (0, 1): per row 0.25 - 0.25 + 0.25, two rows, over 2 * 3
        // pairs: 1/12, so 1/3 of lag 0. (1, 0): 4 * 0.25 / 4 = 0.25: 1. (1, 1) and (1, -1): 0.25
        // over 3 pairs: 1/3. The map is symmetric: (dy, dx) equals (-dy, -dx).
        let b = [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        let (ma, mb) = (
            Autocorrelation::of(&a, 2, 4, 1, 1),
            Autocorrelation::of(&b, 2, 4, 1, 1),
        );
        let want_a = [[1.0, -1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, -1.0, 1.0]];
        let third = 1.0 / 3.0;
        let want_b = [
            [third, 1.0, third],
            [third, 1.0, third],
            [third, 1.0, third],
        ];
        for dy in -1..=1isize {
            for dx in -1..=1isize {
                let (i, j) = ((dy + 1) as usize, (dx + 1) as usize);
                assert!(
                    (ma.at(dy, dx) - want_a[i][j]).abs() < 1e-12,
                    "A ({dy}, {dx})"
                );
                assert!(
                    (mb.at(dy, dx) - want_b[i][j]).abs() < 1e-12,
                    "B ({dy}, {dx})"
                );
            }
        }
        // |A - B|: rows dy = -1 and 1: 2/3 + 2 + 2/3; dy = 0: 4/3 + 0 + 4/3. Sum 28/3 over 9.
        let want = 28.0 / 27.0;
        assert!(
            (ma.distance(&mb) - want).abs() < 1e-12,
            "{}",
            ma.distance(&mb)
        );
        assert!((mb.distance(&ma) - want).abs() < 1e-12);
        assert_eq!(ma.distance(&ma), 0.0);
    }

    #[test]
    fn luminance_weights_and_ignored_channels() {
        let (h, w) = (6, 8);
        let rgba: Vec<f32> = (0..h * w)
            .flat_map(|i| {
                let v = ((i * 37) % 11) as f32 / 11.0;
                [v, 1.0 - v, 0.5 * v, (i % 3) as f32]
            })
            .collect();
        let gray: Vec<f32> = rgba
            .chunks_exact(4)
            .map(|p| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2])
            .collect();
        let rgb: Vec<f32> = rgba
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        let gray_alpha: Vec<f32> = gray.iter().flat_map(|&g| [g, 0.3]).collect();
        let of = |v: &[f32], c: usize| Autocorrelation::of(v, h, w, c, 2);
        assert_eq!(of(&rgba, 4), of(&rgb, 3), "alpha is ignored");
        assert!(of(&rgb, 3).distance(&of(&gray, 1)) < 1e-6);
        assert_eq!(of(&gray_alpha, 2), of(&gray, 1), "gray and alpha: the gray");
    }

    #[test]
    fn a_constant_image_has_an_all_zero_map_and_no_nan() {
        let flat = vec![0.3f32; 10 * 10 * 3];
        let m = Autocorrelation::of(&flat, 10, 10, 3, 2);
        assert!(m.map.iter().all(|&v| v == 0.0));
        assert_eq!(structure_floor(&flat, 10, 10, 3), 0.0);
        // Lags past a small image's side have no pairs: zeros there, not NaN.
        let small = [0.0f32, 1.0, 1.0, 0.0];
        let m = Autocorrelation::of(&small, 2, 2, 1, 3);
        assert!(m.map.iter().all(|v| v.is_finite()));
        assert_eq!((m.at(2, 0), m.at(0, -3), m.at(0, 0)), (0.0, 0.0, 1.0));
    }

    /// Round blobs of radius `r` centred at `centres`, on a `size`-square image in [-1, 1].
    fn blobs(size: usize, r: f64, centres: &[(f64, f64)]) -> Vec<f32> {
        (0..size * size)
            .map(|i| {
                let (y, x) = ((i / size) as f64, (i % size) as f64);
                let near = centres
                    .iter()
                    .map(|&(cy, cx)| (y - cy).hypot(x - cx))
                    .fold(f64::MAX, f64::min);
                if near < r { 1.0 } else { -1.0 }
            })
            .collect()
    }

    /// Lattice points covering `size` (and a margin), `a` and `b` its basis, shifted by `shift`.
    fn lattice(size: usize, a: (f64, f64), b: (f64, f64), shift: (f64, f64)) -> Vec<(f64, f64)> {
        let n = 2 * size as i64;
        let mut points = Vec::new();
        for i in -n..n {
            for j in -n..n {
                let (y, x) = (
                    i as f64 * a.0 + j as f64 * b.0 + shift.0,
                    i as f64 * a.1 + j as f64 * b.1 + shift.1,
                );
                if (-10.0..size as f64 + 10.0).contains(&y)
                    && (-10.0..size as f64 + 10.0).contains(&x)
                {
                    points.push((y, x));
                }
            }
        }
        points
    }

    #[test]
    fn a_square_grid_is_far_from_a_hexagonal_lattice_and_a_shifted_copy_is_near() {
        let (size, spacing, r) = (96, 12.0, 3.5);
        let lags = structure_lags(size, size);
        let row = spacing * 3f64.sqrt() / 2.0;
        let hex = |shift| {
            blobs(
                size,
                r,
                &lattice(size, (row, spacing / 2.0), (0.0, spacing), shift),
            )
        };
        let square = blobs(
            size,
            r,
            &lattice(size, (spacing, 0.0), (0.0, spacing), (0.0, 0.0)),
        );
        let of = |v: &[f32]| Autocorrelation::of(v, size, size, 1, lags);
        let hexagonal = of(&hex((0.0, 0.0)));
        let shifted = hexagonal.distance(&of(&hex((4.3, 7.1))));
        let apart = hexagonal.distance(&of(&square));
        // Measured: a shifted copy 0.011 (its blobs fall on other pixels, its edges cut other
        // blobs), the square grid 0.28.
        assert!(shifted < 0.02, "shifted copy {shifted}");
        assert!(
            apart > 0.1 && apart > 10.0 * shifted,
            "square against hexagonal {apart}"
        );
        // The floor of a regular lattice is near 0 as well: its halves repeat the same way.
        assert!(structure_floor(&hex((0.0, 0.0)), size, size, 1) < 0.05);
    }

    #[test]
    fn fft_lengths_are_powers_of_two_and_long_enough() {
        assert_eq!(
            (fft_len(1), fft_len(7), fft_len(97), fft_len(320)),
            (1, 8, 128, 512)
        );
    }
}
