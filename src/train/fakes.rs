//! The generated side of the critic's input: for each sample, a crop's grid of coordinates
//! moved by a random shift, a fresh latent field, and the condition of a random real crop;
//! painted by the framework's generator (with gradient), or on the CPU by synthesis' own fused
//! engine ([`crate::synth::paint_fused`]) when no gradient is needed, or by the generator's
//! backward's own forward passes, kept for its backward (`Trainer::paint_kept`).

use burn::prelude::*;
use rayon::prelude::*;

use super::coarse::Scale;
use super::draws::{stream, uniform};
use super::{RunKind, Trainer};
use crate::generator::backward::{self, Pass};
use crate::generator::fused::{CHUNK_POINTS, FusedGenerator};
use crate::generator::{Generator, GeneratorWeights};
use crate::latent::{DeviceLattice, LatentField, derive_seed};
use crate::sample::{crop_coordinate, strided_crop_coordinate};

/// The most memory a generator step's kept forward passes may take
/// ([`Trainer::keeps_passes`]).
pub const KEPT_PASSES_BYTES: usize = 512 << 20;

/// Points per generator evaluation when training on flex (see [`Trainer::fake_batch`]).
pub const FLEX_TRAIN_CHUNK: usize = 4096;

impl Trainer {
    /// The coordinates `[points, axes]` of generated sample `s` and its latent field: draw 0
    /// for the crop the critic scores, 1 for its twin (the same coordinates, a fresh field; see
    /// [`super::diversity`]).
    ///
    /// A crop's grid of pixel centres spans 2 units (a coarse crop's `2 · coarse_stride`,
    /// every `coarse_stride`-th pixel) and is shifted by a random offset per axis. For a solid texture it lies in a random axis-aligned plane of the volume: the
    /// plane's axis sits at its random offset, and the crop's rows and columns run along the
    /// other two axes in order. For a volume it is a cube of `crop³` voxels.
    pub(super) fn sample_coordinates(
        &self,
        s: usize,
        counters: &[u64],
        draw: u64,
        scale: Scale,
    ) -> (Vec<f32>, LatentField) {
        let cfg = &self.config;
        let dims = self.kind.generator_axes();
        let key = |purpose: u64, extra: u64| {
            let mut k = vec![purpose, s as u64, extra];
            k.extend_from_slice(counters);
            k
        };
        let shift: Vec<f32> = (0..dims as u64)
            .map(|axis| (uniform(cfg.seed, &key(stream::SHIFT, axis)) * 2.0 - 1.0) * cfg.shift)
            .collect();
        let field = LatentField::hashed(
            derive_seed(cfg.seed, &key(stream::LATENT, draw)),
            dims,
            cfg.latent_dim,
        )
        .with_sigma(cfg.sigma);
        let (crop, stride) = (cfg.crop, self.stride(scale));
        let along = |i: usize, axis: usize| match stride {
            1 => crop_coordinate(crop, i, shift[axis]),
            _ => strided_crop_coordinate(crop, stride, i, shift[axis]),
        };
        // The axes the crop's points run along: all of them, or a solid's random plane.
        let (fixed, running): (Option<usize>, Vec<usize>) = match self.kind {
            RunKind::Solid => {
                let normal =
                    ((uniform(cfg.seed, &key(stream::SLICE_AXIS, 0)) * 3.0) as usize).min(2);
                (Some(normal), (0..3).filter(|&a| a != normal).collect())
            }
            _ => (None, (0..dims).collect()),
        };
        let points = crop.pow(running.len() as u32);
        let mut coords = vec![0f32; points * dims];
        for (q, p) in coords.chunks_exact_mut(dims).enumerate() {
            if let Some(normal) = fixed {
                p[normal] = shift[normal];
            }
            let mut rest = q;
            for &axis in running.iter().rev() {
                p[axis] = along(rest % crop, axis);
                rest /= crop;
            }
        }
        (coords, field)
    }

    /// Generated crops: the generator at every point of every sample, then the condition
    /// the generator was given, as one more channel. `draw` picks the latent fields (0: the
    /// critic's crops; 1: their twins), `scale` the fine or the coarse critic's grid.
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1), depth, crop, crop]` on `device` (`generator`'s)
    pub fn fake_batch(
        &self,
        generator: &Generator,
        device: &Device,
        counters: &[u64],
        draw: u64,
        scale: Scale,
    ) -> Tensor<5> {
        let (b, s, c) = (self.config.batch, self.config.crop, self.exemplar.channels);
        let depth = if self.kind.crop_axes() == 3 { s } else { 1 };
        let samples = self.fake_samples(counters, draw, scale);
        let conditions: Vec<f32> = samples.iter().flat_map(|s| s.condition.clone()).collect();
        let values = if device.clone().inner() == Device::flex() {
            self.values_on_flex(generator, device, &samples)
        } else {
            self.values_on_device(generator, device, &samples, &conditions)
        }; // [b * points, c]
        let crops = values.reshape([b, depth, s, s, c]).permute([0, 4, 1, 2, 3]); // [b, c, depth, s, s]
        if conditions.is_empty() {
            return crops;
        }
        let g = Tensor::<5>::from_data(TensorData::new(conditions, [b, 1, depth, s, s]), device);
        Tensor::cat(vec![crops, g], 1) // [b, c + 1, depth, s, s]
    }

    /// The condition slice of generated sample `s`: that of a random real crop at `scale`
    /// (stream `GUIDE`); empty for an unconditioned run.
    pub(super) fn fake_condition(&self, s: usize, counters: &[u64], scale: Scale) -> Vec<f32> {
        if !self.kind.conditioned() {
            return Vec::new();
        }
        let stride = self.stride(scale);
        let origin = self.crop_origin(stream::GUIDE, s, counters, stride);
        self.crop_condition(&origin, stride)
    }

    /// [`Trainer::fake_batch`] on flex: each point's latent vector blended on the host, then
    /// the MLP in chunks of [`FLEX_TRAIN_CHUNK`] points, so each layer's activations (and, in
    /// the backward pass, their gradients) stay in cache; the weight gradients sum over the
    /// chunks.
    ///
    /// # Shapes
    /// - output: `[batch * points, channels]` on `device`
    fn values_on_flex(
        &self,
        generator: &Generator,
        device: &Device,
        samples: &[FakeSample],
    ) -> Tensor<2> {
        let cfg = &self.config;
        let ld = cfg.latent_dim;
        let conditioned = self.kind.conditioned() as usize;
        let zw = ld + conditioned; // generator input after the encoding: latent, then g
        let (b, n, dims) = (
            samples.len(),
            self.crop_points(),
            self.kind.generator_axes(),
        );
        let coords: Vec<f32> = samples.iter().flat_map(|s| s.p.iter().copied()).collect();
        let mut latent = vec![0f32; b * n * zw];
        latent
            .par_chunks_mut(n * zw)
            .zip(samples)
            .for_each(|(z, sample)| {
                let u: Vec<f32> = sample.p.iter().map(|v| v * cfg.latent_scale).collect();
                if conditioned == 0 {
                    sample.field.fill(&u, z);
                    return;
                }
                let mut zs = vec![0f32; n * ld];
                sample.field.fill(&u, &mut zs);
                for q in 0..n {
                    z[q * zw..q * zw + ld].copy_from_slice(&zs[q * ld..(q + 1) * ld]);
                    z[q * zw + ld] = sample.condition[q];
                }
            });
        let p = Tensor::<2>::from_data(TensorData::new(coords, [b * n, dims]), device);
        let z = Tensor::<2>::from_data(TensorData::new(latent, [b * n, zw]), device);
        let values: Vec<Tensor<2>> = p
            .split(FLEX_TRAIN_CHUNK, 0)
            .into_iter()
            .zip(z.split(FLEX_TRAIN_CHUNK, 0))
            .map(|(p, z)| generator.forward(p, z)) // [chunk, c]
            .collect();
        Tensor::cat(values, 0) // [b * n, c]
    }

    /// [`Trainer::fake_batch`] on a GPU: the latent blend evaluated on the device from each
    /// sample's few lattice vectors ([`DeviceLattice`]) instead of `latent_dim` floats per
    /// point sent from the host. (On flex the host blend is kept: it is as fast there, and
    /// gives the latent values the fused CPU evaluator gives.)
    ///
    /// # Shapes
    /// - output: `[batch * points, channels]` on `device`
    fn values_on_device(
        &self,
        generator: &Generator,
        device: &Device,
        samples: &[FakeSample],
        conditions: &[f32],
    ) -> Tensor<2> {
        let cfg = &self.config;
        let (b, n, dims) = (
            samples.len(),
            self.crop_points(),
            self.kind.generator_axes(),
        );
        // The box of lattice cells each crop touches (u = p * latent_scale, as on the device).
        let fields: Vec<(&LatentField, Vec<f32>, Vec<f32>)> = samples
            .iter()
            .map(|sample| {
                let (mut lo, mut hi) = (vec![f32::INFINITY; dims], vec![f32::NEG_INFINITY; dims]);
                for q in sample.p.chunks_exact(dims) {
                    for d in 0..dims {
                        let u = q[d] * cfg.latent_scale;
                        lo[d] = lo[d].min(u);
                        hi[d] = hi[d].max(u);
                    }
                }
                (&sample.field, lo, hi)
            })
            .collect();
        let lattice = DeviceLattice::new(&fields, device);
        let sample = Tensor::<1, Int>::arange(0..b as i64, device)
            .reshape([b, 1])
            .expand([b, n])
            .reshape([b * n]); // [b * n]: the field of each point
        let coords: Vec<f32> = samples.iter().flat_map(|s| s.p.iter().copied()).collect();
        let p = Tensor::<2>::from_data(TensorData::new(coords, [b * n, dims]), device);
        let mut z = lattice.blend(p.clone().mul_scalar(cfg.latent_scale), Some(sample)); // [b * n, ld]
        if !conditions.is_empty() {
            let g =
                Tensor::<2>::from_data(TensorData::new(conditions.to_vec(), [b * n, 1]), device);
            z = Tensor::cat(vec![z, g], 1); // [b * n, ld + 1]
        }
        generator.forward(p, z) // [b * n, c]
    }

    /// The same crops as [`Trainer::fake_batch`], painted by synthesis' fused CPU engine (no
    /// gradient: for the critic's steps).
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1), depth, crop, crop]` on the training device
    pub fn fake_batch_fused(
        &self,
        generator: &FusedGenerator,
        counters: &[u64],
        scale: Scale,
    ) -> Tensor<5> {
        let samples = self.fake_samples(counters, 0, scale);
        let (planar, shape) = self.paint_fused(generator, &samples);
        Tensor::from_data(TensorData::new(planar, shape), &self.device)
    }

    /// Each generated sample's coordinates `[points, axes]`, latent field and condition (empty
    /// for an unconditioned run), as [`Trainer::fake_batch`] draws them.
    pub(super) fn fake_samples(
        &self,
        counters: &[u64],
        draw: u64,
        scale: Scale,
    ) -> Vec<FakeSample> {
        (0..self.config.batch)
            .into_par_iter()
            .map(|i| {
                let (p, field) = self.sample_coordinates(i, counters, draw, scale);
                FakeSample {
                    p,
                    field,
                    condition: self.fake_condition(i, counters, scale),
                }
            })
            .collect()
    }

    /// `samples` painted by the fused CPU engine, with their conditions as one more channel,
    /// and the batch's shape `[batch, channels (+ 1), depth, crop, crop]`.
    pub(super) fn paint_fused(
        &self,
        generator: &FusedGenerator,
        samples: &[FakeSample],
    ) -> (Vec<f32>, [usize; 5]) {
        let cfg = &self.config;
        let (b, c) = (cfg.batch, self.exemplar.channels);
        let (n, dims) = (self.crop_points(), self.kind.generator_axes());
        let mut points = vec![0f32; b * n * c]; // [b, n, c]
        crate::synth::paint_fused(
            generator,
            |i| &samples[i].field,
            &vec![cfg.latent_scale; dims],
            c,
            &mut points,
            n,
            CHUNK_POINTS,
            |i, start, count, coords, condition| {
                let sample = &samples[i];
                coords.clear();
                coords.extend_from_slice(&sample.p[start * dims..(start + count) * dims]);
                condition.clear();
                if !sample.condition.is_empty() {
                    condition.extend_from_slice(&sample.condition[start..start + count]);
                }
            },
        );
        self.planar(samples, &points)
    }

    /// Whether a generator step keeps the forward passes that painted its crops (and twins)
    /// for its backward, rather than run them again: when they take at most
    /// [`KEPT_PASSES_BYTES`] (`configs/quick.toml`'s 14 MB, `default.toml`'s 343 MB; not
    /// `paper.toml`'s batch of 8 or a volume's), or as [`Trainer::keep_passes_within`] says.
    pub(super) fn keeps_passes(&self, weights: &GeneratorWeights) -> bool {
        let twins = (self.config.diversity > 0.0) as usize;
        let coarse = self.coarse.is_some() as usize;
        let crops = self.config.batch * (1 + twins + coarse);
        let floats = crops * self.crop_points() * backward::pass_floats_per_point(weights);
        floats * size_of::<f32>() <= self.kept_passes_bytes
    }

    /// `count` samples' points in groups of at most [`backward::GROUP_POINTS`], sample by
    /// sample: `(sample, first point, end)`.
    pub(super) fn point_groups(&self, count: usize) -> Vec<(usize, usize, usize)> {
        let (n, group) = (self.crop_points(), backward::GROUP_POINTS);
        let starts = move |i| {
            (0..n)
                .step_by(group)
                .map(move |s| (i, s, (s + group).min(n)))
        };
        (0..count).flat_map(starts).collect()
    }

    /// `samples` painted group by group ([`Trainer::point_groups`]) with each group's forward
    /// pass kept for the backward; the batch laid out as [`Trainer::paint_fused`]'s.
    pub(super) fn paint_kept(
        &self,
        weights: &GeneratorWeights,
        samples: &[FakeSample],
    ) -> (Vec<f32>, [usize; 5], Vec<Pass>) {
        let (n, c, dims) = (
            self.crop_points(),
            self.exemplar.channels,
            self.kind.generator_axes(),
        );
        let scale = vec![self.config.latent_scale; dims];
        let groups = self.point_groups(samples.len());
        let passes: Vec<Pass> = groups
            .par_iter()
            .map(|&(i, start, end)| {
                let sample = &samples[i];
                let p = &sample.p[start * dims..end * dims];
                let guide = sample.condition.get(start..end).unwrap_or(&[]);
                backward::forward(weights, &scale, p, &sample.field, guide)
            })
            .collect();
        let mut points = vec![0f32; samples.len() * n * c]; // [b, n, c]
        for (&(i, start, end), pass) in groups.iter().zip(&passes) {
            points[(i * n + start) * c..(i * n + end) * c].copy_from_slice(pass.output());
        }
        let (planar, shape) = self.planar(samples, &points);
        (planar, shape, passes)
    }

    /// Painted values `[b, n, c]` with the samples' conditions as one more channel, and the
    /// batch's shape: `[batch, channels (+ 1), depth, crop, crop]`.
    fn planar(&self, samples: &[FakeSample], points: &[f32]) -> (Vec<f32>, [usize; 5]) {
        let (s, c) = (self.config.crop, self.exemplar.channels);
        let (b, n) = (samples.len(), self.crop_points());
        let cg = c + self.kind.conditioned() as usize;
        let mut planar = vec![0f32; b * cg * n]; // [b, c (+ g), n]
        for (i, sample) in samples.iter().enumerate() {
            for q in 0..n {
                for ch in 0..c {
                    planar[(i * cg + ch) * n + q] = points[(i * n + q) * c + ch];
                }
            }
            planar[(i * cg + c) * n..(i + 1) * cg * n].copy_from_slice(&sample.condition);
        }
        let depth = if self.kind.crop_axes() == 3 { s } else { 1 };
        (planar, [b, cg, depth, s, s])
    }
}

/// One generated sample's inputs: coordinates `[points, axes]`, latent field, condition.
pub(super) struct FakeSample {
    pub p: Vec<f32>,
    pub field: LatentField,
    pub condition: Vec<f32>,
}
