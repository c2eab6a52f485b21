//! A prepared synthesis over 2 or 3 axes: renders any box of the infinite plane or volume, and
//! streams images (row bands), map sets and volumes (depth slabs, with a mesh) to disk.

use std::path::Path;

use super::engine::{Engine, paint_fused};
use super::tile::TileAdjustment;
use crate::condition::Condition;
use crate::error::Result;
use crate::generator::fused::CHUNK_POINTS;
use crate::io::OutputFormat;
use crate::io::shard::Shard;
use crate::io::zarr::{ZarrReport, ZarrWriter};
use crate::latent::LatentField;
use crate::maps::MapOutput;
use crate::sample::{BoxPoints, PixelGrid};

/// Default band size for [`Painter::write_image`] and volume slabs: 1 Mi pixels (12 MiB of RGB
/// floats).
pub const DEFAULT_BAND_PIXELS: usize = 1 << 20;

/// A prepared synthesis: renders boxes of the plane (2D models) or volume (3D models).
pub struct Painter {
    pub(super) engine: Engine,
    pub(super) field: LatentField,
    pub(super) latent_scale: Vec<f32>,
    pub(super) grid: PixelGrid,
    /// The output's first pixel in the infinite plane or volume (array order).
    pub(super) offset: Vec<i64>,
    pub(super) channels: usize,
    pub(super) tile: Option<TileAdjustment>,
    pub(super) mirror: Option<[usize; 2]>,
    pub(super) condition: Option<Condition>,
}

/// Where pixel `i` of a mirror tile of `n` pixels takes its value: the tile repeats, and its
/// second half reflects the first (`n - 1 - t` for `t >= n / 2`).
fn mirror_source(i: i64, n: usize) -> i64 {
    let t = i.rem_euclid(n as i64);
    t.min(n as i64 - 1 - t)
}

impl Painter {
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Coordinate axes of the model: 2 (images) or 3 (volumes, solid textures).
    pub fn axes(&self) -> usize {
        self.offset.len()
    }

    /// An error unless the model has `axes` coordinate axes: images need a 2D model, volumes
    /// and slices a 3D one.
    pub fn check_axes(&self, axes: usize) -> Result<()> {
        super::check_axes(self.axes(), axes)
    }

    /// What paints: `"fused cpu"`, `"kernel"` (the generator kernel on a GPU) or `"burn"`.
    pub fn engine(&self) -> &'static str {
        self.engine.name()
    }

    /// What `tile` changed, if it was asked for.
    pub fn tile_adjustment(&self) -> Option<&TileAdjustment> {
        self.tile.as_ref()
    }

    /// Renders the box of `shape` whose first pixel is `origin`, relative to the offset (both in
    /// array order: `[row, col]` or `[depth, row, col]`).
    ///
    /// # Shapes
    /// - output: `[..shape, channels]`, row-major, values in [-1, 1]
    pub fn render(&self, origin: &[i64], shape: &[usize]) -> Vec<f32> {
        assert_eq!(origin.len(), self.axes(), "origin has the model's axes");
        assert_eq!(shape.len(), self.axes(), "shape has the model's axes");
        let absolute: Vec<i64> = origin
            .iter()
            .zip(&self.offset)
            .map(|(o, s)| o + s)
            .collect();
        let Some([th, tw]) = self.mirror else {
            return self.render_box(&absolute, shape);
        };
        // Mirror: gather from the painted quarter, which starts at the offset.
        let (y, x, height, width) = (origin[0], origin[1], shape[0], shape[1]);
        let rows: Vec<i64> = (0..height as i64)
            .map(|i| mirror_source(y + i, th))
            .collect();
        let cols: Vec<i64> = (0..width as i64)
            .map(|j| mirror_source(x + j, tw))
            .collect();
        let span = |v: &[i64]| (*v.iter().min().unwrap_or(&0), *v.iter().max().unwrap_or(&0));
        let ((r0, r1), (c0, c1)) = (span(&rows), span(&cols));
        let (bh, bw) = ((r1 - r0 + 1) as usize, (c1 - c0 + 1) as usize);
        let source = self.render_box(&[self.offset[0] + r0, self.offset[1] + c0], &[bh, bw]);
        let c = self.channels;
        let mut out = Vec::with_capacity(width * height * c);
        for &r in &rows {
            for &col in &cols {
                let at = ((r - r0) as usize * bw + (col - c0) as usize) * c;
                out.extend_from_slice(&source[at..at + c]);
            }
        }
        out
    }

    /// The condition values of `points` (`origin` absolute); empty for an unconditioned model.
    fn condition_values(&self, points: BoxPoints, out: &mut Vec<f32>) {
        out.clear();
        let Some(condition) = &self.condition else {
            return;
        };
        let (origin, shape, start) = (points.origin, points.shape, points.start);
        let n = shape.len();
        let (height, width) = (shape[n - 2], shape[n - 1]);
        let (row0, col0) = (
            origin[n - 2] - self.offset[n - 2],
            origin[n - 1] - self.offset[n - 1],
        );
        out.extend((start..start + points.count).map(|k| {
            let row = row0 + (k / width % height) as i64;
            let col = col0 + (k % width) as i64;
            condition.at(row, col)
        }));
    }

    /// Renders the box of `shape` whose first pixel is `origin` in the plane or volume.
    ///
    /// On the CPU, chunks never straddle two slices of a volume's first axis: a volume's chunks
    /// are whole rows counted from the slice's first row, so every slab split of a box
    /// evaluates the same chunks and renders bit for bit alike; an image's chunks are runs of
    /// `CHUNK_POINTS` pixels.
    fn render_box(&self, origin: &[i64], shape: &[usize]) -> Vec<f32> {
        let total: usize = shape.iter().product();
        let c = self.channels;
        let n = shape.len();
        let (height, width) = (shape[n - 2], shape[n - 1]);
        let Engine::Fused(generator) = &self.engine else {
            let axes: Vec<Vec<f32>> = origin
                .iter()
                .zip(shape)
                .map(|(&o, &len)| {
                    (0..len as i64)
                        .map(|i| self.grid.coordinate(o + i))
                        .collect()
                })
                .collect();
            let mut g = Vec::new();
            return self
                .engine
                .render_on_device(&self.field, &self.latent_scale, &axes, c, |start, count| {
                    let points = BoxPoints {
                        origin,
                        shape,
                        start,
                        count,
                    };
                    self.condition_values(points, &mut g);
                    g.clone()
                })
                .expect("device engines render grids");
        };
        let chunk = if n == 2 {
            CHUNK_POINTS
        } else {
            (CHUNK_POINTS / width.max(1)).clamp(1, height.max(1)) * width
        };
        let slice = height * width;
        let mut out = vec![0f32; total * c];
        paint_fused(
            generator,
            |_| &self.field,
            &self.latent_scale,
            c,
            &mut out,
            slice,
            chunk,
            |s, start, count, coords, condition| {
                let points = BoxPoints {
                    origin,
                    shape,
                    start: s * slice + start,
                    count,
                };
                self.grid.coordinates(points, coords);
                self.condition_values(points, condition);
            },
        );
        out
    }

    /// Renders a `[height, width]` image into `path` in row bands of about `band_pixels` pixels,
    /// calling `progress(rows_done)` after each band. The file appears only when complete.
    pub fn write_image(
        &self,
        path: &Path,
        format: OutputFormat,
        [height, width]: [usize; 2],
        band_pixels: usize,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        let whole = MapOutput {
            path: path.to_path_buf(),
            format,
            channels: 0..self.channels,
            normal: false,
            directx: false,
        };
        self.write_maps(&[whole], [height, width], band_pixels, progress)
    }

    /// Writes one file per map of a map set, from bands rendered once for all channels: every
    /// map shows the same seed and region, aligned exactly. Normal maps are renormalised.
    pub fn write_maps(
        &self,
        outputs: &[MapOutput],
        [height, width]: [usize; 2],
        band_pixels: usize,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        let bands = crate::maps::Bands {
            outputs,
            channels: self.channels,
            size: [height, width],
            band_pixels,
            clamp: false,
        };
        bands.write(
            |row, rows| self.render(&[row as i64, 0], &[rows, width]),
            progress,
        )
    }

    /// Renders the chunks of `writer`'s array that `shard` owns, each as one box, and writes
    /// them; chunks already complete (from an earlier run of the shard) are skipped. Memory
    /// holds one chunk. `progress(done, owned)` is called after each chunk.
    pub fn write_zarr(
        &self,
        writer: &ZarrWriter,
        shard: Shard,
        mut progress: impl FnMut(usize, usize),
    ) -> Result<ZarrReport> {
        self.check_axes(writer.axes())?;
        let chunks: usize = writer.grid().iter().product();
        let owned = (0..chunks).filter(|&n| shard.owns(n)).count();
        let mut report = ZarrReport {
            chunks,
            owned,
            written: 0,
            skipped: 0,
        };
        for n in (0..chunks).filter(|&n| shard.owns(n)) {
            let (indices, origin, shape) = writer.chunk_box(n);
            if writer.is_complete(&indices) {
                report.skipped += 1;
            } else {
                writer.write_chunk(&indices, &shape, &self.render(&origin, &shape))?;
                report.written += 1;
            }
            progress(report.written + report.skipped, owned);
        }
        Ok(report)
    }

    /// The mesh of the zero level set of the first channel of the `[depth, height, width]`
    /// volume at the origin, extracted in chunks of about `slab_voxels` voxels and welded.
    pub fn mesh(&self, shape: [usize; 3], slab_voxels: usize) -> crate::mesh::Mesh {
        let mut builder = crate::mesh::MeshBuilder::new(shape[1], shape[2]);
        self.for_each_mesh_chunk(shape, slab_voxels, |start, _, values| {
            builder.add_chunk(&self.first_channel(values), start);
            Ok(())
        })
        .expect("meshing alone does not fail");
        builder.finish()
    }

    /// Writes the `[depth, height, width]` volume at the origin to `.npy` or `.raw`
    /// (`[D, H, W, C]`, raw generator values), in slabs of whole depth slices of about
    /// `slab_voxels` voxels. With `mesh`, the same renders also feed the zero level set of the
    /// first channel into it, so every slice is rendered once (mesh chunks share two slices
    /// with the next one; those are rendered twice).
    pub fn write_volume(
        &self,
        path: &Path,
        shape: [usize; 3],
        slab_voxels: usize,
        mesh: Option<&mut crate::mesh::MeshBuilder>,
    ) -> Result<()> {
        let [depth, height, width] = shape;
        let mut writer =
            crate::io::VolumeWriter::create(path, depth, height, width, self.channels)?;
        let slice = height * width * self.channels;
        match mesh {
            Some(builder) if depth >= 2 => {
                self.for_each_mesh_chunk(shape, slab_voxels, |start, end, values| {
                    builder.add_chunk(&self.first_channel(values), start);
                    // The next chunk starts at end - 1: write up to it, or to the end.
                    let last = if end == depth - 1 { end + 1 } else { end - 1 };
                    writer.write_slab(&values[..(last - start) * slice])
                })?;
            }
            _ => {
                let slab = (slab_voxels / (height * width).max(1)).clamp(1, depth.max(1));
                let mut z = 0;
                while z < depth {
                    let n = slab.min(depth - z);
                    writer.write_slab(&self.render(&[z as i64, 0, 0], &[n, height, width]))?;
                    z += n;
                }
            }
        }
        writer.finish()
    }

    /// Renders the mesh chunks of [`crate::mesh::chunk_starts`] (about `slab_voxels` voxels
    /// each) and hands each to `f(start, end, values)`.
    fn for_each_mesh_chunk(
        &self,
        [depth, height, width]: [usize; 3],
        slab_voxels: usize,
        mut f: impl FnMut(usize, usize, &[f32]) -> Result<()>,
    ) -> Result<()> {
        let slices = (slab_voxels / (height * width).max(1)).max(1);
        for (start, end) in crate::mesh::chunk_starts(depth, slices) {
            let values = self.render(&[start as i64, 0, 0], &[end - start + 1, height, width]);
            f(start, end, &values)?;
        }
        Ok(())
    }

    fn first_channel(&self, values: &[f32]) -> Vec<f32> {
        values.chunks_exact(self.channels).map(|v| v[0]).collect()
    }
}
