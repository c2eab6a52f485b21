//! Synthesis: paint any region of the infinite plane with a trained generator.
//!
//! [`Synth`] is a builder whose options mirror `ipfn synth`'s flags one to one; it produces a
//! [`Painter`], which renders regions (`[height, width, channels]`, values in [-1, 1]) or streams a
//! whole image to disk in row bands, so memory is bounded by a band, not by the image.
//!
//! Tileable output (`tile`): the latent lattice is wrapped and K is snapped so that the tile spans
//! a whole number of periods of every octave; the latent lattice scale is snapped likewise so the
//! tile spans a whole number of lattice cells. The generator is then exactly periodic with the
//! tile's size.

use std::path::Path;
use std::str::FromStr;

use burn::prelude::*;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::generator::fused::{CHUNK_POINTS, FusedGenerator, Scratch};
use crate::generator::kernel::KernelGenerator;
use crate::generator::{Generator, GeneratorConfig, GeneratorWeights};
use crate::guidance::Guide;
use crate::input_error;
use crate::io::{ImageWriter, OutputFormat};
use crate::latent::{DeviceLattice, LatentField, grid_lattice_bounds};
use crate::sample::PixelGrid;

/// Where the generator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The fused CPU evaluator (fastest on a CPU).
    Cpu,
    /// burn's flex CPU backend (the same math through the framework; for checks and training).
    Flex,
    /// burn's wgpu backend (Vulkan, Metal, DX12; lavapipe without a GPU).
    Wgpu,
    /// burn's CUDA backend (NVIDIA GPUs); needs a build with `--features cuda`.
    Cuda,
}

impl FromStr for DeviceChoice {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "cpu" => Ok(Self::Cpu),
            "flex" => Ok(Self::Flex),
            "wgpu" | "gpu" => Ok(Self::Wgpu),
            "cuda" => Ok(Self::Cuda),
            other => Err(input_error!(
                "unknown device '{other}'; use cpu, flex, wgpu or cuda"
            )),
        }
    }
}

impl DeviceChoice {
    /// The burn device for this choice (`None` for the fused CPU path). wgpu is probed here so a
    /// machine without an adapter gets an error instead of a panic on first use.
    pub fn burn_device(&self) -> Result<Option<Device>> {
        match self {
            Self::Cpu => Ok(None),
            Self::Flex => Ok(Some(Device::flex())),
            Self::Wgpu => wgpu_device().map(Some),
            Self::Cuda => cuda_device().map(Some),
        }
    }

    /// The device training uses: flex stands in for the fused CPU path, which has no backward.
    pub fn training_device(&self) -> Result<Device> {
        Ok(self.burn_device()?.unwrap_or_else(Device::flex))
    }
}

/// Whether every wgpu adapter on this machine is a software one (lavapipe, WARP): wgpu then
/// works but runs on the CPU, far slower than `--device cpu`.
#[cfg(feature = "wgpu")]
pub fn wgpu_is_software() -> bool {
    use burn::tensor::wgpu::wgpu;
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle();
    descriptor.backends = wgpu::Backends::PRIMARY;
    let instance = wgpu::Instance::new(descriptor);
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
    !adapters.is_empty()
        && adapters
            .iter()
            .all(|a| a.get_info().device_type == wgpu::DeviceType::Cpu)
}

/// A build without the `wgpu` feature has no wgpu adapter, software or not.
#[cfg(not(feature = "wgpu"))]
pub fn wgpu_is_software() -> bool {
    false
}

/// The CUDA device, probed once per process with a one-element round trip, so a machine without
/// a driver or GPU gets an error instead of a panic on first use.
#[cfg(feature = "cuda")]
pub fn cuda_device() -> Result<Device> {
    static DEVICE: std::sync::OnceLock<std::result::Result<Device, String>> =
        std::sync::OnceLock::new();
    DEVICE
        .get_or_init(|| {
            // The first panic message from any thread (the CUDA runtime initialises on a
            // server thread, whose panic reaches this one only as a closed channel).
            static FIRST_PANIC: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);
            let hook = std::panic::take_hook();
            std::panic::set_hook(Box::new(|info| {
                let message = info
                    .payload()
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| info.payload().downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "CUDA initialisation failed".into());
                let mut first = FIRST_PANIC.lock().unwrap_or_else(|e| e.into_inner());
                first.get_or_insert(message);
            }));
            let probe = std::panic::catch_unwind(|| {
                let device = Device::cuda(0);
                let one = Tensor::<1>::from_floats([1.0f32].as_slice(), &device);
                one.try_into_vec_as::<f32>().map(|_| device)
            });
            std::panic::set_hook(hook);
            let first = FIRST_PANIC
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
                .map(|m| m.split_whitespace().collect::<Vec<_>>().join(" "));
            match probe {
                Ok(Ok(device)) => Ok(device),
                Ok(Err(e)) => Err(first.unwrap_or_else(|| format!("{e:?}"))),
                Err(_) => Err(first.unwrap_or_else(|| "CUDA initialisation failed".into())),
            }
        })
        .clone()
        .map_err(|e| {
            input_error!("--device cuda: no usable CUDA device ({e}); check the NVIDIA driver (nvidia-smi) or use --device wgpu or cpu")
        })
}

/// Without the `cuda` feature, `--device cuda` says how to get it.
#[cfg(not(feature = "cuda"))]
pub fn cuda_device() -> Result<Device> {
    Err(input_error!(
        "--device cuda: this ipfn was built without CUDA; reinstall with `cargo install --path . --features cuda`, or use --device wgpu"
    ))
}

/// Without the `wgpu` feature, `--device wgpu` says how to get it.
#[cfg(not(feature = "wgpu"))]
pub fn wgpu_device() -> Result<Device> {
    Err(input_error!(
        "--device wgpu: this ipfn was built without wgpu; reinstall with `cargo install --path .` (wgpu is a default feature), or use --device cpu"
    ))
}

/// The wgpu device, initialised once per process.
#[cfg(feature = "wgpu")]
pub fn wgpu_device() -> Result<Device> {
    static DEVICE: std::sync::OnceLock<std::result::Result<Device, String>> =
        std::sync::OnceLock::new();
    DEVICE
        .get_or_init(|| {
            Device::wgpu_options()
                .init()
                .map_err(|e| e.to_string().split_whitespace().collect::<Vec<_>>().join(" "))
        })
        .clone()
        .map_err(|e| {
            input_error!("--device wgpu: no usable GPU adapter ({e}); install Vulkan drivers (e.g. mesa-vulkan-drivers) or use --device cpu")
        })
}

/// The evaluator behind a [`Painter`].
enum Engine {
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
    fn new(weights: GeneratorWeights, device: Option<Device>, chunk: usize, kernel: bool) -> Self {
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
    fn name(&self) -> &'static str {
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
    fn render_on_device(
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

/// Whether GPU synthesis uses the generator kernel ([`KernelGenerator`]) where it can:
/// `IPFN_GPU_KERNEL=0` selects the burn generator instead (for comparison in `ipfn bench`).
pub fn gpu_kernel_enabled() -> bool {
    std::env::var("IPFN_GPU_KERNEL").map_or(true, |v| v != "0")
}

/// Points per burn forward pass on a GPU: bounds device memory (`width` activations per point)
/// while keeping launches few. `IPFN_GPU_CHUNK_POINTS` overrides it (for tuning with
/// `ipfn bench`).
pub const GPU_CHUNK_POINTS: usize = 1 << 16;
/// Points per burn forward pass on flex: activations stay in cache (`ipfn bench`: 1024² takes
/// half the time it takes with 65,536-point chunks).
pub const FLEX_CHUNK_POINTS: usize = 1 << 12;

impl DeviceChoice {
    /// Points per burn forward pass on this device.
    pub fn chunk_points(&self) -> usize {
        match self {
            Self::Cpu | Self::Flex => FLEX_CHUNK_POINTS,
            Self::Wgpu | Self::Cuda => std::env::var("IPFN_GPU_CHUNK_POINTS")
                .ok()
                .and_then(|v| v.parse().ok())
                .filter(|&n: &usize| n > 0)
                .unwrap_or(GPU_CHUNK_POINTS),
        }
    }
}

/// How K and the latent lattice were adjusted to make a tile.
#[derive(Debug, Clone, PartialEq)]
pub struct TileAdjustment {
    pub k_trained: Vec<f32>,
    pub k_used: Vec<f32>,
    pub latent_scale_trained: f32,
    pub latent_scale_used: Vec<f32>,
    /// Lattice period (cells) per axis.
    pub lattice_period: Vec<i64>,
}

impl TileAdjustment {
    /// One line for the user: how far K moved on each axis.
    pub fn describe(&self) -> String {
        let moved: Vec<String> = self
            .k_trained
            .iter()
            .zip(&self.k_used)
            .map(|(a, b)| format!("{a:.4} -> {b:.4} ({:+.2}%)", 100.0 * (b / a - 1.0)))
            .collect();
        let lat: Vec<String> = self
            .latent_scale_used
            .iter()
            .map(|s| format!("{:+.2}%", 100.0 * (s / self.latent_scale_trained - 1.0)))
            .collect();
        let axes = if self.k_used.len() == 3 {
            "depth, rows, cols"
        } else {
            "rows, cols"
        };
        format!(
            "tile: K snapped {} ({axes}); latent lattice {:?} cells, scale moved {}",
            moved.join(", "),
            self.lattice_period,
            lat.join(", ")
        )
    }
}

/// Builder for a synthesis; each method matches an `ipfn synth` flag.
#[derive(Debug, Clone)]
pub struct Synth {
    config: GeneratorConfig,
    weights: GeneratorWeights,
    seed: u64,
    zoom: f64,
    offset: [i64; 2],
    tile: Option<[usize; 2]>,
    mirror: Option<[usize; 2]>,
    noise_scale: f64,
    guide: Option<(Guide, [usize; 2])>,
    tile_volume: Option<[usize; 3]>,
    density: Option<DensityRamp>,
    device: DeviceChoice,
    gpu_kernel: bool,
}

/// Densities typical of truncated SDFs (mean |sdf| 0.1 to 0.4) are spread over about ±1 before
/// they reach the generator and the critic: fed raw, their small spread left a 300-iteration
/// model ignoring them (measured on the graded gyroid; with this scaling it followed a ramp).
pub const DENSITY_CENTER: f32 = 0.25;
pub const DENSITY_GAIN: f32 = 6.0;

/// The generator's input for density `d` (the mean |sdf| of a truncated SDF).
pub fn density_input(d: f32) -> f32 {
    (d - DENSITY_CENTER) * DENSITY_GAIN
}

/// The density a density-controlled volume model paints (the mean |sdf| of its truncated SDF):
/// `from` at column 0 of the volume, `to` at its last column, linear in between (constant when
/// they are equal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DensityRamp {
    pub from: f32,
    pub to: f32,
    /// The volume's width in voxels (the ramp's frame).
    pub width: usize,
}

impl DensityRamp {
    /// The generator's density input at column `x` (clamped to the frame).
    pub fn at(&self, x: i64) -> f32 {
        density_input(self.density(x))
    }

    /// The density at column `x` (clamped to the frame).
    pub fn density(&self, x: i64) -> f32 {
        let t = if self.width > 1 {
            (x as f32 / (self.width - 1) as f32).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.from + (self.to - self.from) * t
    }
}

impl Synth {
    /// A synthesis with `model`'s config and weights: seed 0, zoom 1, offset 0, CPU.
    pub fn new(config: GeneratorConfig, weights: GeneratorWeights) -> Self {
        Self {
            config,
            weights,
            seed: 0,
            zoom: 1.0,
            offset: [0, 0],
            tile: None,
            mirror: None,
            noise_scale: 1.0,
            guide: None,
            density: None,
            tile_volume: None,
            device: DeviceChoice::Cpu,
            gpu_kernel: gpu_kernel_enabled(),
        }
    }

    /// `--seed`: which latent field (any u64).
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// `--zoom`: magnification; 1 paints one output pixel per exemplar pixel of training.
    pub fn zoom(mut self, zoom: f64) -> Self {
        self.zoom = zoom;
        self
    }

    /// `--offset X,Y`: the top-left pixel of the output in the infinite plane.
    pub fn offset(mut self, x: i64, y: i64) -> Self {
        self.offset = [y, x];
        self
    }

    /// `--tile`: make the output exactly periodic with period `width` x `height` pixels.
    pub fn tile(mut self, width: usize, height: usize) -> Self {
        self.tile = Some([height, width]);
        self
    }

    /// `--mirror`: a mirror-symmetric tile of `width` x `height` pixels. The top-left quarter is
    /// painted and reflected about the tile's centre lines, so the output is symmetric about
    /// both and repeats with the tile's period (paper §4.4). The plane outside the tile repeats it.
    pub fn mirror(mut self, width: usize, height: usize) -> Self {
        self.mirror = Some([height, width]);
        self
    }

    /// `--noise-scale`: the latent lattice's cells are this many times larger relative to the
    /// pattern's period than in training (paper Fig. 5e): above 1, structure varies over larger
    /// regions; below 1, over smaller ones. 1 is as trained.
    pub fn noise_scale(mut self, scale: f64) -> Self {
        self.noise_scale = scale;
        self
    }

    /// `--guide`: the guidance field of a guided model, over the `width x height` output frame
    /// whose top-left pixel is the offset.
    pub fn guide(mut self, guide: Guide, width: usize, height: usize) -> Self {
        self.guide = Some((guide, [height, width]));
        self
    }

    /// `--tile` with `--depth`: make a volume exactly periodic with `depth x height x width`
    /// voxels.
    /// Density control for a volume model trained with `--density`.
    pub fn density(mut self, ramp: DensityRamp) -> Self {
        self.density = Some(ramp);
        self
    }

    pub fn tile_volume(mut self, depth: usize, height: usize, width: usize) -> Self {
        self.tile_volume = Some([depth, height, width]);
        self
    }

    /// `--device`.
    pub fn device(mut self, device: DeviceChoice) -> Self {
        self.device = device;
        self
    }

    /// Whether GPU devices paint with ipfn's generator kernel where it applies (default: yes,
    /// unless `IPFN_GPU_KERNEL=0`) or with burn's generator.
    pub fn gpu_kernel(mut self, on: bool) -> Self {
        self.gpu_kernel = on;
        self
    }

    /// Validates the options and prepares the evaluator.
    pub fn painter(self) -> Result<Painter> {
        if self.config.dims != 2 {
            return Err(input_error!(
                "this model has {} coordinate axes; image synthesis needs a 2D model (paint volumes with --depth)",
                self.config.dims
            ));
        }
        if !(self.zoom.is_finite() && self.zoom > 0.0) {
            return Err(input_error!(
                "--zoom {}: must be a positive number",
                self.zoom
            ));
        }
        if !(self.noise_scale.is_finite() && self.noise_scale > 0.0) {
            return Err(input_error!(
                "--noise-scale {}: must be a positive number",
                self.noise_scale
            ));
        }
        match (&self.guide, self.config.guidance) {
            (None, 1..) => {
                return Err(input_error!(
                    "this model is guided (trained with --guide); give --guide x, y, a,b,c or a grayscale image"
                ));
            }
            (Some(_), 0) => {
                return Err(input_error!(
                    "--guide: this model was trained without guidance; train with --guide to make a guided model"
                ));
            }
            (Some((guide, [h, w])), _) => guide.check_frame(*w, *h)?,
            (None, 0) => {}
        }
        if self.mirror.is_some_and(|m| m.contains(&0)) {
            return Err(input_error!("--mirror: tile size must be at least 1 pixel"));
        }
        let grid = PixelGrid::new(self.config.crop, self.zoom);
        let mut weights = self.weights;
        let mut field =
            LatentField::hashed(self.seed, 2, self.config.latent_dim).with_sigma(self.config.sigma);
        let noise_latent_scale = (self.config.latent_scale as f64 / self.noise_scale) as f32;
        let mut latent_scale = vec![noise_latent_scale; 2];
        let mut tile = None;
        if let Some(period) = self.tile {
            let adjustment = snap_to_tile(
                &period,
                grid.spacing,
                &mut weights.k,
                noise_latent_scale,
                &mut latent_scale,
            )?;
            field = field.periodic(&adjustment.lattice_period);
            tile = Some(adjustment);
        }
        let engine = Engine::new(
            weights,
            self.device.burn_device()?,
            self.device.chunk_points(),
            self.gpu_kernel,
        );
        Ok(Painter {
            engine,
            field,
            latent_scale,
            grid,
            offset: self.offset,
            channels: self.config.channels,
            tile,
            mirror: self.mirror,
            guide: self.guide,
        })
    }
}

/// Makes the generator exactly periodic with `period` pixels (or voxels) per axis: snaps K so
/// the tile spans a whole number of periods of every octave, and the latent lattice scale so it
/// spans whole lattice cells. Returns what moved; the caller wraps the lattice with
/// `lattice_period`.
fn snap_to_tile(
    period: &[usize],
    spacing: f64,
    k: &mut [f32],
    latent_scale_trained: f32,
    latent_scale: &mut [f32],
) -> Result<TileAdjustment> {
    if period.contains(&0) {
        return Err(input_error!("--tile: tile size must be at least 1 pixel"));
    }
    let k_trained = k.to_vec();
    let mut lattice_period = Vec::new();
    for axis in 0..period.len() {
        let span = period[axis] as f64 * spacing;
        let ka = k_trained[axis] as f64;
        let cycles = (span / (2.0 * ka.abs())).round().max(1.0);
        k[axis] = (span / (2.0 * cycles)).copysign(ka) as f32;
        let cells = (span * latent_scale_trained as f64).round().max(1.0);
        latent_scale[axis] = (cells / span) as f32;
        lattice_period.push(cells as i64);
    }
    Ok(TileAdjustment {
        k_trained,
        k_used: k.to_vec(),
        latent_scale_trained,
        latent_scale_used: latent_scale.to_vec(),
        lattice_period,
    })
}

/// A prepared synthesis: renders regions of the plane.
pub struct Painter {
    engine: Engine,
    field: LatentField,
    latent_scale: Vec<f32>,
    grid: PixelGrid,
    offset: [i64; 2],
    channels: usize,
    tile: Option<TileAdjustment>,
    mirror: Option<[usize; 2]>,
    guide: Option<(Guide, [usize; 2])>,
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

    /// What paints: `"fused cpu"`, `"kernel"` (the generator kernel on a GPU) or `"burn"`.
    pub fn engine(&self) -> &'static str {
        self.engine.name()
    }

    /// What `tile` changed, if it was asked for.
    pub fn tile_adjustment(&self) -> Option<&TileAdjustment> {
        self.tile.as_ref()
    }

    /// Renders the `width x height` region whose top-left pixel is `(x, y)` relative to the
    /// offset.
    ///
    /// # Shapes
    /// - output: `[height, width, channels]`, row-major, values in [-1, 1]
    pub fn render(&self, x: i64, y: i64, width: usize, height: usize) -> Vec<f32> {
        let Some([th, tw]) = self.mirror else {
            return self.render_plane(self.offset[0] + y, self.offset[1] + x, width, height);
        };
        // Mirror: gather from the painted quarter, which starts at the offset.
        let rows: Vec<i64> = (0..height as i64)
            .map(|i| mirror_source(y + i, th))
            .collect();
        let cols: Vec<i64> = (0..width as i64)
            .map(|j| mirror_source(x + j, tw))
            .collect();
        let (r0, r1) = (
            *rows.iter().min().unwrap_or(&0),
            *rows.iter().max().unwrap_or(&0),
        );
        let (c0, c1) = (
            *cols.iter().min().unwrap_or(&0),
            *cols.iter().max().unwrap_or(&0),
        );
        let (bh, bw) = ((r1 - r0 + 1) as usize, (c1 - c0 + 1) as usize);
        let source = self.render_plane(self.offset[0] + r0, self.offset[1] + c0, bw, bh);
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

    /// The guidance values of `count` pixels from the `start`-th pixel (row-major) of the region
    /// `width` wide whose top-left pixel is `(y0, x0)` in the plane; empty for an unguided model.
    fn guide_values(
        &self,
        y0: i64,
        x0: i64,
        width: usize,
        start: usize,
        count: usize,
        out: &mut Vec<f32>,
    ) {
        out.clear();
        if let Some((guide, [fh, fw])) = &self.guide {
            out.extend((start..start + count).map(|k| {
                let row = y0 + (k / width) as i64 - self.offset[0];
                let col = x0 + (k % width) as i64 - self.offset[1];
                guide.at(row, col, *fw, *fh)
            }));
        }
    }

    /// Renders `width x height` pixels whose top-left pixel is `(y0, x0)` in the plane.
    fn render_plane(&self, y0: i64, x0: i64, width: usize, height: usize) -> Vec<f32> {
        let total = width * height;
        let c = self.channels;
        match &self.engine {
            Engine::Fused(generator) => {
                let mut out = vec![0f32; total * c];
                out.par_chunks_mut(CHUNK_POINTS * c)
                    .enumerate()
                    .for_each_init(
                        || (Scratch::default(), Vec::new(), Vec::new()),
                        |(scratch, coords, g), (chunk, values)| {
                            let start = chunk * CHUNK_POINTS;
                            let count = values.len() / c;
                            self.grid
                                .region_coordinates(y0, x0, width, start, count, coords);
                            self.guide_values(y0, x0, width, start, count, g);
                            generator.eval(
                                coords,
                                &self.field,
                                &self.latent_scale,
                                g,
                                values,
                                scratch,
                            );
                        },
                    );
                out
            }
            gpu => {
                let ys: Vec<f32> = (0..height as i64)
                    .map(|r| self.grid.coordinate(y0 + r))
                    .collect();
                let xs: Vec<f32> = (0..width as i64)
                    .map(|col| self.grid.coordinate(x0 + col))
                    .collect();
                let mut g = Vec::new();
                gpu.render_on_device(
                    &self.field,
                    &self.latent_scale,
                    &[ys, xs],
                    c,
                    |start, count| {
                        self.guide_values(y0, x0, width, start, count, &mut g);
                        g.clone()
                    },
                )
                .expect("device engines render grids")
            }
        }
    }

    /// Renders `width x height` pixels into `path` in row bands of about `band_pixels` pixels,
    /// calling `progress(rows_done)` after each band. The file appears only when complete.
    pub fn write_image(
        &self,
        path: &Path,
        format: OutputFormat,
        width: usize,
        height: usize,
        band_pixels: usize,
        mut progress: impl FnMut(usize),
    ) -> Result<()> {
        let mut writer = ImageWriter::create(path, format, width, height, self.channels)?;
        let band_rows = (band_pixels / width.max(1)).clamp(1, height);
        let mut row = 0;
        while row < height {
            let rows = band_rows.min(height - row);
            let band = self.render(0, row as i64, width, rows);
            writer.write_rows(&band)?;
            row += rows;
            progress(row);
        }
        writer.finish()
    }
}

impl Painter {
    /// Writes one file per map of a map set, from bands rendered once for all channels: every
    /// map shows the same seed and region, aligned exactly. Normal maps are renormalised.
    pub fn write_maps(
        &self,
        outputs: &[crate::maps::MapOutput],
        width: usize,
        height: usize,
        band_pixels: usize,
        mut progress: impl FnMut(usize),
    ) -> Result<()> {
        let c = self.channels;
        let mut writers = outputs
            .iter()
            .map(|o| ImageWriter::create(&o.path, o.format, width, height, o.channels.len()))
            .collect::<Result<Vec<_>>>()?;
        let band_rows = (band_pixels / width.max(1)).clamp(1, height);
        let mut row = 0;
        while row < height {
            let rows = band_rows.min(height - row);
            let band = self.render(0, row as i64, width, rows);
            for (o, writer) in outputs.iter().zip(writers.iter_mut()) {
                let mc = o.channels.len();
                let mut map: Vec<f32> = band
                    .chunks_exact(c)
                    .flat_map(|px| px[o.channels.clone()].iter().copied())
                    .collect();
                if o.normal {
                    crate::maps::renormalise(&mut map, mc);
                }
                writer.write_rows(&map)?;
            }
            row += rows;
            progress(row);
        }
        for writer in writers {
            writer.finish()?;
        }
        Ok(())
    }
}

/// A prepared volume synthesis (a 3D model): renders boxes of the infinite volume in chunks (on
/// the CPU with the fused evaluator, or on a burn device), so memory is bounded by the slab
/// being written.
pub struct VolumePainter {
    engine: Engine,
    field: LatentField,
    latent_scale: Vec<f32>,
    grid: PixelGrid,
    channels: usize,
    tile: Option<TileAdjustment>,
    density: Option<DensityRamp>,
}

impl Synth {
    /// Prepares a volume synthesis for a 3D model (seed and zoom apply; the other options are
    /// for images).
    pub fn volume_painter(self) -> Result<VolumePainter> {
        if self.config.dims != 3 {
            return Err(input_error!(
                "this model has {} coordinate axes; volume synthesis (--depth) needs a 3D model",
                self.config.dims
            ));
        }
        if !(self.zoom.is_finite() && self.zoom > 0.0) {
            return Err(input_error!(
                "--zoom {}: must be a positive number",
                self.zoom
            ));
        }
        if !(self.noise_scale.is_finite() && self.noise_scale > 0.0) {
            return Err(input_error!(
                "--noise-scale {}: must be a positive number",
                self.noise_scale
            ));
        }
        if self.tile.is_some() || self.mirror.is_some() || self.guide.is_some() {
            return Err(input_error!(
                "--mirror and --guide are for images; volumes do not support them yet"
            ));
        }
        match (self.density, self.config.guidance) {
            (None, 1..) => {
                return Err(input_error!(
                    "this model was trained with --density; give --density D (e.g. 0.3) or A,B for a ramp along x"
                ));
            }
            (Some(_), 0) => {
                return Err(input_error!(
                    "--density: this model was trained without density control; train on the volume with --density"
                ));
            }
            _ => {}
        }
        let grid = PixelGrid::new(self.config.crop, self.zoom);
        let mut weights = self.weights;
        let mut field =
            LatentField::hashed(self.seed, 3, self.config.latent_dim).with_sigma(self.config.sigma);
        let noise_latent_scale = (self.config.latent_scale as f64 / self.noise_scale) as f32;
        let mut latent_scale = vec![noise_latent_scale; 3];
        let mut tile = None;
        if let Some(period) = self.tile_volume {
            let adjustment = snap_to_tile(
                &period,
                grid.spacing,
                &mut weights.k,
                noise_latent_scale,
                &mut latent_scale,
            )?;
            field = field.periodic(&adjustment.lattice_period);
            tile = Some(adjustment);
        }
        Ok(VolumePainter {
            channels: self.config.channels,
            field,
            latent_scale,
            grid,
            engine: Engine::new(
                weights,
                self.device.burn_device()?,
                self.device.chunk_points(),
                self.gpu_kernel,
            ),
            tile,
            density: self.density,
        })
    }
}

impl VolumePainter {
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// What paints: `"fused cpu"`, `"kernel"` (the generator kernel on a GPU) or `"burn"`.
    pub fn engine(&self) -> &'static str {
        self.engine.name()
    }

    /// What `tile_volume` changed, if it was asked for.
    pub fn tile_adjustment(&self) -> Option<&TileAdjustment> {
        self.tile.as_ref()
    }

    /// Renders the `depth x height x width` box whose first voxel is `(z, y, x)`.
    ///
    /// # Shapes
    /// - output: `[depth, height, width, channels]`, row-major, values in [-1, 1]
    pub fn render(&self, origin: [i64; 3], depth: usize, height: usize, width: usize) -> Vec<f32> {
        let generator = match &self.engine {
            Engine::Fused(generator) => generator,
            gpu => {
                let axis = |o: i64, n: usize| -> Vec<f32> {
                    (0..n as i64).map(|i| self.grid.coordinate(o + i)).collect()
                };
                let axes = [
                    axis(origin[0], depth),
                    axis(origin[1], height),
                    axis(origin[2], width),
                ];
                return gpu
                    .render_on_device(
                        &self.field,
                        &self.latent_scale,
                        &axes,
                        self.channels,
                        |start, count| self.densities(origin[2], width, start, count),
                    )
                    .expect("device engines render grids");
            }
        };
        let c = self.channels;
        // Chunks are groups of whole rows inside one depth slice, counted from the slice's first
        // row, so every slab decomposition of a box evaluates the same chunks: the same region
        // renders bit for bit alike however it is split into slabs.
        let rows_per_chunk = (CHUNK_POINTS / width.max(1)).clamp(1, height.max(1));
        let chunks_per_slice = height.div_ceil(rows_per_chunk);
        let mut out = vec![0f32; depth * height * width * c];
        let mut pieces: Vec<(usize, &mut [f32])> = Vec::new();
        for (z, slice) in out.chunks_mut(height * width * c).enumerate() {
            for (k, piece) in slice.chunks_mut(rows_per_chunk * width * c).enumerate() {
                pieces.push((z * chunks_per_slice + k, piece));
            }
        }
        pieces.into_par_iter().for_each_init(
            || (Scratch::default(), Vec::new()),
            |(scratch, coords), (index, values)| {
                let (z, k) = (index / chunks_per_slice, index % chunks_per_slice);
                let start = z * height * width + k * rows_per_chunk * width;
                let count = values.len() / c;
                self.grid
                    .box_coordinates(origin, height, width, start, count, coords);
                generator.eval(
                    coords,
                    &self.field,
                    &self.latent_scale,
                    &self.densities(origin[2], width, start, count),
                    values,
                    scratch,
                );
            },
        );
        out
    }

    /// The density input of voxels `start..start + count` (row-major) of a box `width` wide
    /// whose first column is `x0`; empty without density control.
    fn densities(&self, x0: i64, width: usize, start: usize, count: usize) -> Vec<f32> {
        match &self.density {
            Some(ramp) => (start..start + count)
                .map(|k| ramp.at(x0 + (k % width) as i64))
                .collect(),
            None => Vec::new(),
        }
    }

    /// The mesh of the zero level set of the first channel of the `depth x height x width`
    /// volume at the origin, extracted in chunks of about `slab_voxels` voxels and welded.
    pub fn mesh(
        &self,
        depth: usize,
        height: usize,
        width: usize,
        slab_voxels: usize,
    ) -> crate::mesh::Mesh {
        let mut builder = crate::mesh::MeshBuilder::new(height, width);
        self.for_each_mesh_chunk(depth, height, width, slab_voxels, |start, _, values| {
            builder.add_chunk(&self.first_channel(values), start);
            Ok(())
        })
        .expect("meshing alone does not fail");
        builder.finish()
    }

    /// Writes the `depth x height x width` volume at the origin to `.npy` (`[D, H, W, C]`, raw
    /// generator values), in slabs of whole depth slices of about `slab_voxels` voxels. With
    /// `mesh`, the same renders also feed the
    /// zero level set of the first channel into it, so every slice is rendered once (mesh
    /// chunks share two slices with the next one; those are rendered twice).
    pub fn write_npy(
        &self,
        path: &Path,
        depth: usize,
        height: usize,
        width: usize,
        slab_voxels: usize,
        mesh: Option<&mut crate::mesh::MeshBuilder>,
    ) -> Result<()> {
        let mut writer =
            crate::io::VolumeWriter::create(path, depth, height, width, self.channels)?;
        let slice = height * width * self.channels;
        match mesh {
            Some(builder) if depth >= 2 => {
                self.for_each_mesh_chunk(
                    depth,
                    height,
                    width,
                    slab_voxels,
                    |start, end, values| {
                        builder.add_chunk(&self.first_channel(values), start);
                        // The next chunk starts at end - 1: write up to it, or to the end.
                        let last = if end == depth - 1 { end + 1 } else { end - 1 };
                        writer.write_slab(&values[..(last - start) * slice])
                    },
                )?;
            }
            _ => {
                let slab = (slab_voxels / (height * width).max(1)).clamp(1, depth.max(1));
                let mut z = 0;
                while z < depth {
                    let n = slab.min(depth - z);
                    writer.write_slab(&self.render([z as i64, 0, 0], n, height, width))?;
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
        depth: usize,
        height: usize,
        width: usize,
        slab_voxels: usize,
        mut f: impl FnMut(usize, usize, &[f32]) -> Result<()>,
    ) -> Result<()> {
        let slices = (slab_voxels / (height * width).max(1)).max(1);
        for (start, end) in crate::mesh::chunk_starts(depth, slices) {
            f(
                start,
                end,
                &self.render([start as i64, 0, 0], end - start + 1, height, width),
            )?;
        }
        Ok(())
    }

    fn first_channel(&self, values: &[f32]) -> Vec<f32> {
        values.chunks_exact(self.channels).map(|v| v[0]).collect()
    }
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
fn render_on_device(
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

/// Default band size for [`Painter::write_image`]: 1 Mi pixels (12 MiB of RGB floats).
pub const DEFAULT_BAND_PIXELS: usize = 1 << 20;
