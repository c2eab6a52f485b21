//! Diversity: a generated crop must depend on its latent field as much as the exemplar's crops
//! differ from one another.
//!
//! The critic judges one crop at a time, and on a photo with no clear period its crops are
//! shorter than the period the generator learns. A generator that ignores its latent field and
//! paints one tile over and over then looks real crop by crop, and its samples are a grid (a
//! repeat strength far above the photo's own: the book's photographs experiment).
//! With `diversity = w`, each generator step also paints every crop's twin, the same
//! coordinates under a fresh latent field, and adds
//!
//! `w · mean_s max(0, T - ||a_s - b_s||)`
//!
//! to the generator's loss, where `||a_s - b_s||` is the L2 distance between crop `s` and its
//! twin over the exemplar's channels, and `T` the mean distance between two random crops of the
//! exemplar ([`Trainer::diversity_target`]). A hinge, not a reward: twins as different as two
//! crops of the exemplar are left to the critic. Its gradient has norm `w` per crop, as the
//! critic's has about 1 under the gradient penalty, so `w = 1` weighs the two alike. (Mode
//! seeking, Mao et al. 2019, rewards the ratio of output to latent distance without a bound.)

use super::Trainer;
use super::draws::stream;

/// Pairs of the exemplar's crops averaged for the target distance.
pub const TARGET_PAIRS: usize = 64;

impl Trainer {
    /// `T`: the mean L2 distance, over the exemplar's channels, between two random crops of the
    /// exemplar at the working scale ([`TARGET_PAIRS`] pairs from their own random stream, so
    /// the same run always has the same target). Measured once, on first use.
    pub fn diversity_target(&self) -> f32 {
        *self
            .diversity_target
            .get_or_init(|| self.measure_diversity_target())
    }

    fn measure_diversity_target(&self) -> f32 {
        let crop = |pair: usize, side: u64| -> Vec<f32> {
            let origin = self.crop_origin(stream::DIVERSITY, pair, &[side], 1);
            self.crop_rows(&origin, 1)
                .flat_map(|row| row.iter().copied())
                .collect::<Vec<f32>>()
        };
        let total: f64 = (0..TARGET_PAIRS)
            .map(|pair| {
                let (a, b) = (crop(pair, 0), crop(pair, 1));
                let squared: f32 = a.iter().zip(&b).map(|(a, b)| (a - b) * (a - b)).sum();
                squared.sqrt() as f64
            })
            .sum();
        (total / TARGET_PAIRS as f64) as f32
    }
}

/// The hinge's value and its gradient with respect to both crops of each pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Hinge {
    /// `w · mean_s max(0, T - ||a_s - b_s||)`.
    pub loss: f32,
    /// `d loss / d a` and `d loss / d b`, point-major: `[batch · points, channels]`.
    pub d_a: Vec<f32>,
    pub d_b: Vec<f32>,
}

/// The diversity hinge between crops `a` and their twins `b`, both planar
/// `[batch, channels_in, points]` as the critic takes them; only the first `channels` of
/// `channels_in` (the exemplar's, not a condition) count.
pub fn hinge(
    a: &[f32],
    b: &[f32],
    [batch, channels_in, points]: [usize; 3],
    channels: usize,
    target: f32,
    weight: f32,
) -> Hinge {
    debug_assert_eq!(a.len(), batch * channels_in * points);
    let mut out = Hinge {
        loss: 0.0,
        d_a: vec![0.0; batch * points * channels],
        d_b: vec![0.0; batch * points * channels],
    };
    for s in 0..batch {
        let crop = |x: &[f32], ch: usize| {
            let at = (s * channels_in + ch) * points;
            x[at..at + points].to_vec()
        };
        let diff: Vec<Vec<f32>> = (0..channels)
            .map(|ch| {
                let (a, b) = (crop(a, ch), crop(b, ch));
                a.iter().zip(&b).map(|(a, b)| a - b).collect()
            })
            .collect();
        let distance = diff.iter().flatten().map(|d| d * d).sum::<f32>().sqrt();
        if distance >= target {
            continue;
        }
        out.loss += weight * (target - distance) / batch as f32;
        // d/da of -w/batch · ||a - b||: -w/batch · (a - b) / ||a - b||; d/db is its negation.
        let scale = -weight / batch as f32 / distance.max(1e-12);
        for (ch, diff) in diff.iter().enumerate() {
            for (q, d) in diff.iter().enumerate() {
                let at = (s * points + q) * channels + ch;
                out.d_a[at] = scale * d;
                out.d_b[at] = -scale * d;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hinge_pushes_twins_apart_until_the_target_and_no_further() {
        // Two samples of 2 channels and 3 points, then a condition channel that must not count.
        let shape = [2, 3, 3];
        let a = vec![
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 9.0, 9.0, 9.0, // sample 0
            1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 9.0, 9.0, 9.0, // sample 1
        ];
        let mut b = a.clone();
        b[0] = 0.6; // sample 0: distance 0.6, under the target 1
        b[1] = 0.8; // now (0.6, 0.8): distance 1.0, at the target: no loss, no gradient
        b[15] = -5.0; // the condition differs too: ignored
        b[9] = 0.5; // sample 1: distance 0.5
        let h = hinge(&a, &b, shape, 2, 1.0, 2.0);
        assert!((h.loss - 2.0 * 0.5 / 2.0).abs() < 1e-6, "{h:?}");
        assert!(h.d_a[..6].iter().all(|&g| g == 0.0), "{h:?}");
        // Sample 1, point 0, channel 0: -w/batch · (a - b)/|a - b| = -1 · 0.5/0.5.
        assert!(
            (h.d_a[6] + 1.0).abs() < 1e-6 && (h.d_b[6] - 1.0).abs() < 1e-6,
            "{h:?}"
        );
        assert_eq!(h.d_a[7..].iter().filter(|&&g| g != 0.0).count(), 0);
    }

    #[test]
    fn the_gradient_matches_differences() {
        let shape = [1, 1, 4];
        let a = [0.1f32, -0.2, 0.3, 0.05];
        let b = [0.0f32, 0.1, 0.1, -0.1];
        let h = hinge(&a, &b, shape, 1, 2.0, 1.5);
        for q in 0..4 {
            let mut up = a;
            up[q] += 1e-3;
            let mut down = a;
            down[q] -= 1e-3;
            let numeric = (hinge(&up, &b, shape, 1, 2.0, 1.5).loss
                - hinge(&down, &b, shape, 1, 2.0, 1.5).loss)
                / 2e-3;
            assert!(
                (numeric - h.d_a[q]).abs() < 1e-2,
                "{q}: {numeric} vs {}",
                h.d_a[q]
            );
        }
    }
}
