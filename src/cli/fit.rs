//! `ipfn fit`: fit a periodic network to a photo and write the seamless tile and its model.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use super::maps::MapSetArgs;
use crate::error::Result;
use crate::fit::request::{FitOutcome, FitRequest, OpenedFit};
use crate::fit::run::Progress;
use crate::fit::{FitEnd, Fitter};

#[derive(Debug, Args)]
pub struct FitArgs {
    /// The photo: PNG (8/16-bit), JPEG or EXR. Not needed with --resume or --maps.
    #[arg(conflicts_with = "maps")]
    pub photo: Option<PathBuf>,
    #[command(flatten)]
    pub maps: MapSetArgs,
    /// A mask of the photo's size: dark pixels (at or below half gray) are left out of the fit
    /// and filled in by the periodic structure.
    #[arg(long, value_name = "PATH")]
    pub mask: Option<PathBuf>,
    /// The tile's period in photo pixels, N or WxH (default: the photo's size). For a photo
    /// that holds several periods of its pattern (`ipfn eval` reports the dominant one).
    #[arg(long, value_name = "N|WxH", value_parser = parse_period)]
    pub period: Option<[usize; 2]>,
    /// The tile image: .png (8 or 16 bit), .exr or .npy. Default RUN/tile.png (a map set: one
    /// file per map beside it).
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// Bits per channel of PNG output: 8 or 16.
    #[arg(long)]
    pub bits: Option<u8>,
    /// With --maps: the fitted material lit as a plane (one light at a grazing angle, GGX
    /// shading), as an 8-bit PNG of one period.
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    /// Run folder (checkpoints, metrics.csv, tile.ipfn). Default runs/<photo name>-tile.
    #[arg(long, value_name = "DIR")]
    pub run: Option<PathBuf>,
    /// Continue the fit in DIR exactly where it stopped.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["photo", "maps", "mask", "run"])]
    pub resume: Option<PathBuf>,
    /// Time budget, e.g. 90s, 10m, 1h: the steps are planned to fit it. Default 10m, unless
    /// --iterations is given.
    #[arg(long, value_name = "DURATION")]
    pub time: Option<String>,
    /// Steps of the last stage (lower stages take a quarter as many), instead of a time budget.
    #[arg(long, value_name = "N")]
    pub iterations: Option<u64>,
    /// Where to fit and paint: auto (a GPU through cuda or wgpu when one is present, else the
    /// fused CPU path), cpu (fused CPU), flex (burn on the CPU), wgpu or cuda.
    #[arg(long, default_value = "auto")]
    pub device: String,
    /// The highest first-layer frequency, in cycles per period (default: a sixteenth of the
    /// shorter side; at most half, Nyquist).
    #[arg(long, value_name = "B")]
    pub band_limit: Option<usize>,
    /// Levels of detail, fitted from low to high frequencies.
    #[arg(long, value_name = "N")]
    pub stages: Option<usize>,
    /// First-layer frequencies of the last stage.
    #[arg(long, value_name = "N")]
    pub frequencies: Option<usize>,
    /// Hidden layer widths of the last stage, e.g. 256,256.
    #[arg(long, value_delimiter = ',', value_name = "WIDTHS")]
    pub hidden: Option<Vec<usize>>,
    /// Adam's learning rate.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Pixels per step.
    #[arg(long)]
    pub batch: Option<usize>,
    /// The outer share of the tile where the seam term applies (0: none).
    #[arg(long, value_name = "F")]
    pub seam_band: Option<f32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Steps between checkpoints.
    #[arg(long, value_name = "N")]
    pub checkpoint_every: Option<u64>,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

impl FitArgs {
    /// The library request these flags ask for.
    pub fn request(&self) -> FitRequest {
        FitRequest {
            photo: self.photo.clone(),
            maps: self.maps.request(),
            mask: self.mask.clone(),
            period: self.period,
            out: self.out.clone(),
            bits: self.bits,
            preview: self.preview.clone(),
            run: self.run.clone(),
            resume: self.resume.clone(),
            time: self.time.clone(),
            iterations: self.iterations,
            device: self.device.clone(),
            band_limit: self.band_limit,
            stages: self.stages,
            frequencies: self.frequencies,
            hidden: self.hidden.clone(),
            lr: self.lr,
            batch: self.batch,
            seam_band: self.seam_band,
            seed: self.seed,
            checkpoint_every: self.checkpoint_every,
        }
    }
}

/// `--period N` or `WxH`, as `[rows, cols]`.
fn parse_period(text: &str) -> std::result::Result<[usize; 2], String> {
    let number = |v: &str| {
        v.trim()
            .parse::<usize>()
            .map_err(|_| format!("'{text}': expected N or WxH in pixels"))
    };
    match text.split_once(['x', 'X']) {
        Some((w, h)) => Ok([number(h)?, number(w)?]),
        None => number(text).map(|n| [n, n]),
    }
}

pub(super) fn fit(args: FitArgs) -> Result<()> {
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let request = args.request();
    let OpenedFit {
        mut fitter,
        device,
        deadline,
        lines,
    } = request.open()?;
    lines.into_iter().for_each(say);
    say(plan_line(&fitter, device));
    crate::stop::install(crate::stop::OnSignal::FinishStep);
    let start = Instant::now();
    let end = run_with_progress(&mut fitter, deadline, args.quiet)?;
    let run = fitter.run_dir().to_path_buf();
    match end {
        FitEnd::Stopped => return Err(stopped(&fitter, &run)),
        FitEnd::BudgetSpent => say(format!(
            "the time budget ran out at stage {}, step {}; the tile holds what was fitted (`ipfn fit --resume {}` finishes the plan)",
            fitter.stage + 1,
            fitter.iteration,
            run.display()
        )),
        _ => {}
    }
    let fitted = start.elapsed().as_secs_f64();
    let outcome = request.finish(&fitter)?;
    say(closing_line(&outcome, fitted));
    outcome.report.maps.iter().for_each(|m| say(map_line(m)));
    Ok(())
}

/// What is fitted, how, and where.
fn plan_line(fitter: &Fitter, device: crate::device::DeviceChoice) -> String {
    let [h, w] = fitter.net.shape.period;
    let params = fitter.net.shape.parameters();
    format!(
        "fitting {}x{w}x{h} tile: {} stages, band limit {}, {params} parameters ({:.2} per pixel), {:?} steps per stage, {}; run folder {}",
        fitter.photo().channels,
        fitter.net.stages(),
        fitter.config.band([h, w]),
        params as f64 / (h * w) as f64,
        fitter.config.iterations,
        crate::bench::device_name(device),
        fitter.run_dir().display()
    )
}

/// Runs the fit with a progress bar on a terminal, a line per checkpoint elsewhere.
fn run_with_progress(
    fitter: &mut Fitter,
    deadline: Option<Instant>,
    quiet: bool,
) -> Result<FitEnd> {
    let bar = super::progress_bar(
        !quiet,
        fitter.stage_iterations(),
        "{prefix} {bar:30} {pos}/{len}  {per_sec}  eta {eta}  {msg}",
    );
    let mut psnr = f64::NAN;
    let end = fitter.run(crate::stop::flag(), deadline, |p: &Progress| {
        psnr = p.psnr.unwrap_or(psnr);
        let line = format!("loss {:.3e}  psnr {psnr:.2} dB", p.loss);
        match &bar {
            Some(bar) => {
                bar.set_prefix(format!("stage {}/{}", p.stage + 1, p.stages));
                bar.set_length(p.iterations);
                bar.set_position(p.iteration);
                bar.set_message(line);
            }
            None if !quiet && p.psnr.is_some() => eprintln!(
                "stage {}/{} step {}/{}  {line}",
                p.stage + 1,
                p.stages,
                p.iteration,
                p.iterations
            ),
            None => {}
        }
    })?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    Ok(end)
}

/// The error a stopped fit ends with: where it stopped and how to continue.
fn stopped(fitter: &Fitter, run: &std::path::Path) -> crate::Error {
    let signal = crate::stop::signal().unwrap_or(2);
    crate::Error::Interrupted(
        format!(
            "{} at stage {}, step {}; saved {}; continue with `ipfn fit --resume {}`",
            crate::stop::name(signal),
            fitter.stage + 1,
            fitter.iteration,
            run.join("latest.ipfn").display(),
            run.display()
        ),
        signal,
    )
}

/// The fit's closing line: how well the tile matches and tiles, and what was written.
fn closing_line(outcome: &FitOutcome, seconds: f64) -> String {
    let report = &outcome.report;
    let lines = match &report.seam_photo_lines {
        Some(l) => format!(" (the photo's own lines: {:.2} to {:.2})", l.p5, l.p95),
        None => String::new(),
    };
    let images: Vec<String> = outcome
        .images
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    format!(
        "fitted in {seconds:.1} s: PSNR {:.2} dB (interior {:.2} dB), seam score 2x2 {:.3}{lines}; wrote {} and {} (paint any size: ipfn synth --model {})",
        report.psnr,
        report.psnr_interior,
        report.seam_tile.overall,
        images.join(", "),
        outcome.model.display(),
        outcome.model.display()
    )
}

/// One map's PSNR and seam score, as the closing lines of a map set's fit say them.
fn map_line(m: &crate::fit::MapTileReport) -> String {
    let lines = match &m.seam_photo_lines {
        Some(l) => format!(" (its own lines: {:.2} to {:.2})", l.p5, l.p95),
        None => String::new(),
    };
    format!(
        "  {}: PSNR {:.2} dB (interior {:.2} dB), seam score 2x2 {:.3}{lines}",
        m.name, m.psnr, m.psnr_interior, m.seam_tile.overall
    )
}
