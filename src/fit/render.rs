//! Painting a fitted tile: any box of its infinite, exactly periodic plane, at any resolution
//! of the period, with stages faded out for a level of detail; streamed to image files.

use rayon::prelude::*;

use super::fused::{CHUNK, Stage};
use super::network::PeriodicNet;
use crate::error::Result;
use crate::maps::MapOutput;

/// How a tile is painted.
#[derive(Debug, Clone)]
pub struct TilePainter {
    pub net: PeriodicNet,
    /// Pixels per period `[rows, cols]` of the output (the photo's size paints it 1:1).
    pub resolution: [usize; 2],
    /// Level of detail in stages (`0..=stages`; the number of stages paints every stage).
    pub lod: f32,
    /// Where it runs: `None` for the fused CPU path, else a burn device.
    pub device: Option<burn::tensor::Device>,
}

impl TilePainter {
    /// Every stage, at the photo's resolution, on the CPU.
    pub fn new(net: PeriodicNet) -> Self {
        let resolution = net.shape.period;
        let lod = net.stages() as f32;
        Self {
            net,
            resolution,
            lod,
            device: None,
        }
    }

    /// The position in period pixels of output pixel `i` along `axis`, wrapped into one period
    /// (in f64, so pixels a whole number of periods apart get the same position, bit for bit).
    fn position(&self, i: i64, axis: usize) -> f32 {
        let period = self.net.shape.period[axis] as f64;
        let step = period / self.resolution[axis] as f64;
        ((i as f64 + 0.5) * step).rem_euclid(period) as f32
    }

    /// Renders the box of `[rows, cols]` pixels whose first pixel is `origin` (row, column).
    ///
    /// # Shapes
    /// - output: `[rows, cols, channels]`, row-major
    pub fn render(&self, origin: [i64; 2], [rows, cols]: [usize; 2]) -> Vec<f32> {
        let mut positions = Vec::with_capacity(rows * cols * 2);
        for y in 0..rows as i64 {
            let py = self.position(origin[0] + y, 0);
            for x in 0..cols as i64 {
                positions.extend([py, self.position(origin[1] + x, 1)]);
            }
        }
        self.eval(&positions)
    }

    /// The sum of the stages, each at its level-of-detail gain, at `positions` `[n, 2]`.
    pub fn eval(&self, positions: &[f32]) -> Vec<f32> {
        let shape = &self.net.shape;
        let c = shape.channels;
        let mut out = vec![0f32; positions.len() / 2 * c];
        for ((stage, params), gain) in shape
            .stages
            .iter()
            .zip(&self.net.params)
            .zip(self.net.lod_gains(self.lod))
        {
            if gain == 0.0 {
                continue;
            }
            let stage = Stage::new(stage, params, c, shape.omega0, shape.period);
            let values = match &self.device {
                None => {
                    let mut values = vec![0f32; out.len()];
                    positions
                        .par_chunks(2 * CHUNK * 8)
                        .zip(values.par_chunks_mut(CHUNK * 8 * c))
                        .for_each(|(p, v)| stage.eval(p, v, None));
                    values
                }
                Some(device) => positions
                    .chunks(2 << 16)
                    .flat_map(|p| super::reference::eval_values(&stage, p, device))
                    .collect(),
            };
            for (o, v) in out.iter_mut().zip(values) {
                *o += gain * v;
            }
        }
        out
    }

    /// Writes `[height, width]` pixels from `origin` to `outputs` (one image, or one per map of
    /// a map set), in bands of about `band_pixels`.
    pub fn write(
        &self,
        outputs: &[MapOutput],
        origin: [i64; 2],
        [height, width]: [usize; 2],
        band_pixels: usize,
    ) -> Result<()> {
        let bands = crate::maps::Bands {
            outputs,
            channels: self.net.shape.channels,
            size: [height, width],
            band_pixels,
            clamp: true,
        };
        bands.write(
            |row, rows| self.render([origin[0] + row as i64, origin[1]], [rows, width]),
            |_| {},
        )
    }
}
