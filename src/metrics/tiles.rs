//! What a tile and a pattern measure: the seam score of tiles laid side by side, and the
//! dominant period of an image along each axis.

use crate::error::Result;
use crate::input_error;

/// How visible the wrap seams of a tile are.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SeamScore {
    /// Across the vertical seam (last column to first).
    pub columns: f64,
    /// Across the horizontal seam (last row to first).
    pub rows: f64,
    /// Both seams together.
    pub overall: f64,
}

/// Lines on each side of a seam whose steps form the interior it is compared with. Comparing
/// with the whole interior instead would measure where the seam falls in the pattern's period
/// (a periodic pattern's gradient changes with its phase), not whether it shows.
pub const SEAM_BAND: usize = 8;

/// The seam score of a tile `[height, width, channels]` laid 2x2 (so it wraps onto itself):
/// the mean absolute step across each wrap seam over the mean step between the neighbouring
/// lines (up to [`SEAM_BAND`] on each side, inside the tile).
///
/// One tile's score depends on where its seam falls in the pattern: across the lines of a
/// seamless honeycomb tile it ranges from about 0.7 to 1.5 (5th to 95th percentile), while a wrap
/// that does not tile scores 4 to 5. [`seam_score_of_tiles`] averages over tiles cut at
/// different phases.
pub fn seam_score(tile: &[f32], height: usize, width: usize, channels: usize) -> Result<SeamScore> {
    seam_score_of_tiles(&[tile], height, width, channels)
}

/// The seam score of several tiles of one size together: summed seam steps over summed
/// interior steps.
pub fn seam_score_of_tiles(
    tiles: &[&[f32]],
    height: usize,
    width: usize,
    channels: usize,
) -> Result<SeamScore> {
    if height < 4 || width < 4 {
        return Err(input_error!(
            "a {width}x{height} tile is too small for a seam score (at least 4x4)"
        ));
    }
    let (mut seam_c, mut inner_c, mut seam_r, mut inner_r) = (0.0, 0.0, 0.0, 0.0);
    for tile in tiles {
        let shape = [height, width, channels];
        let col_step = |x0: usize, x1: usize| column_step(tile, shape, x0, x1);
        let row_step = |y0: usize, y1: usize| row_step(tile, shape, y0, y1);
        // (seam step, mean step of the lines beside it) along an axis of length n.
        let measure = |n: usize, step: &dyn Fn(usize, usize) -> f64| -> (f64, f64) {
            let band = SEAM_BAND.min((n - 2) / 2);
            let inner: f64 = (0..band)
                .map(|i| step(i, i + 1) + step(n - 2 - i, n - 1 - i))
                .sum::<f64>()
                / (2 * band) as f64;
            (step(n - 1, 0), inner)
        };
        let (s, i) = measure(width, &col_step);
        seam_c += s;
        inner_c += i;
        let (s, i) = measure(height, &row_step);
        seam_r += s;
        inner_r += i;
    }
    let ratio = |seam: f64, inner: f64| {
        if inner > 0.0 {
            seam / inner
        } else if seam > 0.0 {
            f64::INFINITY
        } else {
            1.0
        }
    };
    Ok(SeamScore {
        columns: ratio(seam_c, inner_c),
        rows: ratio(seam_r, inner_r),
        overall: ratio(seam_c + seam_r, inner_c + inner_r),
    })
}

/// How the seam score spreads over an image's own lines: the 5th percentile, the median and the
/// 95th percentile.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ScoreSpread {
    pub p5: f64,
    pub median: f64,
    pub p95: f64,
}

impl ScoreSpread {
    /// Whether `score` lies between the 5th and the 95th percentile.
    pub fn holds(&self, score: f64) -> bool {
        (self.p5..=self.p95).contains(&score)
    }
}

/// The seam score an image's own lines get: every pair of neighbouring columns inside
/// `[height, width, channels]` (with [`SEAM_BAND`] lines on each side) scored as if it were the
/// vertical seam, every pair of neighbouring rows as the horizontal one, and `overall` over every
/// (column pair, row pair) combination (every few row pairs past a million), as
/// [`seam_score`] pools its two seams.
///
/// A line inside a photo is no seam at all, so this is the range a seamless tile of the photo's
/// content scores in: one tile's score depends on what its seam happens to cross (on DTD's
/// `brick.jpg`, 5% of its own lines score below 0.70 and 5% above 1.46). `None` for an image
/// with fewer than `2 * SEAM_BAND + 2` lines along an axis.
pub fn line_score_spread(
    image: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> Option<ScoreSpread> {
    let shape = [height, width, channels];
    // Mean absolute step across each boundary between neighbouring lines.
    let col_steps: Vec<f64> = (1..width)
        .map(|x| column_step(image, shape, x - 1, x))
        .collect();
    let row_steps: Vec<f64> = (1..height)
        .map(|y| row_step(image, shape, y - 1, y))
        .collect();
    // (step, mean step of the SEAM_BAND boundaries on each side) per inner boundary.
    let pairs = |steps: &[f64]| -> Vec<(f64, f64)> {
        (SEAM_BAND..steps.len().saturating_sub(SEAM_BAND))
            .map(|k| {
                let side: f64 = steps[k - SEAM_BAND..k].iter().sum::<f64>()
                    + steps[k + 1..=k + SEAM_BAND].iter().sum::<f64>();
                (steps[k], side / (2 * SEAM_BAND) as f64)
            })
            .collect()
    };
    let (cols, rows) = (pairs(&col_steps), pairs(&row_steps));
    // At most about a million combinations: every `stride`-th row pair with each column pair.
    let stride = (cols.len() * rows.len()).div_ceil(1 << 20).max(1);
    let mut scores: Vec<f64> = cols
        .iter()
        .flat_map(|&(sc, ic)| {
            rows.iter()
                .step_by(stride)
                .map(move |&(sr, ir)| (sc + sr) / (ic + ir))
        })
        .filter(|v| v.is_finite())
        .collect();
    if scores.is_empty() {
        return None;
    }
    scores.sort_by(f64::total_cmp);
    let q = |p: f64| scores[((scores.len() - 1) as f64 * p).round() as usize];
    Some(ScoreSpread {
        p5: q(0.05),
        median: q(0.5),
        p95: q(0.95),
    })
}

/// Mean absolute step from column `x0` to column `x1` of `image` `[height, width, channels]`,
/// over its rows and channels.
fn column_step(image: &[f32], [height, width, channels]: [usize; 3], x0: usize, x1: usize) -> f64 {
    let at = |y: usize, x: usize, c: usize| image[(y * width + x) * channels + c] as f64;
    let mut s = 0.0;
    for y in 0..height {
        for c in 0..channels {
            s += (at(y, x1, c) - at(y, x0, c)).abs();
        }
    }
    s / (height * channels) as f64
}

/// Mean absolute step from row `y0` to row `y1`, over its columns and channels.
fn row_step(image: &[f32], [_, width, channels]: [usize; 3], y0: usize, y1: usize) -> f64 {
    let line = |y: usize| &image[y * width * channels..(y + 1) * width * channels];
    let s: f64 = line(y0)
        .iter()
        .zip(line(y1))
        .map(|(a, b)| (*b as f64 - *a as f64).abs())
        .sum();
    s / (width * channels) as f64
}

/// A repeat of an image along one axis, from its autocorrelation.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Repeat {
    /// The lag of the autocorrelation's peak, in pixels, refined to a fraction of a pixel.
    pub period: f64,
    /// The autocorrelation at that lag over its value at lag 0: 1 where the image repeats
    /// exactly, near 0 where the "peak" is only noise (a stochastic texture's).
    pub strength: f64,
}

/// The strongest repeat along rows (vertical, `[0]`) and columns (horizontal, `[1]`) of an image
/// `[height, width, channels]`: the lag of the first autocorrelation peak after the first
/// minimum whose prominence reaches 70% of the most prominent peak's, for lags up to half the
/// side, refined to a fraction of a pixel by a parabola. `None` where there is no such peak.
///
/// Prominence, not height: where something else correlates at every lag (a brick wall's
/// courses, along the courses), the whole profile stands high, and a ripple on it can be
/// nearly as high as the bricks' own peak.
pub fn repeats(
    values: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> [Option<Repeat>; 2] {
    let gray = centred_luminance(values, channels);
    let g = |y: usize, x: usize| gray[y * width + x];
    // Normalised autocorrelation along one axis, averaged over the other.
    let along = |len: usize, other: usize, pick: &dyn Fn(usize, usize) -> f64| -> Option<Repeat> {
        let max_lag = len / 2;
        if max_lag < 3 {
            return None;
        }
        let r: Vec<f64> = (0..=max_lag)
            .map(|lag| {
                let mut s = 0.0;
                for o in 0..other {
                    for i in 0..len - lag {
                        s += pick(o, i) * pick(o, i + lag);
                    }
                }
                s / ((len - lag) * other) as f64
            })
            .collect();
        // No variance, or none that changes along this axis (rows of a vertical stripe): any
        // lag is a "period", so none is.
        if r[0] <= 0.0 || r.iter().all(|&v| (r[0] - v).abs() <= 1e-9 * r[0]) {
            return None;
        }
        let peak = clear_peak(&r)?;
        // Parabolic refinement of the peak's lag.
        let (a, b, c) = (r[peak - 1], r[peak], r[peak + 1]);
        let denom = a - 2.0 * b + c;
        let shift = if denom.abs() > 1e-12 {
            (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        Some(Repeat {
            period: peak as f64 + shift,
            strength: b / r[0],
        })
    };
    [
        along(height, width, &|x, y| g(y, x)),
        along(width, height, &|y, x| g(y, x)),
    ]
}

/// The lag of the first peak of an autocorrelation profile `r` (`r[lag]`, lag 0 first) after its
/// first minimum whose prominence reaches 70% of the most prominent peak's; `None` without one.
fn clear_peak(r: &[f64]) -> Option<usize> {
    let max_lag = r.len() - 1;
    let first_min = (1..max_lag).find(|&l| r[l] <= r[l - 1] && r[l] <= r[l + 1])?;
    let peaks: Vec<usize> = (first_min + 1..max_lag)
        .filter(|&l| r[l] > r[l - 1] && r[l] >= r[l + 1] && r[l] > 0.0)
        .collect();
    let prominence: Vec<f64> = peaks
        .iter()
        .map(|&l| peak_prominence(&r[first_min..], l - first_min))
        .collect();
    let highest = prominence.iter().copied().fold(0.0, f64::max);
    // The first peak nearly as prominent as the most: a non-integer period's multiples can
    // land closer to whole lags and so stand slightly higher than the period itself.
    Some(peaks[prominence.iter().position(|&p| p >= 0.7 * highest)?])
}

/// How far `r[at]`, a local peak, stands above the higher of the lowest points on either side
/// before the profile rises above it again (or ends): the peak's topographic prominence.
fn peak_prominence(r: &[f64], at: usize) -> f64 {
    let base = |side: &mut dyn Iterator<Item = &f64>| {
        side.take_while(|&&v| v <= r[at])
            .fold(r[at], |low, &v| low.min(v))
    };
    let left = base(&mut r[..at].iter().rev());
    let right = base(&mut r[at + 1..].iter());
    r[at] - left.max(right)
}

/// The mean over channels of each pixel, with the image's mean removed.
fn centred_luminance(values: &[f32], channels: usize) -> Vec<f64> {
    let gray: Vec<f64> = values
        .chunks_exact(channels)
        .map(|p| p.iter().map(|&v| v as f64).sum::<f64>() / channels as f64)
        .collect();
    let mean = gray.iter().sum::<f64>() / gray.len().max(1) as f64;
    gray.into_iter().map(|v| v - mean).collect()
}

/// The autocorrelation of an image `[height, width, channels]`'s luminance at the lag
/// `[down, across]` (pixels), over its value at lag 0: each product averaged over the pixels
/// the shifted image still overlaps. 0 where the lag leaves no overlap or the image is flat.
pub fn autocorrelation_at(
    values: &[f32],
    [height, width, channels]: [usize; 3],
    [down, across]: [usize; 2],
) -> f64 {
    if down >= height || across >= width {
        return 0.0;
    }
    let gray = centred_luminance(values, channels);
    let mean_product = |dy: usize, dx: usize| {
        let mut sum = 0.0;
        for y in 0..height - dy {
            let (a, b) = (&gray[y * width..], &gray[(y + dy) * width + dx..]);
            sum += (0..width - dx).map(|x| a[x] * b[x]).sum::<f64>();
        }
        sum / ((height - dy) * (width - dx)) as f64
    };
    let zero = mean_product(0, 0);
    if zero <= 0.0 {
        return 0.0;
    }
    mean_product(down, across) / zero
}

/// The dominant period (pixels) along rows and columns: the lag of [`repeats`], however weak.
pub fn dominant_period(
    values: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> [Option<f64>; 2] {
    repeats(values, height, width, channels).map(|r| r.map(|r| r.period))
}

#[cfg(test)]
mod tests {
    use super::{autocorrelation_at, clear_peak};

    /// Hand-made profiles. Along a brick wall's courses the whole profile stands high, and a
    /// ripple on it (lag 3) is higher than 70% of the bricks' own peak (lag 6): by height it
    /// would be the period, by prominence (0.02 against 0.2) it is not.
    #[test]
    fn the_period_is_the_prominent_peak_not_a_ripple_on_a_high_profile() {
        let on_a_plateau = [1.0, 0.6, 0.5, 0.52, 0.5, 0.5, 0.7, 0.5, 0.5];
        assert_eq!(clear_peak(&on_a_plateau), Some(6));
        // Two peaks of nearly equal prominence: the first is the period, the second its
        // multiple, even where the multiple stands higher.
        let multiples = [1.0, 0.0, 0.8, 0.0, 0.85, 0.0, 0.0];
        assert_eq!(clear_peak(&multiples), Some(2));
        // No minimum, or no peak after it: no period.
        assert_eq!(clear_peak(&[1.0, 0.8, 0.6, 0.4]), None);
        assert_eq!(clear_peak(&[1.0, 0.5, 0.4, 0.3, 0.3]), None);
    }

    /// Hand-computed: columns alternating 1, -1 (mean 0) give -1 one column over, 1 two over;
    /// rows are alike, so any lag down keeps the columns' value.
    #[test]
    fn autocorrelation_at_a_lag_over_its_value_at_zero() {
        let row = [1.0f32, -1.0, 1.0, -1.0];
        let image: Vec<f32> = row.iter().copied().cycle().take(12).collect();
        let at = |lag| autocorrelation_at(&image, [3, 4, 1], lag);
        assert!((at([0, 1]) + 1.0).abs() < 1e-12);
        assert!((at([0, 2]) - 1.0).abs() < 1e-12);
        assert!((at([2, 1]) + 1.0).abs() < 1e-12);
        // No overlap left, or a flat image: 0.
        assert_eq!(at([0, 4]), 0.0);
        assert_eq!(autocorrelation_at(&[0.5; 12], [3, 4, 1], [0, 1]), 0.0);
    }
}
