//! `ipfn eval`: SIFID, structure distance, seam score and period of a model against its
//! exemplar, or SIFID and structure distance of two images.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::error::Result;
use crate::eval::{EvalRequest, ImagesReport, Report, compare_images};
use crate::fit::TileReport;
use crate::model::load_model;

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
    /// Compare two images directly: SIFID of A to B, and B's structure distance to A (A as the
    /// exemplar: its lags and its floor).
    #[arg(long, num_args = 2, value_names = ["A", "B"])]
    pub images: Option<Vec<PathBuf>>,
    /// Samples to synthesize (seeds --seed, --seed + 1, ...), each at the exemplar's size.
    #[arg(long, default_value_t = 8, conflicts_with = "images")]
    pub samples: usize,
    /// First seed.
    #[arg(long, default_value_t = 0, conflicts_with = "images")]
    pub seed: u64,
    /// Where to synthesize: cpu, flex, wgpu, cuda, or auto (the best present, as on every
    /// command).
    #[arg(long, default_value = "cpu", conflicts_with = "images")]
    pub device: String,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub(super) fn eval(args: EvalArgs) -> Result<()> {
    let start = Instant::now();
    if let Some(images) = &args.images {
        return print_images(&args, &compare_images(&images[0], &images[1])?);
    }
    let request = EvalRequest {
        exemplar: args
            .exemplar
            .clone()
            .expect("clap requires --exemplar without --images"),
        samples: args.samples,
        seed: args.seed,
        device: crate::device::DeviceChoice::resolve(&args.device)?,
    };
    let model = load_model(args.model.as_deref(), Path::new("."))?;
    let report = request.evaluate(&model)?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("the report serializes")
        );
        return Ok(());
    }
    match &report {
        Report::Generator(report) => {
            eprintln!("model: {}", model.description());
            print_report(report);
        }
        Report::Tile(report) => {
            eprintln!(
                "model: {} (a periodic tile from ipfn fit)",
                model.description()
            );
            print_tile(report, &request.exemplar);
        }
    }
    eprintln!("evaluated in {:.2} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// `--images A B`: SIFID of the two, and B's structure distance to A with A's lags, beside A's
/// floor.
fn print_images(args: &EvalArgs, r: &ImagesReport) -> Result<()> {
    if args.json {
        println!(
            "{}",
            serde_json::to_string(r).expect("the report serializes")
        );
        return Ok(());
    }
    let (a, b, lags) = (r.a.display(), r.b.display(), r.structure_lags);
    println!(
        "SIFID {:.4}  ({a} vs {b}; Keras InceptionV3 stem, not comparable with torchvision-based values)",
        r.sifid
    );
    println!(
        "structure {:.4}  ({b} against {a}, lags up to {lags} px; {a}'s own halves: {:.4}. Lower is better)",
        r.structure, r.structure_floor
    );
    Ok(())
}

/// The report as text: SIFID, structure, seam score, period and repeat strength, one line each.
fn print_report(r: &crate::metrics::ModelReport) {
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
        "structure      {:.4} ± {:.4} (autocorrelation distance, lags up to {} px); the exemplar's own halves: {:.4}. Lower is better; near the floor, the samples are arranged like the exemplar.",
        r.structure.mean,
        r.structure.std,
        crate::metrics::structure_lags(r.height, r.width),
        r.structure_floor
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
    println!(
        "repeat         samples {:.2} x {:.2}, exemplar {:.2} x {:.2} (autocorrelation at that peak; samples far above the exemplar show a grid)",
        r.repeat_model[0], r.repeat_model[1], r.repeat_exemplar[0], r.repeat_exemplar[1]
    );
}

/// A tile fitted by `ipfn fit` against its photo: PSNR (whole, and outside the seam band of
/// the default fit) and the seam score of the tile laid 2x2.
fn print_tile(r: &TileReport, photo: &Path) {
    println!(
        "PSNR           {:.2} dB against {} ({:.2} dB in the interior, outside the seam band)",
        r.psnr,
        photo.display(),
        r.psnr_interior
    );
    let seam = &r.seam_tile;
    println!(
        "seam score     {:.3} for the tile laid 2x2 (columns {:.3}, rows {:.3}); the photo laid 2x2: {:.3}. About 1 is seamless.",
        seam.overall, seam.columns, seam.rows, r.seam_photo.overall
    );
    if let Some(l) = &r.seam_photo_lines {
        println!(
            "               the photo's own lines score {:.2} to {:.2} (5th to 95th percentile, median {:.2}): the tile's seam {} a line of the photo",
            l.p5,
            l.p95,
            l.median,
            if l.holds(seam.overall) {
                "shows no more than"
            } else if seam.overall < l.p5 {
                "is softer than"
            } else {
                "shows more than"
            }
        );
    }
}
