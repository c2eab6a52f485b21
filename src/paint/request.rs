//! `ipfn synth` as a library request: every flag typed ([`SynthRequest`]), every combination
//! checked against the model once ([`SynthRequest::plan`]), and a [`SynthPlan`] that paints into
//! files ([`SynthPlan::write`]) or into memory ([`SynthPlan::render`]) through the same band
//! loop, so both hold the same values. The command line and the Python package only fill the
//! request; what is allowed, what is the default and what is painted is decided here.
//!
//! The request speaks as the command line does (`x, y` offsets, `W`, `H`, `D` sizes); the plan
//! and the painters below it speak in array order (`[row, col]`).

use std::path::{Path, PathBuf};

use super::plan::{ImagePainter, ImageTarget, SynthPlan, Target};
use crate::condition::{DensityRamp, Guide};
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::fit::{PeriodicNet, TilePainter};
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::io::shard::Shard;
use crate::io::{OutputFormat, VolumeFormat};
use crate::maps::{MapOutput, MapSet};
use crate::model::ModelFile;
use crate::synth::{Painter, Synth};

/// Side of the image painted when no size is given.
pub const DEFAULT_SIZE: usize = 512;

/// `--size`: a width, height and optional depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    pub width: usize,
    pub height: usize,
    pub depth: Option<usize>,
}

/// Where a Zarr store's chunks come from: `--chunk`, `--shard`, `--shard-from-env`, `--shards`.
#[derive(Debug, Clone, Default)]
pub struct ZarrOptions {
    pub chunk: Option<usize>,
    pub shard: Option<Shard>,
    /// The variable naming this worker's shard (empty: the scheduler's usual ones).
    pub shard_from_env: Option<String>,
    pub shards: Option<usize>,
}

impl ZarrOptions {
    fn given(&self) -> bool {
        self.chunk.is_some() || self.shard.is_some() || self.shard_from_env.is_some()
    }

    /// The shard this worker renders: `shard`, the environment's, or the whole array.
    pub fn shard(&self, env: impl Fn(&str) -> Option<String>) -> Result<Shard> {
        match (&self.shard, &self.shard_from_env) {
            (Some(shard), _) => Ok(*shard),
            (None, Some(var)) => {
                let var = (!var.is_empty()).then_some(var.as_str());
                Shard::from_env(var, self.shards, env)
            }
            (None, None) => Ok(Shard::ALL),
        }
    }
}

/// What to paint, one field per `ipfn synth` flag (the model is given to [`SynthRequest::plan`]).
#[derive(Debug, Clone)]
pub struct SynthRequest {
    /// `--size`; for a fitted tile, the pixels of one period.
    pub size: Option<Size>,
    pub width: Option<usize>,
    pub height: Option<usize>,
    pub depth: Option<usize>,
    /// `--slice AXIS=INDEX`: one plane of a 3D model's volume.
    pub slice: Option<(char, usize)>,
    pub solid: bool,
    /// `--mesh`: also write the volume's zero level set here.
    pub mesh: Option<PathBuf>,
    /// `--density A,B`: a ramp from A at the first column to B at the last.
    pub density: Option<(f32, f32)>,
    pub seed: u64,
    pub zoom: f64,
    /// `--offset X,Y`: the output's top-left pixel in the plane.
    pub offset: Option<(i64, i64)>,
    pub tile: bool,
    pub mirror: bool,
    pub noise_scale: f64,
    /// `--guide`: a line, an axis or a grayscale image's path.
    pub guide: Option<String>,
    /// `--out`; default `synth.png`, or `synth.npy` for a volume.
    pub out: Option<PathBuf>,
    /// `--preview`: a map set's material lit, as an 8-bit PNG (up to its top-left 1024²).
    pub preview: Option<PathBuf>,
    pub bits: Option<u8>,
    pub zarr: ZarrOptions,
    pub device: DeviceChoice,
    /// `--lod`: a fitted tile's level of detail, in stages.
    pub lod: Option<f32>,
    /// Whether GPUs paint with ipfn's generator kernel (else burn's), as [`Synth::gpu_kernel`].
    pub gpu_kernel: bool,
}

impl Default for SynthRequest {
    fn default() -> Self {
        Self {
            size: None,
            width: None,
            height: None,
            depth: None,
            slice: None,
            solid: false,
            mesh: None,
            density: None,
            seed: 0,
            zoom: 1.0,
            offset: None,
            tile: false,
            mirror: false,
            noise_scale: 1.0,
            guide: None,
            out: None,
            preview: None,
            bits: None,
            zarr: ZarrOptions::default(),
            device: DeviceChoice::Cpu,
            lod: None,
            gpu_kernel: true,
        }
    }
}

impl SynthRequest {
    /// `[width, height]` of the output: `--width`/`--height`, else `--size`, else 512.
    fn extent(&self) -> Result<[usize; 2]> {
        let width = self
            .width
            .or(self.size.map(|s| s.width))
            .unwrap_or(DEFAULT_SIZE);
        let height = self.height.or(self.size.map(|s| s.height));
        let height = height.unwrap_or(DEFAULT_SIZE);
        if width == 0 || height == 0 {
            return Err(input_error!(
                "size {width}x{height}: width and height must be at least 1"
            ));
        }
        Ok([width, height])
    }

    fn depth(&self) -> Option<usize> {
        self.depth.or(self.size.and_then(|s| s.depth))
    }

    /// Whether a volume is painted (a depth and no slice).
    pub fn is_volume(&self) -> bool {
        self.depth().is_some() && self.slice.is_none()
    }

    /// `--out`, else the default for what is painted.
    pub fn out_path(&self) -> PathBuf {
        let default = if self.is_volume() {
            "synth.npy"
        } else {
            "synth.png"
        };
        self.out.clone().unwrap_or_else(|| PathBuf::from(default))
    }

    /// Whether the output is a Zarr store (painted by [`SynthRequest::zarr_painter`]).
    pub fn is_zarr(&self) -> bool {
        crate::io::extension(&self.out_path()) == "zarr"
    }

    /// Checks the request against `model` and prepares its painter.
    pub fn plan(&self, model: &ModelFile) -> Result<SynthPlan> {
        self.device.burn_device()?; // a missing GPU or driver fails here, before any work
        let [width, height] = self.extent()?;
        if self.is_zarr() {
            return Err(crate::file_error!(
                &self.out_path(),
                "a Zarr store is painted chunk by chunk (the zarr painter), not as one plan",
            ));
        }
        if self.zarr.given() {
            return Err(input_error!(
                "--shard, --shard-from-env and --chunk are for Zarr stores: give --out NAME.zarr"
            ));
        }
        let target = match (self.slice, self.depth()) {
            (Some(slice), depth) => {
                let volume = [depth.unwrap_or(width), height, width];
                self.slice_target(model, volume, slice)?
            }
            (None, Some(depth)) => self.volume_target(model, [depth, height, width])?,
            (None, None) => self.image_target(model, [height, width])?,
        };
        Ok(SynthPlan {
            model: model.description().to_string(),
            out: self.out_path(),
            seed: self.seed,
            device: self.device,
            preview: self.preview_of(model)?,
            target,
        })
    }

    /// `--preview`: where the material's picture goes, and the maps it is lit from.
    fn preview_of(&self, model: &ModelFile) -> Result<Option<(PathBuf, MapSet)>> {
        let Some(path) = &self.preview else {
            return Ok(None);
        };
        crate::maps::preview::check_path(path)?;
        let set = match model {
            _ if self.slice.is_some() || self.depth().is_some() => None,
            ModelFile::Generator(m) => m.maps.clone(),
            ModelFile::Tile {
                checkpoint,
                description,
                ..
            } => MapSet::read_from(checkpoint, Path::new(description))?,
        };
        match set {
            Some(set) => Ok(Some((path.clone(), set))),
            None => Err(input_error!(
                "--preview lights a material's maps (colour, normal, roughness, ...): {} paints no map set; drop --preview",
                model.description()
            )),
        }
    }

    fn image_target(&self, model: &ModelFile, size: [usize; 2]) -> Result<Target> {
        self.check_image_flags()?;
        if let Some(bits) = self.bits.filter(|b| *b != 8 && *b != 16) {
            return Err(crate::setting_error!(
                "--bits",
                bits,
                "PNG output is 8 or 16 bits per channel"
            ));
        }
        let model = match model {
            ModelFile::Tile {
                checkpoint,
                description,
                ..
            } => return self.tile_target(checkpoint, description),
            ModelFile::Generator(model) => model,
        };
        if self.lod.is_some() {
            return Err(input_error!(
                "--lod is for tiles fitted by `ipfn fit`; {} is a generator",
                model.description
            ));
        }
        let (outputs, names) = self.outputs(model.maps.as_ref(), model.config.channels)?;
        check_sizes(&outputs, size)?;
        let synth = self.image_synth(model.config.clone(), model.weights.clone(), size)?;
        let painter = synth.painter()?;
        painter.check_axes(2)?;
        Ok(Target::Image(ImageTarget {
            painter: ImagePainter::Model(painter),
            origin: [0, 0],
            size,
            outputs,
            names,
        }))
    }

    /// The files an image (or each map of a map set) is written to, and the maps' names.
    fn outputs(
        &self,
        maps: Option<&MapSet>,
        channels: usize,
    ) -> Result<(Vec<MapOutput>, Vec<String>)> {
        let out = self.out_path();
        let format = OutputFormat::from_path(&out, self.bits.unwrap_or(8))?;
        Ok(match maps {
            Some(set) => (
                set.outputs(&out, self.bits)?,
                set.maps.iter().map(|m| m.name.clone()).collect(),
            ),
            None => (
                vec![MapOutput {
                    path: out,
                    format,
                    channels: 0..channels,
                    normal: false,
                    directx: false,
                }],
                Vec::new(),
            ),
        })
    }

    fn tile_target(
        &self,
        checkpoint: &crate::checkpoint::Checkpoint,
        model: &str,
    ) -> Result<Target> {
        let refused = [
            (self.mirror, "--mirror"),
            (self.guide.is_some(), "--guide"),
            (
                self.zoom != 1.0,
                "--zoom (give --size: the pixels of one period)",
            ),
            (self.noise_scale != 1.0, "--noise-scale"),
            (
                self.depth().is_some() || self.slice.is_some() || self.solid,
                "volumes",
            ),
            (self.mesh.is_some() || self.density.is_some(), "volumes"),
        ];
        if let Some((_, what)) = refused.iter().find(|(given, _)| *given) {
            return Err(input_error!(
                "{model}: a tile fitted by `ipfn fit` takes no {what}"
            ));
        }
        let net = PeriodicNet::read_from(checkpoint)?;
        let resolution = self
            .size
            .map(|s| [s.height, s.width])
            .unwrap_or(net.shape.period);
        let size = [
            self.height.unwrap_or(resolution[0]),
            self.width.unwrap_or(resolution[1]),
        ];
        if resolution.contains(&0) || size.contains(&0) {
            return Err(input_error!(
                "size {}x{}: width and height must be at least 1",
                size[1],
                size[0]
            ));
        }
        let stages = net.stages() as f32;
        let lod = self.lod.unwrap_or(stages);
        if !(0.0..=stages).contains(&lod) {
            return Err(crate::setting_error!(
                "--lod",
                lod,
                "this tile has {stages} stages; give 0 to {stages}"
            ));
        }
        let maps = MapSet::read_from(checkpoint, Path::new(model))?;
        let (outputs, names) = self.outputs(maps.as_ref(), net.shape.channels)?;
        check_sizes(&outputs, size)?;
        let (x, y) = self.offset.unwrap_or((0, 0));
        let painter = TilePainter {
            net,
            resolution,
            lod,
            device: self.device.burn_device()?,
        };
        Ok(Target::Image(ImageTarget {
            painter: ImagePainter::Tile(painter),
            origin: [y, x],
            size,
            outputs,
            names,
        }))
    }

    fn slice_target(
        &self,
        model: &ModelFile,
        [depth, height, width]: [usize; 3],
        (axis, index): (char, usize),
    ) -> Result<Target> {
        if depth == 0 {
            return Err(input_error!("--depth 0: must be at least 1"));
        }
        if self.mirror || self.guide.is_some() || self.tile || self.mesh.is_some() {
            return Err(input_error!(
                "--slice writes one plane: --tile, --mirror, --guide and --mesh do not apply"
            ));
        }
        if self.offset.is_some() {
            return Err(input_error!(
                "--slice: the plane is placed by AXIS=INDEX in the volume; --offset does not apply"
            ));
        }
        // The plane's origin in the volume and its box (one voxel thick across `axis`).
        let (origin, shape, extent) = match axis {
            'z' => ([index as i64, 0, 0], [1, height, width], depth),
            'y' => ([0, index as i64, 0], [depth, 1, width], height),
            _ => ([0, 0, index as i64], [depth, height, 1], width),
        };
        if index >= extent {
            return Err(input_error!(
                "--slice {axis}={index}: the volume has {extent} voxels along {axis} (indices 0 to {})",
                extent - 1
            ));
        }
        // The image: rows and columns are the two other axes in (z, y, x) order.
        let image = match axis {
            'z' => [height, width],
            'y' => [depth, width],
            _ => [depth, height],
        };
        let out = self.out_path();
        let format = OutputFormat::from_path(&out, self.bits.unwrap_or(8))?;
        let model = model.generator()?;
        if model.config.dims != 3 {
            return Err(input_error!(
                "--slice: this model has {} coordinate axes; slices need a 3D model (train --solid, or a volume)",
                model.config.dims
            ));
        }
        format.check_size(&out, image[1], image[0], model.config.channels)?;
        let painter = self
            .volume_synth(model.config.clone(), model.weights.clone(), width)?
            .painter()?;
        painter.check_axes(3)?;
        Ok(Target::Slice {
            painter,
            origin,
            shape,
            image,
            format,
            what: format!("slice {axis}={index} of {width}x{height}x{depth}"),
        })
    }

    fn volume_target(&self, model: &ModelFile, shape: [usize; 3]) -> Result<Target> {
        let [depth, height, width] = shape;
        if depth == 0 {
            return Err(input_error!("--depth 0: must be at least 1"));
        }
        self.check_volume_flags()?;
        if self.bits.is_some() {
            return Err(input_error!(
                "--bits is for images and Zarr stores; a .npy or .raw volume is written as float32"
            ));
        }
        let out = self.out_path();
        let format = VolumeFormat::from_path(&out)?;
        let model = model.generator()?;
        crate::io::check_volume_size(&out, depth, height, width, model.config.channels)?;
        let mut synth = self.volume_synth(model.config.clone(), model.weights.clone(), width)?;
        if self.tile {
            synth = synth.tile(&shape);
        }
        let painter = synth.painter()?;
        painter.check_axes(3)?;
        if let Some(mesh) = &self.mesh {
            crate::mesh::MeshFormat::from_path(mesh)?;
        }
        Ok(Target::Volume {
            painter,
            shape,
            format,
            mesh: self.mesh.clone(),
        })
    }

    /// The painter of a Zarr store of `model` (image flags for a 2D model, volume flags for a
    /// 3D one), the array's shape in array order, and the chunk side.
    pub fn zarr_painter(&self, model: &ModelFile) -> Result<(Painter, Vec<usize>, usize)> {
        use crate::io::zarr::{DEFAULT_IMAGE_CHUNK, DEFAULT_VOLUME_CHUNK};
        if self.preview.is_some() {
            return Err(crate::file_error!(
                &self.out_path(),
                "--preview lights a map set's maps, which are written as .png or .exr, not as a Zarr store; drop --preview",
            ));
        }
        if self.slice.is_some() || self.mesh.is_some() {
            return Err(crate::file_error!(
                &self.out_path(),
                "--slice and --mesh write an image or a mesh, not a Zarr store: drop them, or give a .png or .obj",
            ));
        }
        let model = model.generator()?;
        if model.maps.is_some() {
            return Err(crate::file_error!(
                &self.out_path(),
                "a map set is written as one image per map; give a .png or .exr --out",
            ));
        }
        let [width, height] = self.extent()?;
        let (config, weights) = (model.config.clone(), model.weights.clone());
        let (painter, shape, chunk) = match self.depth() {
            None => {
                self.check_image_flags()?;
                let synth = self.image_synth(config, weights, [height, width])?;
                (synth.painter()?, vec![height, width], DEFAULT_IMAGE_CHUNK)
            }
            Some(depth) => {
                self.check_volume_flags()?;
                let mut synth = self.volume_synth(config, weights, width)?;
                if self.tile {
                    synth = synth.tile(&[depth, height, width]);
                }
                (
                    synth.painter()?,
                    vec![depth, height, width],
                    DEFAULT_VOLUME_CHUNK,
                )
            }
        };
        painter.check_axes(shape.len())?;
        Ok((painter, shape, self.zarr.chunk.unwrap_or(chunk)))
    }

    /// An error for the flags that only volumes take, given for an image.
    fn check_image_flags(&self) -> Result<()> {
        let volume_only = [
            (
                self.mesh.is_some(),
                "--mesh needs a volume: give --size WxHxD or --depth with a 3D model",
            ),
            (
                self.solid,
                "--solid paints a volume or a plane: give --size WxHxD, --depth or --slice",
            ),
            (
                self.density.is_some(),
                "--density is for volume models: give --size WxHxD, --depth or --slice",
            ),
        ];
        match volume_only.iter().find(|(given, _)| *given) {
            Some((_, message)) => Err(input_error!("{message}")),
            None => Ok(()),
        }
    }

    /// An error for the flags that only images take, given for a volume.
    fn check_volume_flags(&self) -> Result<()> {
        if self.mirror || self.guide.is_some() {
            return Err(input_error!(
                "--mirror and --guide are for images; volumes do not support them yet"
            ));
        }
        if self.offset.is_some() {
            return Err(input_error!(
                "--offset is for images; a volume starts at the origin"
            ));
        }
        Ok(())
    }

    /// The `Synth` of a 2D model: seed, zoom, offset, noise scale, device, tile, mirror, guide.
    fn image_synth(
        &self,
        config: GeneratorConfig,
        weights: GeneratorWeights,
        frame: [usize; 2],
    ) -> Result<Synth> {
        let (x, y) = self.offset.unwrap_or((0, 0));
        let mut synth = self.common_synth(config, weights).offset(&[y, x]);
        if self.tile {
            synth = synth.tile(&frame);
        }
        if self.mirror {
            synth = synth.mirror(frame);
        }
        if let Some(g) = &self.guide {
            synth = synth.guide(Guide::parse_flag(g)?, frame);
        }
        Ok(synth)
    }

    /// The `Synth` of a 3D model: the shared flags and a density ramp along `0..width`.
    fn volume_synth(
        &self,
        config: GeneratorConfig,
        weights: GeneratorWeights,
        width: usize,
    ) -> Result<Synth> {
        let mut synth = self.common_synth(config, weights);
        if let Some((from, to)) = self.density {
            synth = synth.density(DensityRamp { from, to, width });
        }
        Ok(synth)
    }

    fn common_synth(&self, config: GeneratorConfig, weights: GeneratorWeights) -> Synth {
        Synth::new(config, weights)
            .seed(self.seed)
            .zoom(self.zoom)
            .noise_scale(self.noise_scale)
            .device(self.device)
            .gpu_kernel(self.gpu_kernel)
    }
}

/// Every output's size checked against its format's limits.
fn check_sizes(outputs: &[MapOutput], [height, width]: [usize; 2]) -> Result<()> {
    outputs.iter().try_for_each(|o| {
        o.format
            .check_size(&o.path, width, height, o.channels.len())
    })
}
