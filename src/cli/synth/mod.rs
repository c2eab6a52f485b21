//! `ipfn synth`: images, map sets, tiles, volumes, meshes and slices.

mod tile;
mod zarr;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::io::OutputFormat;
use crate::maps::MapOutput;
use crate::model::{ModelFile, choose_model, load_model};
use crate::synth::{DEFAULT_BAND_PIXELS, Synth};

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Model file (.ipfn). Default: the most recently written *.ipfn or runs/*/latest.ipfn in the
    /// working folder, else the shipped honeycomb model.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Output size: N (square), WxH, or WxHxD for a volume (as --depth D). Default 512.
    #[arg(long, value_name = "N|WxH|WxHxD", value_parser = parse_size)]
    pub size: Option<Size>,
    /// Output width in pixels (overrides --size).
    #[arg(long, value_name = "W")]
    pub width: Option<usize>,
    /// Output height in pixels (overrides --size).
    #[arg(long, value_name = "H")]
    pub height: Option<usize>,
    /// Depth in voxels: paint a volume (`[D, H, W, C]`, .npy or .raw) with a 3D model.
    #[arg(long, value_name = "D")]
    pub depth: Option<usize>,
    /// With a volume: also write the zero level set of the volume's first channel as a mesh
    /// (.obj or .ply), extracted slab by slab and welded.
    #[arg(long, value_name = "PATH")]
    pub mesh: Option<PathBuf>,
    /// The model is a solid texture (trained with `train --solid`): paint its volume
    /// (`--size WxHxD` or `--depth`, .npy) or, with --slice, one plane of it as an image.
    #[arg(long)]
    pub solid: bool,
    /// With a 3D model: write only the plane AXIS=INDEX of the WxHxD volume as an image, e.g.
    /// z=0 (an HxW plane), y=10 (DxW) or x=255 (DxH).
    #[arg(long, value_name = "AXIS=INDEX", value_parser = parse_slice)]
    pub slice: Option<(char, usize)>,
    /// For a volume model trained with --density: the density (mean |sdf| of the truncated
    /// SDF, e.g. 0.3) to paint, or A,B for a ramp from A at the first column to B at the last.
    #[arg(long, value_name = "D|A,B", value_parser = parse_density)]
    pub density: Option<(f32, f32)>,
    /// Seed of the latent field: each seed paints a different sample.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Magnification: 1 paints one output pixel per exemplar pixel seen in training; 2 paints
    /// the pattern twice as large.
    #[arg(long, default_value_t = 1.0)]
    pub zoom: f64,
    /// Top-left pixel of the output in the infinite plane, as X,Y. Adjacent offsets paint
    /// adjacent pieces of one larger image.
    #[arg(long, value_name = "X,Y", value_parser = parse_offset, allow_hyphen_values = true)]
    pub offset: Option<(i64, i64)>,
    /// Make the output tile seamlessly: K is snapped so the image spans whole periods, and the
    /// latent lattice wraps. Prints how far K moved.
    #[arg(long)]
    pub tile: bool,
    /// Make a mirror-symmetric tile: the top-left quarter is painted and reflected about the
    /// image's centre lines, so the output is symmetric and tiles by plain repetition.
    #[arg(long, conflicts_with = "tile")]
    pub mirror: bool,
    /// Size of the latent noise's cells relative to the pattern, as a multiple of training's:
    /// above 1, structure varies over larger regions; below 1, over smaller ones.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub noise_scale: f64,
    /// Guidance for a guided model: x, y, -x, -y, a line a,b,c (g = a·x + b·y + c over the
    /// output, x and y in [-1, 1]), or a grayscale image of the output's size (g = 2v - 1).
    #[arg(long, value_name = "LINE|IMAGE", allow_hyphen_values = true)]
    pub guide: Option<String>,
    /// Output file: .png (8 or 16 bit), .exr (float) or .npy (raw floats in [-1, 1], [H, W, C]);
    /// a volume: .npy ([D, H, W, C] float32) or .raw (bare little-endian float32). Either as
    /// .zarr: a chunked Zarr v3 store (see --chunk and --shard). Default synth.png, or synth.npy
    /// for a volume.
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out_path: Option<PathBuf>,
    /// `--out`, or the default for what is painted (set by `synth`).
    #[arg(skip)]
    pub out: PathBuf,
    /// Bits per channel for PNG output: 8 or 16. Default 8; a map set's maps keep their
    /// inputs' depth. For .zarr: 8 or 16 store unsigned integers, as PNG; default float32.
    #[arg(long)]
    pub bits: Option<u8>,
    /// For .zarr output: the side of a chunk on every axis (default 512 for images, 64 for
    /// volumes). Chunks are the unit of work of --shard.
    #[arg(long, value_name = "N")]
    pub chunk: Option<usize>,
    /// For .zarr output: render only the K-th of N disjoint sets of chunks (K from 0 to N-1),
    /// so N workers, on one machine or many, fill one store. Rerunning a shard skips the
    /// chunks it finished.
    #[arg(long, value_name = "K/N", conflicts_with = "shard_from_env")]
    pub shard: Option<crate::io::shard::Shard>,
    /// For .zarr output: take K of --shard from the environment: VAR, else
    /// JOB_COMPLETION_INDEX (Kubernetes Indexed Job), else SLURM_ARRAY_TASK_ID (less
    /// SLURM_ARRAY_TASK_MIN). N is --shards, else SLURM_ARRAY_TASK_COUNT.
    #[arg(long, value_name = "VAR", num_args = 0..=1, default_missing_value = "")]
    pub shard_from_env: Option<String>,
    /// With --shard-from-env: the number of shards N.
    #[arg(long, value_name = "N", requires = "shard_from_env")]
    pub shards: Option<usize>,
    /// Where to run: cpu (fused CPU evaluator), flex (burn CPU backend), wgpu (GPU) or cuda
    /// (NVIDIA GPU; a build with --features cuda).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// For a tile from `ipfn fit`: the level of detail, in stages (0 to the tile's stage
    /// count, fractions blend): the stages above it are faded out, an anti-aliased rendering
    /// for a smaller size. Default: every stage.
    #[arg(long, value_name = "T")]
    pub lod: Option<f32>,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `--size`: a width, height and optional depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    pub width: usize,
    pub height: usize,
    pub depth: Option<usize>,
}

fn parse_size(s: &str) -> std::result::Result<Size, String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let number = |p: &str| {
        p.trim()
            .parse::<usize>()
            .map_err(|_| format!("'{s}': expected N, WxH or WxHxD, e.g. 512 or 256x256x256"))
    };
    match parts.as_slice() {
        [n] => Ok(Size {
            width: number(n)?,
            height: number(n)?,
            depth: None,
        }),
        [w, h] => Ok(Size {
            width: number(w)?,
            height: number(h)?,
            depth: None,
        }),
        [w, h, d] => Ok(Size {
            width: number(w)?,
            height: number(h)?,
            depth: Some(number(d)?),
        }),
        _ => Err(format!(
            "'{s}': expected N, WxH or WxHxD, e.g. 512 or 256x256x256"
        )),
    }
}

fn parse_density(s: &str) -> std::result::Result<(f32, f32), String> {
    let err = || format!("'{s}': expected a density D or a ramp A,B, e.g. 0.3 or 0.35,0.2");
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|_| err()))
        .collect::<std::result::Result<_, _>>()?;
    match values[..] {
        [d] if d.is_finite() => Ok((d, d)),
        [a, b] if a.is_finite() && b.is_finite() => Ok((a, b)),
        _ => Err(err()),
    }
}

fn parse_slice(s: &str) -> std::result::Result<(char, usize), String> {
    let err = || format!("'{s}': expected AXIS=INDEX with AXIS x, y or z, e.g. z=0");
    let (axis, index) = s.split_once('=').ok_or_else(err)?;
    let axis = match axis.trim().to_ascii_lowercase().as_str() {
        "x" => 'x',
        "y" => 'y',
        "z" => 'z',
        _ => return Err(err()),
    };
    Ok((axis, index.trim().parse().map_err(|_| err())?))
}

fn parse_offset(s: &str) -> std::result::Result<(i64, i64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("'{s}': expected X,Y (e.g. 512,-256)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<i64>()
            .map_err(|_| format!("'{s}': expected two integers X,Y"))
    };
    Ok((parse(x)?, parse(y)?))
}

pub(super) fn synth(mut args: SynthArgs) -> Result<()> {
    let device: DeviceChoice = args.device.parse()?;
    device.burn_device()?; // a missing GPU or driver fails here, before any work
    let width = args.width.or(args.size.map(|s| s.width)).unwrap_or(512);
    let height = args.height.or(args.size.map(|s| s.height)).unwrap_or(512);
    if width == 0 || height == 0 {
        return Err(input_error!(
            "size {width}x{height}: width and height must be at least 1"
        ));
    }
    let depth = args.depth.or(args.size.and_then(|s| s.depth));
    let volume = depth.is_some() && args.slice.is_none();
    args.out = args
        .out_path
        .clone()
        .unwrap_or_else(|| PathBuf::from(if volume { "synth.npy" } else { "synth.png" }));
    if crate::io::extension(&args.out) == "zarr" {
        return zarr::synth_zarr(&args, device, [height, width], depth);
    }
    if args.shard.is_some() || args.shard_from_env.is_some() || args.chunk.is_some() {
        return Err(input_error!(
            "--shard, --shard-from-env and --chunk are for Zarr stores: give --out NAME.zarr"
        ));
    }
    match (args.slice, depth) {
        (Some(slice), _) => synth_slice(&args, [depth.unwrap_or(width), height, width], slice),
        (None, Some(depth)) => synth_volume(&args, width, height, depth),
        (None, None) => synth_image(&args, device, [height, width]),
    }
}

/// `ipfn synth` of an image (or a map set) from a 2D model, streamed to disk in row bands.
fn synth_image(args: &SynthArgs, device: DeviceChoice, [height, width]: [usize; 2]) -> Result<()> {
    check_image_flags(args)?;
    if let Some(bits) = args.bits.filter(|b| *b != 8 && *b != 16) {
        return Err(input_error!(
            "--bits {bits}: PNG output is 8 or 16 bits per channel"
        ));
    }
    // The model file is read once, and its kind decides what paints it.
    let model = match load_model(args.model.as_deref(), Path::new("."))? {
        ModelFile::Tile {
            checkpoint,
            description,
        } => return tile::synth_tile(args, device, &checkpoint, &description),
        ModelFile::Generator(model) => model,
    };
    if args.lod.is_some() {
        return Err(input_error!(
            "--lod is for tiles fitted by `ipfn fit`; {} is a generator",
            model.description
        ));
    }
    let format = OutputFormat::from_path(&args.out, args.bits.unwrap_or(8))?;
    crate::io::check_destination(&args.out)?;
    let outputs = match &model.maps {
        Some(set) => set.outputs(&args.out, args.bits)?,
        None => vec![MapOutput {
            path: args.out.clone(),
            format,
            channels: 0..model.config.channels,
            normal: false,
        }],
    };
    crate::maps::check_outputs(&outputs, width, height)?;
    let painter =
        image_synth(args, device, model.config, model.weights, [height, width])?.painter()?;
    painter.check_axes(2)?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    say_model(&say, &model.description, &painter);
    let start = Instant::now();
    let bar = row_bar(!args.quiet && width * height >= 1 << 22, height);
    painter.write_maps(&outputs, [height, width], DEFAULT_BAND_PIXELS, |rows| {
        if let Some(bar) = &bar {
            bar.set_position(rows as u64);
        }
    })?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let written: Vec<String> = outputs
        .iter()
        .map(|o| o.path.display().to_string())
        .collect();
    say(format!(
        "wrote {} ({width}x{height}, seed {}, {device:?}) in {:.2} s",
        written.join(", "),
        args.seed,
        start.elapsed().as_secs_f64()
    ));
    Ok(())
}

/// Says which model paints and, for a tile, how far K moved.
fn say_model(say: &impl Fn(String), model: &str, painter: &crate::synth::Painter) {
    say(format!("model: {model}"));
    if let Some(t) = painter.tile_adjustment() {
        say(t.describe());
    }
}

/// An error for the flags that only volumes take, given for an image.
fn check_image_flags(args: &SynthArgs) -> Result<()> {
    let volume_only = [
        (
            args.mesh.is_some(),
            "--mesh needs a volume: give --size WxHxD or --depth with a 3D model",
        ),
        (
            args.solid,
            "--solid paints a volume or a plane: give --size WxHxD, --depth or --slice",
        ),
        (
            args.density.is_some(),
            "--density is for volume models: give --size WxHxD, --depth or --slice",
        ),
    ];
    if let Some((_, message)) = volume_only.iter().find(|(given, _)| *given) {
        return Err(input_error!("{message}"));
    }
    Ok(())
}

/// The `Synth` of a 2D model with the image flags: seed, zoom, offset, noise scale, device,
/// tile, mirror and guide.
fn image_synth(
    args: &SynthArgs,
    device: DeviceChoice,
    config: GeneratorConfig,
    weights: GeneratorWeights,
    [height, width]: [usize; 2],
) -> Result<Synth> {
    let (x, y) = args.offset.unwrap_or((0, 0));
    let mut builder = Synth::new(config, weights)
        .seed(args.seed)
        .zoom(args.zoom)
        .offset(&[y, x])
        .noise_scale(args.noise_scale)
        .device(device)
        .gpu_kernel(gpu_kernel_from_env());
    if args.tile {
        builder = builder.tile(&[height, width]);
    }
    if args.mirror {
        builder = builder.mirror([height, width]);
    }
    if let Some(g) = &args.guide {
        builder = builder.guide(crate::condition::Guide::parse_flag(g)?, [height, width]);
    }
    Ok(builder)
}

/// A progress bar over `rows` rows, on a terminal when `show`.
fn row_bar(show: bool, rows: usize) -> Option<indicatif::ProgressBar> {
    (show && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(rows as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} rows  {elapsed} (eta {eta})",
            )
            .expect("valid progress template"),
        );
        bar
    })
}

/// `ipfn synth --slice AXIS=I`: one plane of a 3D model's `depth x height x width` volume as
/// an image.
fn synth_slice(
    args: &SynthArgs,
    [depth, height, width]: [usize; 3],
    slice: (char, usize),
) -> Result<()> {
    if depth == 0 {
        return Err(input_error!("--depth 0: must be at least 1"));
    }
    if args.mirror || args.guide.is_some() || args.tile || args.mesh.is_some() {
        return Err(input_error!(
            "--slice writes one plane: --tile, --mirror, --guide and --mesh do not apply"
        ));
    }
    if args.offset.is_some() {
        return Err(input_error!(
            "--slice: the plane is placed by AXIS=INDEX in the volume; --offset does not apply"
        ));
    }
    let (axis, index) = slice;
    // The plane's origin in the volume and its box (one voxel thick across `axis`).
    let (origin, [d, h, w], extent) = match axis {
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
    let (rows, cols) = match axis {
        'z' => (height, width),
        'y' => (depth, width),
        _ => (depth, height),
    };
    let format = OutputFormat::from_path(&args.out, args.bits.unwrap_or(8))?;
    crate::io::check_destination(&args.out)?;
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    if model.config.dims != 3 {
        return Err(input_error!(
            "--slice: this model has {} coordinate axes; slices need a 3D model (train --solid, or a volume)",
            model.config.dims
        ));
    }
    format.check_size(&args.out, cols, rows, model.config.channels)?;
    let start = Instant::now();
    let painter = volume_synth(args, model.config, model.weights, width)?.painter()?;
    painter.check_axes(3)?;
    let values = painter.render(&origin, &[d, h, w]);
    let mut writer =
        crate::io::ImageWriter::create(&args.out, format, cols, rows, painter.channels())?;
    writer.write_rows(&values)?;
    writer.finish()?;
    if !args.quiet {
        eprintln!(
            "model: {}\nwrote {} (slice {axis}={index} of {width}x{height}x{depth}: {cols}x{rows}, seed {}) in {:.2} s",
            model.description,
            args.out.display(),
            args.seed,
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// The `Synth` of a 3D model with the flags volumes and slices share: seed, zoom, noise scale,
/// device and a density ramp along columns `0..width`.
/// `IPFN_GPU_KERNEL=0` paints on a GPU with burn's generator instead of ipfn's kernel (to
/// compare the two, as `benches/gpu.sh` does).
fn gpu_kernel_from_env() -> bool {
    std::env::var("IPFN_GPU_KERNEL").map_or(true, |v| v != "0")
}

fn volume_synth(
    args: &SynthArgs,
    config: GeneratorConfig,
    weights: GeneratorWeights,
    width: usize,
) -> Result<Synth> {
    let mut builder = Synth::new(config, weights)
        .seed(args.seed)
        .zoom(args.zoom)
        .noise_scale(args.noise_scale)
        .device(args.device.parse()?)
        .gpu_kernel(gpu_kernel_from_env());
    if let Some((from, to)) = args.density {
        builder = builder.density(crate::condition::DensityRamp { from, to, width });
    }
    Ok(builder)
}

/// An error for the flags that only images take, given for a volume.
fn check_volume_flags(args: &SynthArgs) -> Result<()> {
    if args.mirror || args.guide.is_some() {
        return Err(input_error!(
            "--mirror and --guide are for images; volumes do not support them yet"
        ));
    }
    if args.offset.is_some() {
        return Err(input_error!(
            "--offset is for images; a volume starts at the origin"
        ));
    }
    Ok(())
}

/// `ipfn synth --depth D`: a volume from a 3D model, streamed to .npy in slabs.
fn synth_volume(args: &SynthArgs, width: usize, height: usize, depth: usize) -> Result<()> {
    if depth == 0 {
        return Err(input_error!("--depth 0: must be at least 1"));
    }
    check_volume_flags(args)?;
    if args.bits.is_some() {
        return Err(input_error!(
            "--bits is for images and Zarr stores; a .npy or .raw volume is written as float32"
        ));
    }
    let format = crate::io::VolumeFormat::from_path(&args.out)?;
    crate::io::check_destination(&args.out)?;
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    crate::io::check_volume_size(&args.out, depth, height, width, model.config.channels)?;
    let mut builder = volume_synth(args, model.config, model.weights, width)?;
    if args.tile {
        builder = builder.tile(&[depth, height, width]);
    }
    let painter = builder.painter()?;
    painter.check_axes(3)?;
    if let (Some(t), false) = (painter.tile_adjustment(), args.quiet) {
        eprintln!("{}", t.describe());
    }
    if let Some(mesh) = &args.mesh {
        crate::mesh::MeshFormat::from_path(mesh)?;
        crate::io::check_destination(mesh)?;
    }
    let start = Instant::now();
    let mut builder = args
        .mesh
        .as_ref()
        .map(|_| crate::mesh::MeshBuilder::new(height, width));
    painter.write_volume(
        &args.out,
        [depth, height, width],
        DEFAULT_BAND_PIXELS,
        builder.as_mut(),
    )?;
    if let (Some(path), Some(builder)) = (&args.mesh, builder) {
        let mesh = builder.finish();
        crate::mesh::write_mesh(&mesh, path)?;
        if !args.quiet {
            eprintln!(
                "wrote {}: {} vertices, {} triangles",
                path.display(),
                mesh.positions.len(),
                mesh.triangles.len()
            );
        }
    }
    if !args.quiet {
        let layout = match format {
            crate::io::VolumeFormat::Npy => String::new(),
            crate::io::VolumeFormat::Raw => format!(
                ", little-endian float32 [D, H, W, C] = [{depth}, {height}, {width}, {}], no header",
                painter.channels()
            ),
        };
        eprintln!(
            "model: {}\nwrote {} ({width}x{height}x{depth} voxels, {} channels, seed {}{layout}) in {:.2} s",
            model.description,
            args.out.display(),
            painter.channels(),
            args.seed,
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
