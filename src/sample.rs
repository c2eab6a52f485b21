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

    /// Writes the `(row, col)` coordinates of `count` consecutive pixels of a `width`-wide region
    /// whose top-left pixel is `(y0, x0)`, starting at flat index `start` (row-major), into
    /// `out` (`[count, 2]`).
    pub fn region_coordinates(
        &self,
        y0: i64,
        x0: i64,
        width: usize,
        start: usize,
        count: usize,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        out.reserve(count * 2);
        for flat in start..start + count {
            let (row, col) = ((flat / width) as i64, (flat % width) as i64);
            out.push(self.coordinate(y0 + row));
            out.push(self.coordinate(x0 + col));
        }
    }

    /// Writes the `(depth, row, col)` coordinates of `count` consecutive voxels of a
    /// `height x width` box whose first voxel is `(z0, y0, x0)`, starting at flat index `start`
    /// (row-major), into `out` (`[count, 3]`).
    #[allow(clippy::too_many_arguments)]
    pub fn box_coordinates(
        &self,
        origin: [i64; 3],
        height: usize,
        width: usize,
        start: usize,
        count: usize,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        out.reserve(count * 3);
        for flat in start..start + count {
            let plane = height * width;
            let (d, r, c) = (flat / plane, (flat % plane) / width, flat % width);
            out.push(self.coordinate(origin[0] + d as i64));
            out.push(self.coordinate(origin[1] + r as i64));
            out.push(self.coordinate(origin[2] + c as i64));
        }
    }
}
