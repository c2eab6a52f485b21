//! The evaluators behind a [`super::Painter`] and behind training's fakes: the fused CPU
//! generator in parallel chunks ([`paint_fused`], the one chunk loop), the generator kernel on a
//! GPU, or burn's generator on any device.

use burn::prelude::*;
use rayon::prelude::*;

use crate::generator::fused::{FusedGenerator, Scratch};
use crate::generator::kernel::KernelGenerator;
use crate::generator::{Generator, GeneratorWeights};
use crate::latent::{DeviceLattice, LatentField, grid_lattice_bounds};

/// The evaluator behind a [`Painter`].
pub(crate) enum Engine {
    Fused(FusedGenerator),
    /// The generator as one CubeCL kernel, where the device runs CubeCL and the model fits.
    Kernel(Box<KernelGenerator>),
    Burn {
        generator: Generator,
        device: Device,
        /// Points per forward pass.
        chunk: usize,
    },
}

impl Engine {
    /// The evaluator for `weights` on `device` (`None`: the CPU); `kernel` lets GPU devices
    /// use the generator kernel.
    pub(crate) fn new(
        weights: GeneratorWeights,
        device: Option<Device>,
        chunk: usize,
        kernel: bool,
    ) -> Self {
        let Some(device) = device else {
            return Engine::Fused(FusedGenerator::new(weights));
        };
        match kernel
            .then(|| KernelGenerator::new(&weights, &device))
            .flatten()
        {
            Some(kernel) => Engine::Kernel(Box::new(kernel)),
            None => Engine::Burn {
                generator: Generator::from_weights(&weights, &device),
                device,
                chunk,
            },
        }
    }

    /// What paints: `"fused cpu"`, `"kernel"` (the generator kernel on a GPU) or `"burn"`.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            Engine::Fused(_) => "fused cpu",
            Engine::Kernel(_) => "kernel",
            Engine::Burn { .. } => "burn",
        }
    }

    /// Renders the grid `axes[0] x axes[1] (x axes[2])` on the device engines (the fused CPU
    /// evaluator renders its own chunks: `None`). `guide(start, count)` gives the guidance
    /// values of points `start..start + count`, empty for an unguided model.
    ///
    /// # Shapes
    /// - output: `[points, channels]`, row-major over the axes
    pub(crate) fn render_on_device(
        &self,
        field: &LatentField,
        latent_scale: &[f32],
        axes: &[Vec<f32>],
        channels: usize,
        guide: impl FnMut(usize, usize) -> Vec<f32>,
    ) -> Option<Vec<f32>> {
        match self {
            Engine::Fused(_) => None,
            Engine::Kernel(kernel) => Some(kernel.render(field, latent_scale, axes, guide)),
            Engine::Burn {
                generator,
                device,
                chunk,
            } => Some(render_on_device(
                generator,
                device,
                *chunk,
                field,
                latent_scale,
                axes,
                channels,
                guide,
            )),
        }
    }
}

/// Evaluates the fused CPU generator into `out` (`[points, channels]`) in parallel chunks: `out`
/// is cut into slices of `slice_points` points, each slice into chunks of `chunk_points`, and
/// `inputs(slice, start, count, coords, condition)` fills a chunk's coordinates and condition
/// values (left empty for an unconditioned model) for points `start..start + count` of its
/// slice. `field(slice)` is the slice's latent field. Every chunk is evaluated alike however
/// the work is scheduled, so results do not depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub(crate) fn paint_fused<'f>(
    generator: &FusedGenerator,
    field: impl Fn(usize) -> &'f LatentField + Sync,
    latent_scale: &[f32],
    channels: usize,
    out: &mut [f32],
    slice_points: usize,
    chunk_points: usize,
    inputs: impl Fn(usize, usize, usize, &mut Vec<f32>, &mut Vec<f32>) + Sync,
) {
    let c = channels;
    let mut pieces: Vec<(usize, usize, &mut [f32])> = Vec::new();
    for (slice, values) in out.chunks_mut(slice_points.max(1) * c).enumerate() {
        for (k, piece) in values.chunks_mut(chunk_points.max(1) * c).enumerate() {
            pieces.push((slice, k * chunk_points, piece));
        }
    }
    pieces.into_par_iter().for_each_init(
        || (Scratch::default(), Vec::new(), Vec::new()),
        |(scratch, coords, condition), (slice, start, values)| {
            let count = values.len() / c;
            inputs(slice, start, count, coords, condition);
            generator.eval(
                coords,
                field(slice),
                latent_scale,
                condition,
                values,
                scratch,
            );
        },
    );
}

/// Chunks read back together by [`render_on_device`]: one transfer per 16 chunks keeps the
/// device busy while bounding its memory (16 x 65,536 points of output).
const CHUNKS_PER_READBACK: usize = 16;

/// Renders the grid of points `axes[0] x axes[1] (x axes[2])` (coordinates per axis, row-major,
/// last axis fastest) through the burn generator on `device`: coordinates are built there from
/// the per-axis lists, the latent field is blended there from the few lattice vectors the box
/// touches ([`DeviceLattice`]), and outputs are read back a few chunks at a time. Chunks are
/// whole rows inside one slice of the first axis (3D), counted from that slice's first row, so
/// every slab split of a volume evaluates the same chunks. `guide(start, count)` gives the
/// guidance values of points `start..start + count` (row-major), empty for an unguided model.
///
/// # Shapes
/// - output: `[points, channels]`, row-major over the axes
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_on_device(
    generator: &Generator,
    device: &Device,
    chunk_points: usize,
    field: &LatentField,
    latent_scale: &[f32],
    axes: &[Vec<f32>],
    channels: usize,
    mut guide: impl FnMut(usize, usize) -> Vec<f32>,
) -> Vec<f32> {
    let dims = axes.len();
    let total: usize = axes.iter().map(Vec::len).product();
    let mut out = Vec::with_capacity(total * channels);
    if total == 0 {
        return out;
    }
    let (lo, hi) = grid_lattice_bounds(axes, latent_scale);
    let lattice = DeviceLattice::new(&[(field, lo, hi)], device);
    let axis: Vec<Tensor<1>> = axes
        .iter()
        .map(|a| Tensor::from_data(TensorData::new(a.clone(), [a.len()]), device))
        .collect();
    let scale = Tensor::<2>::from_data(TensorData::new(latent_scale.to_vec(), [1, dims]), device);
    let (height, width) = (axes[dims - 2].len(), axes[dims - 1].len());
    let depth = total / (height * width);
    let rows_per_chunk = (chunk_points / width).clamp(1, height);
    let mut pending = Vec::new();
    let flush = |pending: &mut Vec<Tensor<2>>, out: &mut Vec<f32>| {
        if !pending.is_empty() {
            let host = Tensor::cat(std::mem::take(pending), 0)
                .try_into_vec_as::<f32>()
                .expect("generator output is readable as f32");
            out.extend_from_slice(&host);
        }
    };
    for z in 0..depth {
        for r0 in (0..height).step_by(rows_per_chunk) {
            let rows = rows_per_chunk.min(height - r0);
            let n = rows * width;
            let column = |t: Tensor<3>| t.expand([rows, width, 1]); // [rows, width, 1]
            let mut parts = Vec::with_capacity(dims);
            if dims == 3 {
                parts.push(column(axis[0].clone().slice(z..z + 1).reshape([1, 1, 1])));
            }
            parts.push(column(
                axis[dims - 2]
                    .clone()
                    .slice(r0..r0 + rows)
                    .reshape([rows, 1, 1]),
            ));
            parts.push(column(axis[dims - 1].clone().reshape([1, width, 1])));
            let p = Tensor::cat(parts, 2).reshape([n, dims]); // [n, dims]
            let mut latent = lattice.blend(p.clone() * scale.clone(), None); // [n, latent_dim]
            let g = guide(z * height * width + r0 * width, n);
            if !g.is_empty() {
                let g = Tensor::<2>::from_data(TensorData::new(g, [n, 1]), device);
                latent = Tensor::cat(vec![latent, g], 1); // [n, latent_dim + 1]
            }
            pending.push(generator.forward(p, latent)); // [n, channels]
            if pending.len() == CHUNKS_PER_READBACK {
                flush(&mut pending, &mut out);
            }
        }
    }
    flush(&mut pending, &mut out);
    out
}
