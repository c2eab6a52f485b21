//! The `ipfn` command line: clap definitions, one file per subcommand. Each maps its flags onto
//! library calls and prints what happened; policy (model choice, validation, the training loop)
//! lives in the library.

mod bench;
mod eval;
mod fit;
mod maps;
mod synth;
mod tools;
mod train;
mod view;

use clap::{Parser, Subcommand};

use crate::error::Result;
pub use bench::BenchArgs;
pub use eval::EvalArgs;
pub use fit::FitArgs;
pub use synth::{Size, SynthArgs};
pub use tools::{DrawArgs, ImportArgs, VoxelizeArgs};
pub use train::TrainArgs;
pub use view::ViewArgs;

#[derive(Debug, Parser)]
#[command(
    name = "ipfn",
    version,
    about = "Implicit Periodic Field Network: learn a pattern from one exemplar, paint it at any size",
    long_about = "Implicit Periodic Field Network (Chen et al., CVPR 2022).\n\n\
        `ipfn train` learns a pattern from one exemplar (an image, or a set of material maps). \
        `ipfn synth` paints new, varied, optionally seamless versions of it at any size, on the \
        CPU or a GPU. `ipfn eval` scores a model (SIFID, structure, seams, period); `ipfn bench` times this \
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
    /// Paint a sample of a trained pattern (PNG, EXR, NPY or a Zarr store).
    Synth(Box<SynthArgs>),
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
    /// Turn a photo (or a map set) into an exactly periodic, seamless tile: a periodic
    /// sinusoidal network fitted to it (Paz, Novello and Velho), paintable at any size.
    Fit(Box<FitArgs>),
    /// Score a model against its exemplar (SIFID, structure, seam score, period), or two images
    /// (SIFID, structure).
    Eval(EvalArgs),
    /// Time synthesis and training on this machine's devices, beside floors measured now.
    Bench(BenchArgs),
    /// Pan and zoom a model's plane in a browser, and follow a training run live (a local web
    /// page; prints its address).
    View(ViewArgs),
}

/// Parses the process arguments and runs the command.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    // A stop removes the temporary files of unfinished writes; `train` stops at a safe point.
    crate::stop::install(crate::stop::OnSignal::ExitNow);
    match cli.command {
        Command::Synth(args) => synth::synth(*args),
        Command::Train(args) => train::train(*args),
        Command::Import(args) => tools::import(args),
        Command::Draw(args) => tools::draw(args),
        Command::Voxelize(args) => tools::voxelize(args),
        Command::Eval(args) => eval::eval(args),
        Command::Fit(args) => fit::fit(*args),
        Command::Bench(args) => bench::bench(args),
        Command::View(args) => view::view(args),
    }
}

#[cfg(test)]
mod flag_tests;

/// A progress bar of `total` steps drawn with `template`, on a terminal when `show`.
fn progress_bar(show: bool, total: u64, template: &str) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    (show && std::io::stderr().is_terminal()).then(|| {
        indicatif::ProgressBar::new(total).with_style(
            indicatif::ProgressStyle::with_template(template).expect("valid progress template"),
        )
    })
}
