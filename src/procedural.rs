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

/// Height units to pixels for [`material`]'s normals: a height step of 1 over one pixel tilts
/// the normal 45° times this.
pub const MATERIAL_RELIEF: f32 = 8.0;

/// A material map set: rounded pillows of period `period` pixels on both axes, each pillow
/// with its own height, colour and roughness.
///
/// Returns `[albedo (3 ch), normal (3 ch, (n + 1) / 2), roughness (1 ch), height (1 ch)]`, each
/// `[height, width, channels]` in [0, 1]. The normals are the height field's true normals:
/// `n = normalize(-MATERIAL_RELIEF * dh/dx, -MATERIAL_RELIEF * dh/dy, 1)` with `x` along columns
/// and `y` along rows (down), from the analytic derivative.
pub fn material(width: usize, height: usize, period: usize) -> [Vec<f32>; 4] {
    let p = period as f32;
    let pi = std::f32::consts::PI;
    let mut maps: [Vec<f32>; 4] = Default::default();
    for y in 0..height {
        for x in 0..width {
            let (cx, cy) = ((x / period) as i64, (y / period) as i64);
            let amp = 0.55 + 0.45 * noise(23, cx % 4, cy % 4);
            let (fx, fy) = ((x as f32 + 0.5) / p, (y as f32 + 0.5) / p);
            let (sx, sy) = ((pi * fx).sin(), (pi * fy).sin());
            let h = amp * sx * sx * sy * sy;
            // d/dx sin²(pi x / P) = (pi / P) sin(2 pi x / P).
            let dhdx = amp * (pi / p) * (2.0 * pi * fx).sin() * sy * sy;
            let dhdy = amp * (pi / p) * (2.0 * pi * fy).sin() * sx * sx;
            let n = [-MATERIAL_RELIEF * dhdx, -MATERIAL_RELIEF * dhdy, 1.0];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let tint = noise(29, cx % 4, cy % 4);
            let low = [0.30, 0.22, 0.16];
            let high = [0.85, 0.70 + 0.1 * tint, 0.45 + 0.2 * tint];
            for c in 0..3 {
                maps[0].push(low[c] + (high[c] - low[c]) * h);
                maps[1].push((n[c] / len + 1.0) * 0.5);
            }
            maps[2].push(0.9 - 0.6 * h);
            maps[3].push(h);
        }
    }
    maps
}

/// The names of [`material`]'s maps, in order, and their channel counts.
pub const MATERIAL_MAPS: [(&str, usize); 4] = [
    ("albedo", 3),
    ("normal", 3),
    ("roughness", 1),
    ("height", 1),
];

/// How well a normal map matches the normals of a height map: the mean cosine between the two
/// over the interior pixels, with the height map's normals from central differences and
/// [`MATERIAL_RELIEF`]. Both maps in [0, 1], `[h, w, 3]` and `[h, w, 1]`.
pub fn normal_agreement(normal: &[f32], height: &[f32], width: usize, rows: usize) -> f64 {
    let mut sum = 0.0f64;
    let mut count = 0usize;
    for y in 1..rows - 1 {
        for x in 1..width - 1 {
            let h = |yy: usize, xx: usize| height[yy * width + xx];
            let dhdx = (h(y, x + 1) - h(y, x - 1)) * 0.5;
            let dhdy = (h(y + 1, x) - h(y - 1, x)) * 0.5;
            let a = [-MATERIAL_RELIEF * dhdx, -MATERIAL_RELIEF * dhdy, 1.0];
            let at = (y * width + x) * 3;
            let b = [
                normal[at] * 2.0 - 1.0,
                normal[at + 1] * 2.0 - 1.0,
                normal[at + 2] * 2.0 - 1.0,
            ];
            let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            let lb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
            if la > 0.0 && lb > 0.0 {
                sum += (dot / (la * lb)) as f64;
                count += 1;
            }
        }
    }
    sum / count.max(1) as f64
}

/// Directional stripes: vertical stripes of period `period` pixels whose bright part grows from
/// `duty0` of the period at the left edge to `duty1` at the right, so the image brightens from
/// left to right. An exemplar for guided training (`--guide x`).
pub fn graded_stripes(
    width: usize,
    height: usize,
    period: f32,
    duty0: f32,
    duty1: f32,
) -> Vec<f32> {
    let mut out = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        for x in 0..width {
            let xf = x as f32 + 0.5;
            let duty = duty0 + (duty1 - duty0) * xf / width as f32;
            // Distance (pixels) inside the bright part of the period, soft over one pixel.
            let t = (xf / period).fract() * period;
            let inside = (duty * period - t).min(t).min(period - t + 0.0);
            let v = (inside + 0.5).clamp(0.0, 1.0);
            let grain = 0.04 * (noise(31, x as i64, y as i64) - 0.5);
            out.push((0.15 + 0.7 * v + grain).clamp(0.0, 1.0));
            out.push((0.25 + 0.5 * v + grain).clamp(0.0, 1.0));
            out.push((0.55 - 0.3 * v + grain).clamp(0.0, 1.0));
        }
    }
    out
}

/// A signed-distance volume of a gyroid sheet (a porous, triply periodic surface): `n` voxels
/// per side, period `period` voxels, sheet half-thickness `thickness` (in units of the gyroid
/// function). Row-major `[n, n, n]` (z, y, x); negative inside the sheet. Distances are a
/// first-order estimate (`(|f| - t) / |grad f|`) in units of the volume's side, so the
/// authors' `sdf_scale` of 10 truncates at a tenth of the side.
pub fn gyroid_sdf(n: usize, period: f32, thickness: f32) -> Vec<f32> {
    graded_gyroid_sdf(n, period, thickness, thickness)
}

/// [`gyroid_sdf`] whose sheet thickens along x, from `from` at the first column to `to` at the
/// last: porosity and density (mean |sdf|) change across the volume, for density control.
pub fn graded_gyroid_sdf(n: usize, period: f32, from: f32, to: f32) -> Vec<f32> {
    let k = std::f32::consts::TAU / period;
    let mut out = Vec::with_capacity(n * n * n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let (a, b, c) = (
                    k * (x as f32 + 0.5),
                    k * (y as f32 + 0.5),
                    k * (z as f32 + 0.5),
                );
                let f = a.sin() * b.cos() + b.sin() * c.cos() + c.sin() * a.cos();
                let grad = [
                    a.cos() * b.cos() - c.sin() * a.sin(),
                    -a.sin() * b.sin() + b.cos() * c.cos(),
                    -b.sin() * c.sin() + c.cos() * a.cos(),
                ];
                let norm = (grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2])
                    .sqrt()
                    .max(0.5)
                    * k;
                let t = from + (to - from) * x as f32 / (n.max(2) - 1) as f32;
                out.push((f.abs() - t) / norm / n as f32);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_normals_are_the_height_fields_normals() {
        let (w, h) = (96, 64);
        let [_, normal, _, height] = material(w, h, 32);
        // Central differences agree with the analytic normals up to discretisation.
        let agreement = normal_agreement(&normal, &height, w, h);
        assert!(agreement > 0.999, "{agreement}");
        // And a flat normal map does not.
        let flat: Vec<f32> = (0..w * h).flat_map(|_| [0.5, 0.5, 1.0]).collect();
        assert!(normal_agreement(&flat, &height, w, h) < agreement - 0.02);
    }
}
