//! `ipfn fit`: fit a periodic network to a photo and write the seamless tile and its model.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::fit::run::Progress;
use crate::fit::{FitConfig, FitEnd, Fitter};
use crate::input_error;
use crate::io::OutputFormat;
use crate::maps::{MapFiles, MapOutput};

#[derive(Debug, Args)]
pub struct FitArgs {
    /// The photo: PNG (8/16-bit), JPEG or EXR. Not needed with --resume or --maps.
    pub photo: Option<PathBuf>,
    /// A material map set fitted by one network, so the maps stay aligned.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "FILES",
        conflicts_with = "photo"
    )]
    pub maps: Option<Vec<PathBuf>>,
    /// Which maps are normal maps, by file stem (default: names containing "normal").
    #[arg(long, value_delimiter = ',', value_name = "NAMES", requires = "maps")]
    pub normal_maps: Option<Vec<String>>,
    /// Resample maps of another size to the first map's size (maps of mixed bit depths are
    /// read as they are, without it).
    #[arg(long, requires = "maps")]
    pub resize_maps: bool,
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
    fn config(&self) -> Result<FitConfig> {
        let mut c = FitConfig {
            photo: self.photo.clone(),
            mask: self.mask.clone(),
            period: self.period,
            ..FitConfig::default()
        };
        if let Some(files) = &self.maps {
            c.maps = Some(MapFiles::new(
                files.clone(),
                self.normal_maps.as_deref(),
                self.resize_maps,
            )?);
        }
        macro_rules! set {
            ($($field:ident),*) => { $(if let Some(v) = &self.$field { c.$field = v.clone(); })* };
        }
        set!(
            band_limit,
            stages,
            frequencies,
            hidden,
            lr,
            batch,
            seed,
            checkpoint_every
        );
        if self.seam_band.is_some() {
            c.seam_band = self.seam_band;
        }
        if let Some(n) = self.iterations {
            c.iterations = FitConfig::stage_steps(n, c.stages);
        }
        c.time = match (&self.time, self.iterations) {
            (Some(t), _) => Some(t.clone()),
            (None, None) => Some("10m".into()),
            (None, Some(_)) => None,
        };
        Ok(c)
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

/// `--device`: `None` for the fused CPU path, else a burn device.
fn fit_device(name: &str) -> Result<(Option<burn::tensor::Device>, String)> {
    let choice = match name.to_ascii_lowercase().as_str() {
        "auto" => match DeviceChoice::best_for_training() {
            DeviceChoice::Flex => DeviceChoice::Cpu,
            gpu => gpu,
        },
        other => other.parse()?,
    };
    Ok((choice.burn_device()?, crate::bench::device_name(choice)))
}

pub(super) fn fit(args: FitArgs) -> Result<()> {
    let (device, device_name) = fit_device(&args.device)?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let mut fitter = match &args.resume {
        Some(dir) => {
            let f = Fitter::resume(dir, device)?;
            say(format!(
                "resuming {} at stage {}, step {}",
                dir.display(),
                f.stage + 1,
                f.iteration
            ));
            f
        }
        None => {
            let config = args.config()?;
            let budget = config
                .time
                .as_deref()
                .map(crate::train::config::parse_duration)
                .transpose()?;
            let name = config.photo.as_deref().or(args
                .maps
                .as_ref()
                .and_then(|m| m.first().map(PathBuf::as_path)));
            let run = args
                .run
                .clone()
                .unwrap_or_else(|| default_run_dir(name.unwrap_or(Path::new("tile"))));
            let mut f = Fitter::start(config, &run, device)?;
            if let Some(budget) = budget.filter(|_| f.config.iterations.is_empty()) {
                f.plan(budget);
            }
            f
        }
    };
    let [h, w] = fitter.net.shape.period;
    let params = fitter.net.shape.parameters();
    say(format!(
        "fitting {}x{w}x{h} tile: {} stages, band limit {}, {params} parameters ({:.2} per pixel), {:?} steps per stage, {device_name}; run folder {}",
        fitter.photo().channels,
        fitter.net.stages(),
        fitter.config.band([h, w]),
        params as f64 / (h * w) as f64,
        fitter.config.iterations,
        fitter.run_dir().display()
    ));
    let deadline = match (&args.resume, &fitter.config.time) {
        (None, Some(t)) => Some(Instant::now() + crate::train::config::parse_duration(t)?),
        _ => None,
    };
    crate::stop::install(crate::stop::OnSignal::FinishStep);
    let start = Instant::now();
    let bar = (!args.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(fitter.stage_iterations());
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{prefix} {bar:30} {pos}/{len}  {per_sec}  eta {eta}  {msg}",
            )
            .expect("valid progress template"),
        );
        bar
    });
    let mut psnr = f64::NAN;
    let end = fitter.run(crate::stop::flag(), deadline, |p: &Progress| {
        if let Some(v) = p.psnr {
            psnr = v;
        }
        let line = format!("loss {:.3e}  psnr {psnr:.2} dB", p.loss);
        match &bar {
            Some(bar) => {
                bar.set_prefix(format!("stage {}/{}", p.stage + 1, p.stages));
                bar.set_length(p.iterations);
                bar.set_position(p.iteration);
                bar.set_message(line);
            }
            None if !args.quiet && p.psnr.is_some() => eprintln!(
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
    let run = fitter.run_dir().to_path_buf();
    if end == FitEnd::Stopped {
        let signal = crate::stop::signal().unwrap_or(2);
        return Err(crate::Error::Interrupted(
            format!(
                "{} at stage {}, step {}; saved {}; continue with `ipfn fit --resume {}`",
                crate::stop::name(signal),
                fitter.stage + 1,
                fitter.iteration,
                run.join("latest.ipfn").display(),
                run.display()
            ),
            signal,
        ));
    }
    if end == FitEnd::BudgetSpent {
        say(format!(
            "the time budget ran out at stage {}, step {}; the tile holds what was fitted (`ipfn fit --resume {}` finishes the plan)",
            fitter.stage + 1,
            fitter.iteration,
            run.display()
        ));
    }
    let fitted = start.elapsed().as_secs_f64();
    write_outputs(&args, &fitter, &say, fitted)
}

/// `runs/<photo stem>-tile`.
pub fn default_run_dir(photo: &Path) -> PathBuf {
    let stem = photo.file_stem().map(|s| s.to_string_lossy().into_owned());
    PathBuf::from("runs").join(format!("{}-tile", stem.unwrap_or_else(|| "photo".into())))
}

/// Writes `tile.ipfn` and the tile image(s), and says how well the tile matches and tiles.
fn write_outputs(
    args: &FitArgs,
    fitter: &Fitter,
    say: &impl Fn(String),
    seconds: f64,
) -> Result<()> {
    let run = fitter.run_dir();
    let model = run.join("tile.ipfn");
    fitter.model_file().save(&model)?;
    let out = args.out.clone().unwrap_or_else(|| run.join("tile.png"));
    if let Some(bits) = args.bits.filter(|b| *b != 8 && *b != 16) {
        return Err(input_error!(
            "--bits {bits}: PNG output is 8 or 16 bits per channel"
        ));
    }
    let photo = fitter.photo();
    let (h, w, c) = (photo.height, photo.width, photo.channels);
    let period = fitter.net.shape.period;
    let outputs = match fitter.maps() {
        Some(set) => set.outputs(&out, args.bits)?,
        None => vec![MapOutput {
            path: out.clone(),
            format: OutputFormat::from_path(&out, args.bits.unwrap_or(8))?,
            channels: 0..c,
            normal: false,
        }],
    };
    let painter = fitter.painter();
    painter.write(&outputs, [0, 0], period, crate::synth::DEFAULT_BAND_PIXELS)?;
    let tile = painter.render([0, 0], [h, w]);
    let lambda = crate::fit::target::seam_mask(h, w, fitter.config.seam_band_for([h, w]));
    let kept = |i: usize| fitter.mask().is_none_or(|m| m[i] > 0.5);
    let whole = crate::fit::psnr(&tile, &photo.values, c, kept);
    let interior = crate::fit::psnr(&tile, &photo.values, c, |i| kept(i) && lambda[i] == 0.0);
    let one: Vec<f32> = if period == [h, w] {
        tile.iter().map(|v| v.clamp(-1.0, 1.0)).collect()
    } else {
        painter
            .render([0, 0], period)
            .iter()
            .map(|v| v.clamp(-1.0, 1.0))
            .collect()
    };
    let seam = crate::metrics::seam_score(&one, period[0], period[1], c)?;
    let lines = match crate::metrics::line_score_spread(&photo.values, h, w, c) {
        Some(l) => format!(" (the photo's own lines: {:.2} to {:.2})", l.p5, l.p95),
        None => String::new(),
    };
    let written: Vec<String> = outputs
        .iter()
        .map(|o| o.path.display().to_string())
        .collect();
    say(format!(
        "fitted in {seconds:.1} s: PSNR {whole:.2} dB (interior {interior:.2} dB), seam score 2x2 {:.3}{lines}; wrote {} and {} (paint any size: ipfn synth --model {})",
        seam.overall,
        written.join(", "),
        model.display(),
        model.display()
    ));
    Ok(())
}
