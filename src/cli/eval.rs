//! `ipfn eval`: SIFID, structure distance, seam score and period of a model against its
//! exemplar, or SIFID and structure distance of two images.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::input_error;
use crate::model::{choose_checkpoint, choose_model};

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
    /// Where to synthesize: cpu, flex, wgpu or cuda.
    #[arg(long, default_value = "cpu", conflicts_with = "images")]
    pub device: String,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub(super) fn eval(args: EvalArgs) -> Result<()> {
    use crate::metrics;
    let start = Instant::now();
    if let Some(images) = &args.images {
        return eval_images(&args, &images[0], &images[1]);
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
    let exemplar = crate::exemplar::read_exemplar(exemplar_path)?;
    let (checkpoint, description, _) = choose_checkpoint(args.model.as_deref(), Path::new("."))?;
    if crate::fit::PeriodicNet::is_in(&checkpoint) {
        return eval_tile(&args, &checkpoint, &description, &exemplar, exemplar_path);
    }
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
    print_report(&report);
    eprintln!("evaluated in {:.2} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// `--images A B`: SIFID of the two, and B's structure distance to A with A's lags, beside A's
/// floor.
fn eval_images(args: &EvalArgs, a: &Path, b: &Path) -> Result<()> {
    use crate::metrics;
    let read = |p: &Path| -> Result<(crate::exemplar::Exemplar, metrics::Gaussian)> {
        let image = crate::exemplar::read_exemplar(p)?;
        let in_file = |e: crate::Error| match e {
            crate::Error::Input(m) => input_error!("{}: {m}", p.display()),
            other => other,
        };
        let rgb = metrics::to_unit_rgb(&image.values, image.channels).map_err(in_file)?;
        let features = metrics::InceptionStem::embedded()
            .features(&rgb, image.height, image.width)
            .map_err(in_file)?;
        let gaussian = metrics::Gaussian::fit(&features).map_err(in_file)?;
        Ok((image, gaussian))
    };
    let ((ia, ga), (ib, gb)) = (read(a)?, read(b)?);
    let score = metrics::frechet_distance(&ga, &gb);
    let lags = metrics::structure_lags(ia.height, ia.width);
    let map = |i: &crate::exemplar::Exemplar| {
        metrics::Autocorrelation::of(&i.values, i.height, i.width, i.channels, lags)
    };
    let structure = map(&ia).distance(&map(&ib));
    let floor = metrics::structure_floor(&ia.values, ia.height, ia.width, ia.channels);
    if args.json {
        let out = serde_json::json!({
            "metric": metrics::SIFID_NAME,
            "sifid": score,
            "structure": structure,
            "structure_floor": floor,
            "structure_lags": lags,
            "a": a,
            "b": b,
        });
        println!("{out}");
        return Ok(());
    }
    println!(
        "SIFID {score:.4}  ({} vs {}; Keras InceptionV3 stem, not comparable with torchvision-based values)",
        a.display(),
        b.display()
    );
    println!(
        "structure {structure:.4}  ({} against {}, lags up to {lags} px; {}'s own halves: {floor:.4}. Lower is better)",
        b.display(),
        a.display(),
        a.display()
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

/// A tile fitted by `ipfn fit` against its photo: PSNR (whole, and inside the seam band of
/// the default fit) and the seam score of the tile laid 2x2.
fn eval_tile(
    args: &EvalArgs,
    checkpoint: &crate::checkpoint::Checkpoint,
    description: &str,
    photo: &crate::exemplar::Exemplar,
    photo_path: &Path,
) -> Result<()> {
    let net = crate::fit::PeriodicNet::read_from(checkpoint)?;
    let period = net.shape.period;
    let (h, w, c) = (photo.height, photo.width, net.shape.channels);
    if photo.channels != c || h < period[0] || w < period[1] {
        return Err(input_error!(
            "{}: {w}x{h} with {} channels, but the tile {description} has a {}x{} period and {c} channels: give the photo it was fitted to",
            photo_path.display(),
            photo.channels,
            period[1],
            period[0]
        ));
    }
    let mut painter = crate::fit::TilePainter::new(net);
    painter.device = args.device.parse::<DeviceChoice>()?.burn_device()?;
    let paint = |shape: [usize; 2]| -> Vec<f32> {
        let values = painter.render([0, 0], shape);
        values.iter().map(|v| v.clamp(-1.0, 1.0)).collect()
    };
    let (tile, one) = (paint([h, w]), paint(period));
    let lambda =
        crate::fit::target::seam_mask(h, w, crate::fit::FitConfig::default().seam_band_for([h, w]));
    let whole = crate::fit::psnr(&tile, &photo.values, c, |_| true);
    let interior = crate::fit::psnr(&tile, &photo.values, c, |i| lambda[i] == 0.0);
    let seam = crate::metrics::seam_score(&one, period[0], period[1], c)?;
    let photo_seam = crate::metrics::seam_score(&photo.values, h, w, c)?;
    let lines = crate::metrics::line_score_spread(&photo.values, h, w, c);
    if args.json {
        let out = serde_json::json!({
            "model": description,
            "psnr": whole,
            "psnr_interior": interior,
            "seam_tile": seam,
            "seam_photo": photo_seam,
            "seam_photo_lines": lines,
        });
        println!("{out}");
        return Ok(());
    }
    eprintln!("model: {description} (a periodic tile from ipfn fit)");
    println!(
        "PSNR           {whole:.2} dB against {} ({interior:.2} dB in the interior, outside the seam band)",
        photo_path.display()
    );
    println!(
        "seam score     {:.3} for the tile laid 2x2 (columns {:.3}, rows {:.3}); the photo laid 2x2: {:.3}. About 1 is seamless.",
        seam.overall, seam.columns, seam.rows, photo_seam.overall
    );
    if let Some(l) = lines {
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
    Ok(())
}
