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
use crate::synth::{DEFAULT_BAND_PIXELS, DeviceChoice, Synth};

/// The honeycomb generator published by the authors of IPFN (MIT), converted with
/// `ipfn import`; see `exemplars/README.md`.
pub const SHIPPED_HONEYCOMB: &[u8] = include_bytes!("../exemplars/honeycomb.ipfn");

#[derive(Debug, Parser)]
#[command(
    name = "ipfn",
    version,
    about = "Implicit Periodic Field Network: learn a pattern from one exemplar, paint it at any size",
    long_about = "Implicit Periodic Field Network (Chen et al., CVPR 2022).\n\n\
        `ipfn synth` paints new, varied, optionally seamless versions of a learned pattern at any \
        size, on the CPU or a GPU. `ipfn import` converts a generator trained by the authors' \
        PyTorch code. With no model given, synth uses the most recent model in the working \
        folder, else the shipped honeycomb model."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Paint a sample of a trained pattern (PNG, EXR or NPY).
    Synth(SynthArgs),
    /// Convert an authors' PyTorch generator (netG.pth) into an ipfn model file.
    Import(ImportArgs),
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Model file (.ipfn). Default: the most recently written *.ipfn or runs/*/latest.ipfn in the
    /// working folder, else the shipped honeycomb model.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Output width and height in pixels (square). Default 512.
    #[arg(long, value_name = "N")]
    pub size: Option<usize>,
    /// Output width in pixels (overrides --size).
    #[arg(long, value_name = "W")]
    pub width: Option<usize>,
    /// Output height in pixels (overrides --size).
    #[arg(long, value_name = "H")]
    pub height: Option<usize>,
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
    /// Output file: .png (8 or 16 bit), .exr (float) or .npy (raw floats in [-1, 1], [H, W, C]).
    #[arg(long, short, default_value = "synth.png", value_name = "PATH")]
    pub out: PathBuf,
    /// Bits per channel for PNG output: 8 or 16.
    #[arg(long, default_value_t = 8)]
    pub bits: u8,
    /// Where to run: cpu (fused CPU evaluator), flex (burn CPU backend) or wgpu (GPU).
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
        Command::Import(args) => import(args),
    }
}

/// A model to synthesize with, and a phrase saying where it came from.
pub struct ChosenModel {
    pub config: GeneratorConfig,
    pub weights: GeneratorWeights,
    pub description: String,
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
    Ok(ChosenModel {
        config,
        weights,
        description,
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

fn synth(args: SynthArgs) -> Result<()> {
    let device: DeviceChoice = args.device.parse()?;
    let width = args.width.or(args.size).unwrap_or(512);
    let height = args.height.or(args.size).unwrap_or(512);
    if width == 0 || height == 0 {
        return Err(input_error!(
            "size {width}x{height}: width and height must be at least 1"
        ));
    }
    let format = OutputFormat::from_path(&args.out, args.bits)?;
    crate::io::check_destination(&args.out)?;
    if !(args.zoom.is_finite() && args.zoom > 0.0) {
        return Err(input_error!(
            "--zoom {}: must be a positive number",
            args.zoom
        ));
    }
    let model = choose_model(args.model.as_deref(), Path::new("."))?;
    format.check_size(&args.out, width, height, model.config.channels)?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    say(format!("model: {}", model.description));

    let (x, y) = args.offset.unwrap_or((0, 0));
    let mut builder = Synth::new(model.config, model.weights)
        .seed(args.seed)
        .zoom(args.zoom)
        .offset(x, y)
        .device(device);
    if args.tile {
        builder = builder.tile(width, height);
    }
    let painter = builder.painter()?;
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
    painter.write_image(
        &args.out,
        format,
        width,
        height,
        DEFAULT_BAND_PIXELS,
        |rows| {
            if let Some(bar) = &bar {
                bar.set_position(rows as u64);
            }
        },
    )?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    say(format!(
        "wrote {} ({width}x{height}, seed {}, {:?}) in {:.2} s",
        args.out.display(),
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
