//! Procedural exemplars drawn by our own code, with known periods, for users and tests
//! (`ipfn draw`). All return `[height, width, 3]` RGB values in [0, 1].

use crate::latent::mix64;

/// Hash-based value in [0, 1) for integer coordinates: per-brick and per-thread variation.
fn noise(seed: u64, a: i64, b: i64) -> f32 {
    (mix64(seed ^ mix64((a as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (b as u64))) >> 40) as f32
        / 16_777_216.0
}

/// Running bond brickwork: bricks `brick_w x brick_h` pixels (mortar included), every other row
/// offset by half a brick. Period: `brick_w` across, `2 * brick_h` down.
pub fn bricks(width: usize, height: usize, brick_w: usize, brick_h: usize) -> Vec<f32> {
    let mortar = 2.0f32;
    let mut out = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        let row = y / brick_h;
        let shift = if row % 2 == 1 { brick_w / 2 } else { 0 };
        for x in 0..width {
            let xs = (x + shift) % brick_w;
            let col = (x + shift) / brick_w;
            let (dx, dy) = (xs as f32 + 0.5, (y % brick_h) as f32 + 0.5);
            let edge = dx.min(brick_w as f32 - dx).min(dy).min(brick_h as f32 - dy);
            // Soft mortar edge, brick colour varying per brick (by position in the period).
            let t = ((edge - mortar) / 1.5).clamp(0.0, 1.0);
            let tone = 0.85 + 0.15 * noise(7, (col % 2) as i64, (row % 2) as i64);
            let grain = 0.06 * (noise(11, x as i64, y as i64) - 0.5);
            let brick = [
                0.62 * tone + grain,
                0.27 * tone + grain,
                0.18 * tone + grain,
            ];
            let mortar_c = [0.78 + grain, 0.76 + grain, 0.72 + grain];
            for c in 0..3 {
                out.push((mortar_c[c] * (1.0 - t) + brick[c] * t).clamp(0.0, 1.0));
            }
        }
    }
    out
}

/// A plain weave: horizontal and vertical threads alternating over and under, thread pitch
/// `pitch` pixels. Period: `2 * pitch` on both axes.
pub fn weave(width: usize, height: usize, pitch: usize) -> Vec<f32> {
    let p = pitch as f32;
    let mut out = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        for x in 0..width {
            let (cx, cy) = (x / pitch, y / pitch);
            let (fx, fy) = ((x % pitch) as f32 + 0.5, (y % pitch) as f32 + 0.5);
            let horizontal_on_top = (cx + cy) % 2 == 0;
            // Thread cross-section shading: bright in the middle of a thread, dark at its edges.
            let (along, across) = if horizontal_on_top {
                (fx, fy)
            } else {
                (fy, fx)
            };
            let profile = (std::f32::consts::PI * across / p).sin();
            let dip = 0.75 + 0.25 * (std::f32::consts::PI * along / p).sin();
            let shade = (profile * dip).clamp(0.0, 1.0);
            let warm = if horizontal_on_top {
                [0.86, 0.72, 0.46]
            } else {
                [0.55, 0.38, 0.22]
            };
            let fibre = 0.05 * (noise(3, x as i64, y as i64) - 0.5);
            for c in warm {
                out.push((0.12 + c * shade + fibre).clamp(0.0, 1.0));
            }
        }
    }
    out
}

/// Vertical stripes of period `period` pixels (a soft sine profile): the simplest pattern with a
/// known period, for tests of the learned K.
pub fn stripes(width: usize, height: usize, period: f32) -> Vec<f32> {
    let mut out = Vec::with_capacity(width * height * 3);
    for _ in 0..height {
        for x in 0..width {
            let v = 0.5 + 0.45 * (2.0 * std::f32::consts::PI * (x as f32 + 0.5) / period).sin();
            out.extend([v, 0.3 + 0.4 * v, 1.0 - v]);
        }
    }
    out
}
