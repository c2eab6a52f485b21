//! Synthesis: paint any region of the infinite plane (or volume) with a trained generator.
//!
//! [`Synth`] is a builder whose options mirror `ipfn synth`'s flags one to one; it produces a
//! [`Painter`], which renders regions or streams a whole image or volume to disk in bands, so
//! memory is bounded by a band, not by the output.
//!
//! **Axis order.** Every position, size and period in this API is in array order, the order of
//! the values in memory and of the generator's coordinates: `[row, col]` for images (y before
//! x), `[depth, row, col]` for volumes. Outputs are row-major `[.., rows, cols, channels]`. Only
//! the command line speaks in `x,y` and `WxH`.

mod engine;
mod painter;
mod tile;

pub(crate) use engine::{Engine, paint_fused};
pub use painter::{DEFAULT_BAND_PIXELS, Painter};
pub use tile::TileAdjustment;

use crate::condition::{Condition, DensityRamp, Guide};
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::latent::LatentField;
use crate::sample::PixelGrid;

/// Builder for a synthesis; each method matches an `ipfn synth` flag.
#[derive(Debug, Clone)]
pub struct Synth {
    config: GeneratorConfig,
    weights: GeneratorWeights,
    seed: u64,
    zoom: f64,
    offset: Option<Vec<i64>>,
    tile: Option<Vec<usize>>,
    mirror: Option<[usize; 2]>,
    noise_scale: f64,
    condition: Option<Condition>,
    device: DeviceChoice,
    gpu_kernel: bool,
}

impl Synth {
    /// A synthesis with `model`'s config and weights: seed 0, zoom 1, offset 0, CPU.
    pub fn new(config: GeneratorConfig, weights: GeneratorWeights) -> Self {
        Self {
            config,
            weights,
            seed: 0,
            zoom: 1.0,
            offset: None,
            tile: None,
            mirror: None,
            noise_scale: 1.0,
            condition: None,
            device: DeviceChoice::Cpu,
            gpu_kernel: true,
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

    /// `--offset`: the first pixel of the output in the infinite plane, `[row, col]`.
    pub fn offset(mut self, origin: &[i64]) -> Self {
        self.offset = Some(origin.to_vec());
        self
    }

    /// `--tile`: make the output exactly periodic with this period per axis (`[rows, cols]`,
    /// or `[depth, rows, cols]` for a volume).
    pub fn tile(mut self, period: &[usize]) -> Self {
        self.tile = Some(period.to_vec());
        self
    }

    /// `--mirror`: a mirror-symmetric tile of `[rows, cols]` pixels. The top-left quarter is
    /// painted and reflected about the tile's centre lines, so the output is symmetric about
    /// both and repeats with the tile's period (paper §4.4). The plane outside the tile repeats it.
    pub fn mirror(mut self, size: [usize; 2]) -> Self {
        self.mirror = Some(size);
        self
    }

    /// `--noise-scale`: the latent lattice's cells are this many times larger relative to the
    /// pattern's period than in training (paper Fig. 5e): above 1, structure varies over larger
    /// regions; below 1, over smaller ones. 1 is as trained.
    pub fn noise_scale(mut self, scale: f64) -> Self {
        self.noise_scale = scale;
        self
    }

    /// `--guide`: the guidance field of a guided model, over the `[rows, cols]` output frame
    /// whose top-left pixel is the offset.
    pub fn guide(mut self, guide: Guide, frame: [usize; 2]) -> Self {
        self.condition = Some(Condition::Guide { guide, frame });
        self
    }

    /// `--density`: density control for a volume model trained with `--density`.
    pub fn density(mut self, ramp: DensityRamp) -> Self {
        self.condition = Some(Condition::Density(ramp));
        self
    }

    /// `--device`.
    pub fn device(mut self, device: DeviceChoice) -> Self {
        self.device = device;
        self
    }

    /// Whether GPU devices paint with ipfn's generator kernel where it applies (default: yes)
    /// or with burn's generator.
    pub fn gpu_kernel(mut self, on: bool) -> Self {
        self.gpu_kernel = on;
        self
    }

    /// Validates the options against the model and prepares the evaluator.
    pub fn painter(self) -> Result<Painter> {
        let dims = self.config.dims;
        self.check_options()?;
        let grid = PixelGrid::new(self.config.crop, self.zoom);
        let mut weights = self.weights;
        let mut field = LatentField::hashed(self.seed, dims, self.config.latent_dim)
            .with_sigma(self.config.sigma);
        let noise_latent_scale = (self.config.latent_scale as f64 / self.noise_scale) as f32;
        let mut latent_scale = vec![noise_latent_scale; dims];
        let mut tile = None;
        if let Some(period) = &self.tile {
            let adjustment = tile::snap_to_tile(
                period,
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
            offset: self.offset.unwrap_or_else(|| vec![0; dims]),
            channels: self.config.channels,
            tile,
            mirror: self.mirror,
            condition: self.condition,
        })
    }

    /// Every option checked against the model, once.
    fn check_options(&self) -> Result<()> {
        let dims = self.config.dims;
        if !(self.zoom.is_finite() && self.zoom > 0.0) {
            return Err(crate::setting_error!(
                "--zoom",
                self.zoom,
                "must be a positive number"
            ));
        }
        if !(self.noise_scale.is_finite() && self.noise_scale > 0.0) {
            return Err(crate::setting_error!(
                "--noise-scale",
                self.noise_scale,
                "must be a positive number"
            ));
        }
        let given = [
            self.offset.as_ref().map(Vec::len),
            self.tile.as_ref().map(Vec::len),
        ];
        for axes in given.into_iter().flatten() {
            check_axes(dims, axes)?;
        }
        if let Some(m) = self.mirror {
            if dims != 2 {
                return Err(input_error!(
                    "--mirror and --guide are for images; volumes do not support them yet"
                ));
            }
            if m.contains(&0) {
                return Err(input_error!("--mirror: tile size must be at least 1 pixel"));
            }
        }
        self.check_condition()
    }

    /// A conditioned model needs its condition, and an unconditioned one refuses it.
    fn check_condition(&self) -> Result<()> {
        let conditioned = self.config.guidance > 0;
        match (&self.condition, conditioned, self.config.dims) {
            (None, true, 2) => Err(input_error!(
                "this model is guided (trained with --guide); give --guide x, y, a,b,c or a grayscale image"
            )),
            (None, true, _) => Err(input_error!(
                "this model was trained with --density; give --density D (e.g. 0.3) or A,B for a ramp along x"
            )),
            (Some(Condition::Guide { .. }), _, 3) => Err(input_error!(
                "--mirror and --guide are for images; volumes do not support them yet"
            )),
            (Some(Condition::Guide { .. }), false, _) => Err(input_error!(
                "--guide: this model was trained without guidance; train with --guide to make a guided model"
            )),
            (Some(Condition::Density(_)), _, 2) => Err(input_error!(
                "--density is for volume models: give --size WxHxD, --depth or --slice"
            )),
            (Some(Condition::Density(_)), false, _) => Err(input_error!(
                "--density: this model was trained without density control; train on the volume with --density"
            )),
            (Some(Condition::Guide { guide, frame }), true, _) => {
                guide.check_frame(frame[1], frame[0])
            }
            _ => Ok(()),
        }
    }
}

/// An error unless a model of `model` coordinate axes can paint a box of `asked` axes: images
/// need a 2D model, volumes and slices a 3D one.
pub(crate) fn check_axes(model: usize, asked: usize) -> Result<()> {
    match asked {
        _ if asked == model => Ok(()),
        2 => Err(input_error!(
            "this model has {model} coordinate axes; image synthesis needs a 2D model (paint volumes with --depth)"
        )),
        _ => Err(input_error!(
            "this model has {model} coordinate axes; volume synthesis (--depth) needs a 3D model"
        )),
    }
}
