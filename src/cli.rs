//! The `ipfn` command line: clap definitions and what each subcommand does.
//!
//! Every subcommand is a thin layer over the library: `synth` over [`crate::synth::Synth`],
//! `import` over [`crate::checkpoint::import_pytorch`].

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, Parser, Subcommand};

use crate::checkpoint::{self, Checkpoint};
use crate::error::Result;
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::io::OutputFormat;
use crate::maps::{MapFiles, MapSet};
use crate::synth::{DEFAULT_BAND_PIXELS, DeviceChoice, Synth};
use crate::train::{ExemplarSource, TrainConfig, Trainer};

/// The honeycomb generator published by the authors of IPFN (MIT), converted with
/// `ipfn import`; see `exemplars/README.md`.
pub const SHIPPED_HONEYCOMB: &[u8] = include_bytes!("../exemplars/honeycomb.ipfn");

#[derive(Debug, Parser)]
#[command(
    name = "ipfn",
    version,
    about = "Implicit Periodic Field Network: learn a pattern from one exemplar, paint it at any size",
    long_about = "Implicit Periodic Field Network (Chen et al., CVPR 2022).\n\n\
        `ipfn train` learns a pattern from one exemplar (an image, or a set of material maps). \
        `ipfn synth` paints new, varied, optionally seamless versions of it at any size, on the \
        CPU or a GPU. `ipfn eval` scores a model (SIFID, seams, period); `ipfn bench` times this \
        machine; `ipfn import` converts a generator trained by the authors' PyTorch code. With no \
        model given, synth uses the most recent model in the working folder, else the shipped \
        honeycomb model."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Paint a sample of a trained pattern (PNG, EXR or NPY).
    Synth(SynthArgs),
    /// Learn a pattern from one exemplar (PNG, JPEG, EXR, or an SDF volume .npy): WGAN-GP,
    /// checkpoints, previews.
    Train(Box<TrainArgs>),
    /// Turn a closed mesh (.obj or .ply) into a signed-distance volume (.npy) to train on.
    Voxelize(VoxelizeArgs),
    /// Convert an authors' PyTorch generator (netG.pth) into an ipfn model file.
    Import(ImportArgs),
    /// Draw a procedural exemplar: bricks, weave, stripes, graded (PNG), material (a map set) or
    /// gyroid (an SDF volume).
    Draw(DrawArgs),
    /// Score a model against its exemplar (SIFID, seam score, period), or two images (SIFID).
    Eval(EvalArgs),
    /// Time synthesis and training on this machine's devices, beside floors measured now.
    Bench(BenchArgs),
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Square sizes to synthesize, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "256,512,1024")]
    pub sizes: Vec<usize>,
    /// Devices, comma-separated: cpu, flex, wgpu, cuda. Default: cpu and flex, plus wgpu and
    /// cuda where they start (wgpu on a software adapter such as lavapipe is slow: name it).
    #[arg(long, value_delimiter = ',')]
    pub devices: Option<Vec<String>>,
    /// Timed runs per figure (the median is printed), after one warm-up run.
    #[arg(long, default_value_t = 3)]
    pub runs: usize,
    /// Skip the training iteration.
    #[arg(long)]
    pub no_train: bool,
    /// Batch sizes of the timed training iterations, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "4")]
    pub batches: Vec<usize>,
    /// Also paint cubes of these sides, comma-separated, with a 3D generator of the paper's size
    /// (10x128, random weights), e.g. --volumes 128,512.
    #[arg(long, value_delimiter = ',')]
    pub volumes: Vec<usize>,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Model file (.ipfn). Default: as for synth (most recent model here, else the shipped one).
    #[arg(long, value_name = "PATH", conflicts_with = "images")]
    pub model: Option<PathBuf>,
    /// The exemplar the model was trained on (PNG, JPEG or EXR).
    #[arg(
        long,
        value_name = "PATH",
        required_unless_present = "images",
        conflicts_with = "images"
    )]
    pub exemplar: Option<PathBuf>,
    /// Compare two images directly: SIFID of A to B.
    #[arg(long, num_args = 2, value_names = ["A", "B"])]
    pub images: Option<Vec<PathBuf>>,
    /// Samples to synthesize (seeds --seed, --seed + 1, ...), each at the exemplar's size.
    #[arg(long, default_value_t = 8, conflicts_with = "images")]
    pub samples: usize,
    /// First seed.
    #[arg(long, default_value_t = 0, conflicts_with = "images")]
    pub seed: u64,
    /// Where to synthesize: cpu, flex, wgpu or cuda.
    #[arg(long, default_value = "cpu", conflicts_with = "images")]
    pub device: String,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The exemplar: PNG (8/16-bit), JPEG or EXR; gray, RGB or RGBA (alpha is learned as a
    /// channel). Not needed with --resume.
    pub exemplar: Option<PathBuf>,
    /// TOML config (see configs/); flags below override it. Default: configs/default.toml's values.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Run folder. Default: runs/<exemplar name>.
    #[arg(long, short, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Continue the run in DIR from its latest.ipfn, exactly where it stopped.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["exemplar", "config", "out", "maps"])]
    pub resume: Option<PathBuf>,
    /// A material map set instead of one image: aligned maps of one size and bit depth
    /// (albedo.png,normal.png,roughness.png,height.png), learned together; synth writes one
    /// file per map, named after these files.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "FILES",
        conflicts_with = "exemplar"
    )]
    pub maps: Option<Vec<PathBuf>>,
    /// Which maps are normal maps (renormalised to unit length on output), by file stem.
    /// Default: the maps whose name contains "normal"; pass "" for none.
    #[arg(long, value_delimiter = ',', value_name = "NAMES", requires = "maps")]
    pub normal_maps: Option<Vec<String>>,
    /// Resample maps of another size to the first map's size, and accept mixed bit depths.
    #[arg(long, requires = "maps")]
    pub resize_maps: bool,
    /// Where to train: flex (CPU), wgpu (GPU) or cuda (NVIDIA GPU; a build with --features cuda).
    #[arg(long, default_value = "flex")]
    pub device: String,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub overrides: TrainOverrides,
}

/// Flags that override config keys of the same name.
#[derive(Debug, Args, Default)]
pub struct TrainOverrides {
    /// Total iterations (with --resume: the new total).
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Crops per step.
    #[arg(long)]
    pub batch: Option<usize>,
    /// Crop size in pixels, a multiple of 16.
    #[arg(long)]
    pub crop: Option<usize>,
    /// Random shift of generated crops, in coordinate units (a crop spans 2).
    #[arg(long)]
    pub shift: Option<f32>,
    /// Critic updates per iteration.
    #[arg(long)]
    pub critic_steps: Option<usize>,
    /// Generator updates per iteration.
    #[arg(long)]
    pub generator_steps: Option<usize>,
    /// Adam learning rate.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Seed of every random draw.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Scale the exemplar first (Lanczos-3, anti-aliased), e.g. 0.5.
    #[arg(long)]
    pub resize: Option<f64>,
    /// Checkpoint every N iterations.
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Preview image every N iterations.
    #[arg(long)]
    pub preview_every: Option<u64>,
    /// Plain log line every N iterations (when stderr is not a terminal).
    #[arg(long)]
    pub log_every: Option<u64>,
    /// Generator: encoding octaves.
    #[arg(long)]
    pub octaves: Option<usize>,
    /// Generator: latent channels.
    #[arg(long)]
    pub latent_dim: Option<usize>,
    /// Generator: hidden layers.
    #[arg(long)]
    pub hidden_layers: Option<usize>,
    /// Generator: units per hidden layer.
    #[arg(long)]
    pub width: Option<usize>,
    /// Directional guidance (conditional IPFN): x, y, -x, -y or a,b,c, for g = a·x + b·y + c
    /// over the exemplar (x, y in [-1, 1]). The model then needs --guide in synth.
    #[arg(long, value_name = "LINE", allow_hyphen_values = true)]
    pub guide: Option<String>,
    /// Learn a solid texture from the 2D exemplar: a 3D generator whose random axis-aligned
    /// slices must look like the exemplar (paint it with `synth --solid --size WxHxD`).
    #[arg(long)]
    pub solid: bool,
    /// Volumes: density control. Condition the generator and the critic on each crop's
    /// density (mean |sdf|); paint with `synth --density`.
    #[arg(long)]
    pub density: bool,
}

impl TrainOverrides {
    /// Applies the flags to `config`.
    pub fn apply(&self, c: &mut TrainConfig) {
        if let Some(g) = &self.guide {
            c.guide = Some(g.clone());
        }
        if self.solid {
            c.solid = true;
        }
        if self.density {
            c.density = true;
        }
        macro_rules! set {
            ($($f:ident),*) => { $( if let Some(v) = self.$f.clone() { c.$f = v; } )* };
        }
        set!(
            iterations,
            batch,
            crop,
            shift,
            critic_steps,
            generator_steps,
            lr,
            seed,
            resize,
            checkpoint_every,
            preview_every,
            log_every
        );
        set!(octaves, latent_dim, hidden_layers, width);
    }

    /// Flags that change the model or the random streams, which a resumed run cannot change.
    fn fixed_on_resume(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        macro_rules! check {
            ($($f:ident),*) => { $( if self.$f.is_some() { v.push(concat!("--", stringify!($f))); } )* };
        }
        check!(
            batch,
            crop,
            shift,
            critic_steps,
            generator_steps,
            lr,
            seed,
            resize,
            octaves,
            latent_dim,
            hidden_layers,
            width,
            guide
        );
        if self.solid {
            v.push("--solid");
        }
        if self.density {
            v.push("--density");
        }
        v
    }
}

#[derive(Debug, Args)]
pub struct VoxelizeArgs {
    /// The mesh: .obj or .ply (ASCII or binary), closed for a meaningful inside.
    pub mesh: PathBuf,
    /// Voxels per side of the cubic volume.
    #[arg(long, default_value_t = 64)]
    pub res: usize,
    /// Empty margin around the mesh's bounding box, as a fraction of its largest side.
    #[arg(long, default_value_t = 0.05)]
    pub padding: f32,
    /// Output volume: .npy `[res, res, res, 1]`, or .raw (bare little-endian float32); signed
    /// distance in units of the volume's side, negative inside.
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct DrawArgs {
    /// bricks (32x16 bricks: period 32 across, 32 down), weave (thread pitch 8: period 16),
    /// stripes (period 40 across), graded (16 px stripes whose bright part grows from 15% of
    /// the period at the left to 85% at the right: for --guide x), or material: a map set (albedo, normal, roughness,
    /// height; 16-bit PNGs, period 32) written into the folder --out, or gyroid: a signed
    /// distance volume (.npy, size^3 voxels, period 32).
    pub pattern: String,
    /// Width and height in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    /// gyroid: the period in voxels (default 32).
    #[arg(long, value_name = "VOXELS")]
    pub period: Option<usize>,
    /// gyroid: thicken the sheet along x (half-thickness 0.1 to 0.9), so porosity grows from
    /// about 7% to 58% across the volume (an exemplar for `train --density`).
    #[arg(long)]
    pub graded: bool,
    /// Output PNG (a folder for material).
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
}

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
    /// a volume: .npy ([D, H, W, C] float32) or .raw (bare little-endian float32). Default
    /// synth.png, or synth.npy for a volume.
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out_path: Option<PathBuf>,
    /// `--out`, or the default for what is painted (set by `synth`).
    #[arg(skip)]
    pub out: PathBuf,
    /// Bits per channel for PNG output: 8 or 16. Default 8; a map set's maps keep their
    /// inputs' depth.
    #[arg(long)]
    pub bits: Option<u8>,
    /// Where to run: cpu (fused CPU evaluator), flex (burn CPU backend), wgpu (GPU) or cuda
    /// (NVIDIA GPU; a build with --features cuda).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The authors' generator checkpoint (e.g. honeycomb_test_netG_Epoch101.pth).
    pub pth: PathBuf,
    /// Where to write the ipfn model.
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
    /// Octaves of the encoding the model was trained with (their code's default: 5).
    #[arg(long, default_value_t = 5)]
    pub octaves: usize,
    /// Crop size it was trained with, in pixels (their default: 128).
    #[arg(long, default_value_t = 128)]
    pub crop: usize,
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

/// Parses the process arguments and runs the command.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Synth(args) => synth(args),
        Command::Train(args) => train(*args),
        Command::Import(args) => import(args),
        Command::Draw(args) => draw(args),
        Command::Voxelize(args) => voxelize(args),
        Command::Eval(args) => eval(args),
        Command::Bench(args) => bench(args),
    }
}

/// A model to synthesize with, and a phrase saying where it came from.
pub struct ChosenModel {
    pub config: GeneratorConfig,
    pub weights: GeneratorWeights,
    pub description: String,
    /// The maps of a map-set model.
    pub maps: Option<MapSet>,
}

/// Loads `--model`, else the most recent model in `dir`, else the shipped honeycomb.
pub fn choose_model(explicit: Option<&Path>, dir: &Path) -> Result<ChosenModel> {
    let (checkpoint, description) = match explicit {
        Some(path) => (Checkpoint::load(path)?, format!("{}", path.display())),
        None => match most_recent_model(dir) {
            Some(path) => (
                Checkpoint::load(&path)?,
                format!("{} (most recent model in this folder; --model to choose)", path.display()),
            ),
            None => (
                Checkpoint::from_bytes(SHIPPED_HONEYCOMB, Path::new("<shipped honeycomb>"))?,
                "shipped honeycomb (the IPFN authors' pretrained generator, MIT; --model to choose)".to_string(),
            ),
        },
    };
    let (config, weights) = GeneratorWeights::read_from(&checkpoint)?;
    let maps = MapSet::read_from(&checkpoint, explicit.unwrap_or(Path::new("model")))?;
    if let Some(set) = &maps
        && set.channels() != config.channels
    {
        return Err(input_error!(
            "{}: its map list has {} channels but the generator paints {}",
            description,
            set.channels(),
            config.channels
        ));
    }
    Ok(ChosenModel {
        config,
        weights,
        description,
        maps,
    })
}

/// The newest `*.ipfn` in `dir` or `runs/*/latest.ipfn` under it.
pub fn most_recent_model(dir: &Path) -> Option<PathBuf> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    let ipfn_files = |d: &Path| -> Vec<PathBuf> {
        std::fs::read_dir(d)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "ipfn"))
            .collect()
    };
    candidates.extend(ipfn_files(dir));
    for run in std::fs::read_dir(dir.join("runs"))
        .into_iter()
        .flatten()
        .flatten()
    {
        let latest = run.path().join("latest.ipfn");
        if latest.is_file() {
            candidates.push(latest);
        }
    }
    candidates
        .into_iter()
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max()
        .map(|(_, p)| p.strip_prefix(dir).map(Path::to_path_buf).unwrap_or(p))
}

fn synth(mut args: SynthArgs) -> Result<()> {
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
    if let Some(slice) = args.slice {
        return synth_slice(&args, [depth.unwrap_or(width), height, width], slice);
    }
    if let Some(depth) = depth {
        return synth_volume(&args, width, height, depth);
    }
    if args.mesh.is_some() {
        return Err(input_error!(
            "--mesh needs a volume: give --size WxHxD or --depth with a 3D model"
        ));
    }
    if args.solid {
        return Err(input_error!(
            "--solid paints a volume or a plane: give --size WxHxD, --depth or --slice"
        ));
    }
    if args.density.is_some() {
        return Err(input_error!(
            "--density is for volume models: give --size WxHxD, --depth or --slice"
        ));
    }
    if args.bits.is_some_and(|b| b != 8 && b != 16) {
        return Err(input_error!(
            "--bits {}: PNG output is 8 or 16 bits per channel",
            args.bits.unwrap_or_default()
        ));
    }
    let format = OutputFormat::from_path(&args.out, args.bits.unwrap_or(8))?;
    crate::io::check_destination(&args.out)?;
    if !(args.zoom.is_finite() && args.zoom > 0.0) {
        return Err(input_error!(
            "--zoom {}: must be a positive number",
            args.zoom
        ));
    }
    if !(args.noise_scale.is_finite() && args.noise_scale > 0.0) {
        return Err(input_error!(
            "--noise-scale {}: must be a positive number",
            args.noise_scale
        ));
    }
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    let map_outputs = match &model.maps {
        Some(set) => {
            let outputs = set.outputs(&args.out, args.bits)?;
            crate::maps::check_outputs(&outputs, width, height)?;
            Some(outputs)
        }
        None => {
            format.check_size(&args.out, width, height, model.config.channels)?;
            None
        }
    };
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let description = model.description.clone();

    let (x, y) = args.offset.unwrap_or((0, 0));
    let mut builder = Synth::new(model.config, model.weights)
        .seed(args.seed)
        .zoom(args.zoom)
        .offset(x, y)
        .noise_scale(args.noise_scale)
        .device(device);
    if args.tile {
        builder = builder.tile(width, height);
    }
    if args.mirror {
        builder = builder.mirror(width, height);
    }
    if let Some(g) = &args.guide {
        builder = builder.guide(crate::guidance::Guide::parse_flag(g)?, width, height);
    }
    let painter = builder.painter()?;
    say(format!("model: {description}"));
    if let Some(t) = painter.tile_adjustment() {
        say(t.describe());
    }

    let start = Instant::now();
    let bar =
        (!args.quiet && std::io::stderr().is_terminal() && width * height >= 1 << 22).then(|| {
            let bar = indicatif::ProgressBar::new(height as u64);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} rows  {elapsed} (eta {eta})",
                )
                .expect("valid progress template"),
            );
            bar
        });
    let progress = |rows: usize| {
        if let Some(bar) = &bar {
            bar.set_position(rows as u64);
        }
    };
    match &map_outputs {
        Some(outputs) => {
            painter.write_maps(outputs, width, height, DEFAULT_BAND_PIXELS, progress)?
        }
        None => painter.write_image(
            &args.out,
            format,
            width,
            height,
            DEFAULT_BAND_PIXELS,
            progress,
        )?,
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let written = match &map_outputs {
        Some(outputs) => outputs
            .iter()
            .map(|o| o.path.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        None => args.out.display().to_string(),
    };
    say(format!(
        "wrote {} ({width}x{height}, seed {}, {:?}) in {:.2} s",
        written,
        args.seed,
        device,
        start.elapsed().as_secs_f64()
    ));
    Ok(())
}

fn import(args: ImportArgs) -> Result<()> {
    if args.out.extension().is_none_or(|e| e != "ipfn") {
        return Err(input_error!(
            "{}: model files end in .ipfn",
            args.out.display()
        ));
    }
    let (config, weights) = checkpoint::import_pytorch(&args.pth, args.octaves, args.crop)?;
    let mut ckpt = Checkpoint::new();
    ckpt.metadata.insert(
        "provenance".into(),
        format!(
            "imported by ipfn {} from {}",
            env!("CARGO_PKG_VERSION"),
            args.pth
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        ),
    );
    weights.write_to(&config, &mut ckpt);
    ckpt.save(&args.out)?;
    eprintln!(
        "wrote {}: {} hidden layers of {}, latent {}, {} channels, K = {:?}",
        args.out.display(),
        config.hidden_layers,
        config.width,
        config.latent_dim,
        config.channels,
        weights.k
    );
    Ok(())
}

fn train(args: TrainArgs) -> Result<()> {
    let device = args.device.parse::<DeviceChoice>()?.training_device()?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let mut trainer = match &args.resume {
        Some(dir) => {
            let fixed = args.overrides.fixed_on_resume();
            if !fixed.is_empty() {
                return Err(input_error!(
                    "{} cannot change when resuming (they change the model or its random draws); start a new run with --out instead",
                    fixed.join(", ")
                ));
            }
            let mut t = Trainer::resume(dir, args.overrides.iterations, &device)?;
            args.overrides.apply(&mut t.config);
            say(format!(
                "resuming {} at iteration {}",
                dir.display(),
                t.iteration
            ));
            t
        }
        None => {
            let source: ExemplarSource = match (&args.exemplar, &args.maps) {
                (Some(image), _) => image.into(),
                (None, Some(files)) => {
                    MapFiles::new(files.clone(), args.normal_maps.as_deref(), args.resize_maps)?
                        .into()
                }
                (None, None) => {
                    return Err(input_error!(
                        "no exemplar given: `ipfn train IMAGE` (or `--maps A.png,B.png,...`) starts a run, `ipfn train --resume runs/NAME` continues one"
                    ));
                }
            };
            let exemplar = source.main_path().to_path_buf();
            let mut config = match &args.config {
                Some(path) => {
                    let text = std::fs::read_to_string(path)
                        .map_err(|e| input_error!("{}: cannot read: {e}", path.display()))?;
                    TrainConfig::from_toml(&text, path)?
                }
                None => TrainConfig::default(),
            };
            args.overrides.apply(&mut config);
            let run_dir = args.out.clone().unwrap_or_else(|| {
                let stem = exemplar
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "run".into());
                Path::new("runs").join(stem)
            });
            if run_dir.join("latest.ipfn").exists() {
                return Err(input_error!(
                    "{} already holds a run; continue it with `ipfn train --resume {}` or start another with --out DIR",
                    run_dir.display(),
                    run_dir.display()
                ));
            }
            let trainer = Trainer::new(config, source, &run_dir, &device)?;
            if let Some(maps) = trainer.maps() {
                let names: Vec<String> = maps
                    .maps
                    .iter()
                    .map(|m| {
                        format!(
                            "{} ({} ch, {}-bit{})",
                            m.name,
                            m.channels,
                            m.bits,
                            if m.normal { ", normal" } else { "" }
                        )
                    })
                    .collect();
                say(format!("map set: {}", names.join(", ")));
            }
            trainer
        }
    };
    trainer.prepare_run_dir()?;
    let total = trainer.config.iterations;
    say(format!(
        "training {} -> {} ({} iterations, batch {}, crop {}, {})",
        trainer.run_dir().display(),
        trainer.run_dir().join("latest.ipfn").display(),
        total,
        trainer.config.batch,
        trainer.config.crop,
        args.device
    ));

    static STOP: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    let _ = ctrlc::set_handler(|| {
        if STOP.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(130); // a second Ctrl-C: stop now (latest.ipfn is intact)
        }
        eprintln!(
            "\ninterrupted: finishing this iteration and saving a checkpoint (Ctrl-C again to quit at once)"
        );
    });

    let tty = std::io::stderr().is_terminal();
    let bar = (!args.quiet && tty).then(|| {
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} it  {per_sec}  eta {eta}  {msg}",
            )
            .expect("valid progress template"),
        );
        bar.set_position(trainer.iteration);
        bar
    });
    let start = Instant::now();
    let first = trainer.iteration;
    let cfg = trainer.config.clone();
    while trainer.iteration < total {
        let stats = trainer.step();
        trainer.append_metrics(&stats)?;
        let it = trainer.iteration;
        let k: Vec<String> = stats.k.iter().map(|k| format!("{k:.4}")).collect();
        let line = format!(
            "W {:.4}  gp {:.4}  G {:.4}  K {}",
            stats.wasserstein,
            stats.penalty,
            stats.generator_loss,
            k.join(" ")
        );
        match &bar {
            Some(bar) => {
                bar.set_position(it);
                bar.set_message(line);
            }
            None if !args.quiet && (it % cfg.log_every == 0 || it == total) => {
                eprintln!(
                    "iter {it}/{total}  {line}  {:.3} it/s",
                    stats.iterations_per_second
                );
            }
            None => {}
        }
        let stop = STOP.load(std::sync::atomic::Ordering::SeqCst);
        if it % cfg.checkpoint_every == 0 || it == total || stop {
            trainer.save_checkpoint()?;
        }
        if it % cfg.preview_every == 0 || it == total {
            trainer.save_preview()?;
        }
        if stop {
            if let Some(bar) = &bar {
                bar.abandon();
            }
            return Err(crate::Error::Interrupted(format!(
                "interrupted at iteration {it}; saved {}; continue with `ipfn train --resume {}`",
                trainer.run_dir().join("latest.ipfn").display(),
                trainer.run_dir().display()
            )));
        }
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    say(format!(
        "trained {} iterations in {:.1} s; model: {} (ipfn synth uses it by default here)",
        trainer.iteration - first,
        start.elapsed().as_secs_f64(),
        trainer.run_dir().join("latest.ipfn").display()
    ));
    Ok(())
}

fn draw(args: DrawArgs) -> Result<()> {
    use crate::procedural;
    if args.size == 0 {
        return Err(input_error!("--size 0: must be at least 1"));
    }
    let n = args.size;
    if args.pattern == "gyroid" {
        let period = args.period.unwrap_or(32);
        if period < 2 {
            return Err(input_error!("--period {period}: must be at least 2 voxels"));
        }
        let sdf = if args.graded {
            procedural::graded_gyroid_sdf(n, period as f32, 0.1, 0.9)
        } else {
            procedural::gyroid_sdf(n, period as f32, 0.4)
        };
        let mut writer = crate::io::VolumeWriter::create(&args.out, n, n, n, 1)?;
        writer.write_slab(&sdf)?;
        writer.finish()?;
        eprintln!(
            "wrote {} ({n}x{n}x{n} gyroid sheet SDF, period {period} voxels)",
            args.out.display()
        );
        return Ok(());
    }
    if args.pattern == "material" {
        std::fs::create_dir_all(&args.out)
            .map_err(|e| input_error!("{}: cannot create folder: {e}", args.out.display()))?;
        let maps = procedural::material(n, n, 32);
        for ((name, channels), unit) in procedural::MATERIAL_MAPS.iter().zip(maps) {
            let path = args.out.join(format!("{name}.png"));
            let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
            let mut writer = crate::io::ImageWriter::create(
                &path,
                OutputFormat::Png { bits: 16 },
                n,
                n,
                *channels,
            )?;
            writer.write_rows(&values)?;
            writer.finish()?;
        }
        eprintln!(
            "wrote {}/{{albedo,normal,roughness,height}}.png ({n}x{n} 16-bit material)",
            args.out.display()
        );
        return Ok(());
    }
    let unit = match args.pattern.as_str() {
        "bricks" => procedural::bricks(n, n, 32, 16),
        "weave" => procedural::weave(n, n, 8),
        "stripes" => procedural::stripes(n, n, 40.0),
        "graded" => procedural::graded_stripes(n, n, 16.0, 0.15, 0.85),
        other => {
            return Err(input_error!(
                "unknown pattern '{other}'; use bricks, weave, stripes, graded, material or gyroid"
            ));
        }
    };
    let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
    crate::io::write_png(&args.out, n, n, 3, &values)?;
    eprintln!("wrote {} ({n}x{n} {})", args.out.display(), args.pattern);
    Ok(())
}

fn eval(args: EvalArgs) -> Result<()> {
    use crate::metrics;
    let start = Instant::now();
    if let Some(images) = &args.images {
        let gaussian = |p: &Path| -> Result<metrics::Gaussian> {
            let image = crate::io::read_exemplar(p)?;
            let in_file = |e: crate::Error| match e {
                crate::Error::Input(m) => input_error!("{}: {m}", p.display()),
                other => other,
            };
            let rgb = metrics::to_unit_rgb(&image.values, image.channels).map_err(in_file)?;
            let features = metrics::InceptionStem::embedded()
                .features(&rgb, image.height, image.width)
                .map_err(in_file)?;
            metrics::Gaussian::fit(&features).map_err(in_file)
        };
        let score = metrics::frechet_distance(&gaussian(&images[0])?, &gaussian(&images[1])?);
        if args.json {
            let out = serde_json::json!({
                "metric": metrics::SIFID_NAME,
                "sifid": score,
                "a": images[0],
                "b": images[1],
            });
            println!("{out}");
        } else {
            println!(
                "SIFID {score:.4}  ({} vs {}; Keras InceptionV3 stem, not comparable with torchvision-based values)",
                images[0].display(),
                images[1].display()
            );
        }
        return Ok(());
    }
    let exemplar_path = args
        .exemplar
        .as_deref()
        .expect("clap requires --exemplar without --images");
    let device: DeviceChoice = args.device.parse()?;
    device.burn_device()?;
    if args.samples == 0 {
        return Err(input_error!("--samples 0: need at least one sample"));
    }
    let exemplar = crate::io::read_exemplar(exemplar_path)?;
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    let report = metrics::evaluate_model(
        &model.config,
        &model.weights,
        &exemplar,
        args.samples,
        args.seed,
        device,
    )
    .map_err(|e| match e {
        crate::Error::Input(m) => input_error!("{}: {m}", exemplar_path.display()),
        other => other,
    })?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("the report serializes")
        );
        return Ok(());
    }
    eprintln!("model: {}", model.description);
    let r = &report;
    let fmt_period = |p: Option<f64>| p.map_or("none".to_string(), |v| format!("{v:.1}"));
    println!(
        "SIFID          {:.4} ± {:.4} over {} samples of {}x{} (seeds {}..{}; Keras InceptionV3 stem, not comparable with torchvision-based values)",
        r.sifid.mean,
        r.sifid.std,
        r.sifid.values.len(),
        r.width,
        r.height,
        r.seed,
        r.seed + r.sifid.values.len() as u64 - 1
    );
    println!(
        "seam score     {:.3} for --tile samples laid 2x2 (columns {:.3}, rows {:.3}); the exemplar laid 2x2: {:.3}. About 1 is seamless.",
        r.seam_model_tile.overall,
        r.seam_model_tile.columns,
        r.seam_model_tile.rows,
        r.seam_exemplar.overall
    );
    println!(
        "period (px)    model {:.1} x {:.1} (rows x columns, from K); exemplar {} x {} (autocorrelation peak)",
        r.period_model[0],
        r.period_model[1],
        fmt_period(r.period_exemplar[0]),
        fmt_period(r.period_exemplar[1])
    );
    eprintln!("evaluated in {:.2} s", start.elapsed().as_secs_f64());
    Ok(())
}

fn voxelize(args: VoxelizeArgs) -> Result<()> {
    if !(args.padding.is_finite() && args.padding >= 0.0) {
        return Err(input_error!(
            "--padding {}: must be a fraction of 0 or more",
            args.padding
        ));
    }
    crate::io::VolumeFormat::from_path(&args.out)?;
    crate::io::check_destination(&args.out)?;
    let start = Instant::now();
    let mesh = crate::mesh::read_mesh(&args.mesh)?;
    let volume = crate::mesh::voxelize(&mesh, args.res, args.padding)
        .map_err(|e| input_error!("{}: {e}", args.mesh.display()))?;
    if volume.open_edges > 0 {
        eprintln!(
            "warning: {} has {} open edges: inside and outside are decided by ray parity voted over three axes, which can leak through holes; close the mesh for a reliable sign",
            args.mesh.display(),
            volume.open_edges
        );
    }
    let n = args.res;
    let mut writer = crate::io::VolumeWriter::create(&args.out, n, n, n, 1)?;
    writer.write_slab(&volume.values)?;
    writer.finish()?;
    let inside =
        volume.values.iter().filter(|&&v| v < 0.0).count() as f64 / volume.values.len() as f64;
    eprintln!(
        "wrote {} ({n}x{n}x{n} signed distance of {}: {} triangles, {:.1}% inside) in {:.2} s",
        args.out.display(),
        args.mesh.display(),
        mesh.triangles.len(),
        100.0 * inside,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn bench(args: BenchArgs) -> Result<()> {
    use crate::bench;
    if args.sizes.contains(&0) || args.volumes.contains(&0) {
        return Err(input_error!("--sizes/--volumes: sizes must be at least 1"));
    }
    if args.batches.contains(&0) {
        return Err(input_error!("--batches: batch sizes must be at least 1"));
    }
    if args.runs == 0 {
        return Err(input_error!("--runs 0: need at least one run"));
    }
    let devices = match &args.devices {
        Some(names) => names
            .iter()
            .map(|n| {
                let d: DeviceChoice = n.parse()?;
                d.burn_device()?; // fail now, with the device's own message
                Ok(d)
            })
            .collect::<Result<Vec<_>>>()?,
        None => {
            let mut found = vec![DeviceChoice::Cpu, DeviceChoice::Flex];
            for gpu in [DeviceChoice::Wgpu, DeviceChoice::Cuda] {
                match gpu.burn_device() {
                    Ok(_) if gpu == DeviceChoice::Wgpu && crate::synth::wgpu_is_software() => {
                        eprintln!(
                            "wgpu: software adapter only (no GPU); skipped, name it in --devices to time it"
                        )
                    }
                    Ok(_) => found.push(gpu),
                    Err(e) => eprintln!("{}: skipped ({e})", bench::device_name(gpu)),
                }
            }
            found
        }
    };
    let plan = bench::BenchPlan {
        sizes: args.sizes.clone(),
        devices,
        runs: args.runs,
        train: !args.no_train,
        batches: args.batches.clone(),
        volumes: args.volumes.clone(),
    };
    println!(
        "ipfn {} bench on {}",
        env!("CARGO_PKG_VERSION"),
        bench::machine()
    );
    println!(
        "shipped honeycomb generator (10x128 MLP); medians of {} runs after a warm-up",
        args.runs
    );
    println!();
    println!("| work | device | ours | floor measured now (or reference) | ours / floor |");
    println!("|---|---|---|---|---|");
    bench::run(&plan, |row| println!("{}", row.markdown()))?;
    Ok(())
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
    let painter = volume_synth(args, model.config, model.weights, width)?.volume_painter()?;
    let values = painter.render(origin, d, h, w);
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
        .device(args.device.parse()?);
    if let Some((from, to)) = args.density {
        builder = builder.density(crate::synth::DensityRamp { from, to, width });
    }
    Ok(builder)
}

/// `ipfn synth --depth D`: a volume from a 3D model, streamed to .npy in slabs.
fn synth_volume(args: &SynthArgs, width: usize, height: usize, depth: usize) -> Result<()> {
    if depth == 0 {
        return Err(input_error!("--depth 0: must be at least 1"));
    }
    if args.mirror || args.guide.is_some() {
        return Err(input_error!(
            "--mirror and --guide are for images; volumes do not support them yet"
        ));
    }
    if args.offset.is_some() || args.bits.is_some() {
        return Err(input_error!(
            "--offset and --bits are for images; a volume starts at the origin and is written as float32 (.npy or .raw)"
        ));
    }
    let format = crate::io::VolumeFormat::from_path(&args.out)?;
    crate::io::check_destination(&args.out)?;
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    crate::io::check_volume_size(&args.out, depth, height, width, model.config.channels)?;
    let mut builder = volume_synth(args, model.config, model.weights, width)?;
    if args.tile {
        builder = builder.tile_volume(depth, height, width);
    }
    let painter = builder.volume_painter()?;
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
    painter.write_npy(
        &args.out,
        depth,
        height,
        width,
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
