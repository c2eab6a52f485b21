//! `ipfn train`: start or resume a run, show progress, stop cleanly on Ctrl-C.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use super::maps::MapSetArgs;
use crate::error::Result;
use crate::train::request::{OpenedRun, TrainRequest};
use crate::train::{RunEnd, TrainOverrides, Trainer};

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The exemplar: PNG (8/16-bit), JPEG or EXR; gray, RGB or RGBA (alpha is learned as a
    /// channel). Not needed with --resume.
    #[arg(conflicts_with = "maps")]
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
    /// With --resume: continue from the run's previous.ipfn (the full state one checkpoint
    /// before latest.ipfn), for when latest.ipfn is damaged.
    #[arg(long, requires = "resume")]
    pub from_previous: bool,
    #[command(flatten)]
    pub maps: MapSetArgs,
    /// Where to train: auto (the best present: cuda where it starts, else a wgpu GPU, else
    /// the CPU; the choice is printed), flex (CPU), wgpu (GPU) or cuda (NVIDIA GPU; a build
    /// with --features cuda).
    #[arg(long, default_value = "auto")]
    pub device: String,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub overrides: TrainOverrides,
}

impl TrainArgs {
    /// The library request these flags ask for.
    pub fn request(&self) -> TrainRequest {
        TrainRequest {
            exemplar: self.exemplar.clone(),
            maps: self.maps.request(),
            config: self.config.clone(),
            settings: None,
            flags: self.overrides.clone(),
            out: self.out.clone(),
            resume: self.resume.clone(),
            from_previous: self.from_previous,
            device: self.device.clone(),
        }
    }
}

pub(super) fn train(args: TrainArgs) -> Result<()> {
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let OpenedRun {
        mut trainer,
        device,
        lines,
    } = args.request().open()?;
    lines.into_iter().for_each(say);
    if !args.quiet {
        opening_lines(&trainer, device, &say)?;
    }
    crate::stop::install(crate::stop::OnSignal::FinishStep);
    let (start, first) = (Instant::now(), trainer.iteration);
    let bar = super::progress_bar(
        !args.quiet,
        trainer.config.iterations,
        "{bar:30} {pos}/{len} it  {per_sec}  eta {eta}  {msg}",
    )
    .inspect(|bar| bar.set_position(first));
    let end = run_with_progress(&mut trainer, bar.as_ref(), args.quiet)?;
    if end == RunEnd::Stopped {
        if let Some(bar) = &bar {
            bar.abandon();
        }
        return Err(stopped(&trainer));
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    say(closing_line(&trainer, trainer.iteration - first, start));
    Ok(())
}

/// How much was trained, and where the model and the report are.
fn closing_line(trainer: &Trainer, iterations: u64, start: Instant) -> String {
    format!(
        "trained {iterations} iterations in {:.1} s; model: {} (ipfn synth uses it by default here); report: {}",
        start.elapsed().as_secs_f64(),
        trainer.run_dir().join("latest.ipfn").display(),
        trainer.run_dir().join("report.html").display()
    )
}

/// What is trained and how, where to watch it, and the structure floor it aims at; the first
/// two said before the floor is computed, which takes a moment on a large exemplar.
fn opening_lines(
    trainer: &Trainer,
    device: crate::device::DeviceChoice,
    say: &dyn Fn(String),
) -> Result<()> {
    say(start_line(trainer, device));
    say(format!(
        "watch it in a browser: ipfn view {}",
        trainer.run_dir().display()
    ));
    if let Some(floor) = trainer.structure_floor()? {
        say(floor_line(&floor));
    }
    Ok(())
}

/// What is trained, for how long, how, and where.
fn start_line(trainer: &Trainer, device: crate::device::DeviceChoice) -> String {
    let length = match &trainer.config.time {
        Some(time) => time.clone(),
        None => format!("{} iterations", trainer.config.iterations),
    };
    format!(
        "training {} -> {} ({length}, batch {}, crop {}, {})",
        trainer.run_dir().display(),
        trainer.run_dir().join("latest.ipfn").display(),
        trainer.config.batch,
        trainer.config.crop,
        crate::bench::device_name(device)
    )
}

/// The structure floor, a map set's per map too: what checkpoints can hope to score.
fn floor_line(floor: &crate::train::score::StructureFloor) -> String {
    let per_map: Vec<String> = (floor.maps.iter())
        .map(|(name, f)| format!("{name} {f:.3}"))
        .collect();
    let per_map = match per_map.is_empty() {
        true => String::new(),
        false => format!(" ({})", per_map.join(", ")),
    };
    format!(
        "structure floor {:.3}{per_map}: the exemplar's halves against the whole; checkpoints scoring near it paint its structure",
        floor.mean
    )
}

/// Runs the training loop, moving `bar` (or printing a line every `log_every` iterations and
/// at each score where there is no bar).
fn run_with_progress(
    trainer: &mut Trainer,
    bar: Option<&indicatif::ProgressBar>,
    quiet: bool,
) -> Result<RunEnd> {
    let log_every = trainer.config.log_every;
    trainer.run(crate::stop::flag(), |trainer, stats| {
        let (it, total) = (stats.iteration, trainer.config.iterations);
        let line = stats.summary();
        match bar {
            Some(bar) => {
                bar.set_length(total);
                bar.set_position(it);
                bar.set_message(line);
            }
            None if !quiet
                && (it.is_multiple_of(log_every) || it == total || stats.sifid.is_some()) =>
            {
                eprintln!(
                    "iter {it}/{total}  {line}  {:.3} it/s",
                    stats.iterations_per_second
                );
            }
            None => {}
        }
    })
}

/// The error a stopped run ends with: where it stopped and how to continue.
fn stopped(trainer: &Trainer) -> crate::Error {
    let signal = crate::stop::signal().unwrap_or(2);
    crate::Error::Interrupted(
        format!(
            "{} at iteration {}; saved {}; continue with `ipfn train --resume {}`",
            crate::stop::name(signal),
            trainer.iteration,
            trainer.run_dir().join("latest.ipfn").display(),
            trainer.run_dir().display()
        ),
        signal,
    )
}
