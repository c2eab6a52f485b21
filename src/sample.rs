//! Coordinate grids: where each pixel sits in the generator's continuous coordinate space.
//!
//! A training crop of `crop` pixels spans 2 coordinate units, so at zoom 1 one pixel is
//! `2 / crop` units wide. Pixel `(y, x)` of the infinite plane has its centre at
//! `((y + 0.5) * spacing, (x + 0.5) * spacing)`; coordinates are ordered like array axes
//! (row first), as in the authors' code.

/// Maps integer pixel positions of the infinite plane to coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelGrid {
    /// Coordinate units per pixel.
    pub spacing: f64,
}

impl PixelGrid {
    /// The grid of a model trained on `crop`-pixel crops, magnified by `zoom`.
    pub fn new(crop: usize, zoom: f64) -> Self {
        Self {
            spacing: 2.0 / (crop as f64 * zoom),
        }
    }

    /// Coordinate of the centre of pixel index `i` along one axis.
    #[inline]
    pub fn coordinate(&self, i: i64) -> f32 {
        ((i as f64 + 0.5) * self.spacing) as f32
    }

    /// Writes the coordinates of `points` into `out` (`[count, axes]`).
    pub fn coordinates(&self, points: BoxPoints, out: &mut Vec<f32>) {
        let (origin, shape) = (points.origin, points.shape);
        let axes = shape.len();
        out.clear();
        out.reserve(points.count * axes);
        for flat in points.start..points.start + points.count {
            let mut rest = flat;
            let at = out.len();
            out.resize(at + axes, 0.0);
            for a in (0..axes).rev() {
                let i = rest % shape[a];
                rest /= shape[a];
                out[at + a] = self.coordinate(origin[a] + i as i64);
            }
        }
    }
}

/// `count` consecutive points of the box of `shape` whose first pixel is `origin` (both in
/// array order, 2 or 3 axes), from flat index `start` (row-major).
#[derive(Debug, Clone, Copy)]
pub struct BoxPoints<'a> {
    pub origin: &'a [i64],
    pub shape: &'a [usize],
    pub start: usize,
    pub count: usize,
}

/// A training crop's grid: pixel `i` of a `crop`-pixel crop lies at `-1 + (i + 0.5) * 2 / crop`
/// (the crop spans [-1, 1]), moved by the sample's random `shift`. This is [`PixelGrid`] at
/// zoom 1 with its origin at the crop's centre, computed in f32 as training always has.
pub fn crop_coordinate(crop: usize, i: usize, shift: f32) -> f32 {
    let step = 2.0 / crop as f32;
    -1.0 + (i as f32 + 0.5) * step + shift
}

/// Point `i` of a training crop painted every `stride`-th pixel (the coarse critic's): pixel
/// `i · stride` of a crop of `crop · stride` pixels, which spans `2 · stride` units, moved by
/// the sample's random `shift`. With `stride` 1 this is [`crop_coordinate`].
pub fn strided_crop_coordinate(crop: usize, stride: usize, i: usize, shift: f32) -> f32 {
    let step = 2.0 / crop as f32;
    -(stride as f32) + ((i * stride) as f32 + 0.5) * step + shift
}
