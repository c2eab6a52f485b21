//! `cargo bench --bench fit`: `ipfn fit` on photographs, beside what image editors' "make
//! seamless" filters do (the cross-faded offset tile, computed in the same run) and beside the
//! paper's figures; then one fitting step beside its GEMM floor, measured in the same run.
//!
//! ```text
//! cargo bench --bench fit                                   # 60 s per photo
//! IPFN_FIT_BUDGET=15m IPFN_FIT_PHOTOS=a.png,b.jpg cargo bench --bench fit
//! IPFN_FIT_ITERATIONS=5593 IPFN_FIT_WINDOWS=512 IPFN_FIT_PHOTOS=brick.jpg cargo bench --bench fit
//! ```
//!
//! `IPFN_FIT_ITERATIONS=N` fits N steps of the last stage instead of a time budget (the same
//! work whatever else the machine runs). `IPFN_FIT_WINDOWS=N` fits five NxN windows of each
//! photo instead of the whole photo, at offsets spread so that no two windows' seams fall on
//! the same line, and pools their seam scores: one tile's score depends on what its seam
//! happens to cross (a photo's own lines spread from about 0.7 to 1.5), so a method's seam is
//! judged over several.
//!
//! Photos: `IPFN_FIT_PHOTOS`, else the DTD photographs in `../shared/exemplars/` where that
//! folder exists, then the shipped `exemplars/honeycomb.png`, `bricks.png` and `weave.png`.
//! PSNR is over the whole tile and over its interior (outside the seam band, where the fit
//! keeps the photo's colours); the seam score is the tile laid 2x2 (about 1 is seamless), beside
//! the range the photo's own lines score in (`line_score_spread`: what a seam that shows no more
//! than a line of the photo scores).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use ipfn::exemplar::read_exemplar;
use ipfn::fit::crossfade::crossfade_tile;
use ipfn::fit::fused::{CHUNK, Stage};
use ipfn::fit::target::seam_mask;
use ipfn::fit::{FitConfig, Fitter, psnr};
use ipfn::generator::fused::matmul_into;
use ipfn::metrics::{line_score_spread, seam_score, seam_score_of_tiles};
use rayon::prelude::*;

fn photos() -> Vec<PathBuf> {
    if let Ok(list) = std::env::var("IPFN_FIT_PHOTOS") {
        return list.split(',').map(PathBuf::from).collect();
    }
    let mut photos: Vec<PathBuf> = std::fs::read_dir("../shared/exemplars")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg" || e == "png"))
        .collect();
    photos.sort();
    photos.extend(
        ["honeycomb", "bricks", "weave"].map(|n| PathBuf::from(format!("exemplars/{n}.png"))),
    );
    photos
}

struct Row {
    name: String,
    size: String,
    params: usize,
    pixels: usize,
    seconds: f64,
    fit: [f64; 3],
    crossfade: [f64; 3],
    photo_seam: f64,
    /// The photo's own lines scored as seams: "p5 to p95".
    photo_lines: String,
    /// The fitted tile and the cross-faded one, for pooled seam scores.
    tiles: [Vec<f32>; 2],
    channels: usize,
}

/// PSNR whole, PSNR interior and the 2x2 seam score of `tile` against `photo`.
fn scores(tile: &[f32], photo: &ipfn::exemplar::Exemplar, lambda: &[f32]) -> [f64; 3] {
    let (h, w, c) = (photo.height, photo.width, photo.channels);
    let tile: Vec<f32> = tile.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
    [
        psnr(&tile, &photo.values, c, |_| true),
        psnr(&tile, &photo.values, c, |i| lambda[i] == 0.0),
        seam_score(&tile, h, w, c).expect("a tile scores").overall,
    ]
}

/// Fits `path` for `budget`, or `iterations` steps of the last stage where given.
fn measure(
    path: &Path,
    budget: Duration,
    iterations: Option<u64>,
    scratch: &Path,
) -> ipfn::Result<Row> {
    let mut config = FitConfig {
        photo: Some(path.to_path_buf()),
        ..FitConfig::default()
    };
    if let Some(n) = iterations {
        config.iterations = FitConfig::stage_steps(n, config.stages);
    }
    let run = scratch.join(path.file_stem().unwrap_or_default());
    let start = Instant::now();
    let mut fitter = Fitter::start(config, &run, None)?;
    let deadline = match iterations {
        Some(_) => None,
        None => {
            fitter.plan(budget);
            Some(start + budget)
        }
    };
    fitter.run(&AtomicBool::new(false), deadline, |_| {})?;
    let photo = fitter.photo().clone();
    let (h, w) = (photo.height, photo.width);
    let tile = fitter.painter().render([0, 0], [h, w]);
    let seconds = start.elapsed().as_secs_f64();
    let lambda = seam_mask(h, w, fitter.config.seam_band_for([h, w]));
    let crossfade = crossfade_tile(&photo);
    Ok(Row {
        name: path
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into(),
        size: format!("{w}x{h}"),
        params: fitter.net.shape.parameters(),
        pixels: w * h,
        seconds,
        fit: scores(&tile, &photo, &lambda),
        crossfade: scores(&crossfade.values, &photo, &lambda),
        photo_seam: seam_score(&photo.values, h, w, photo.channels)?.overall,
        photo_lines: line_score_spread(&photo.values, h, w, photo.channels)
            .map(|l| format!("{:.2} to {:.2}", l.p5, l.p95))
            .unwrap_or_default(),
        tiles: [tile, crossfade.values],
        channels: photo.channels,
    })
}

/// Five `side x side` windows of the photo at `path`, written to `scratch` as PNGs: the centre
/// and four offsets (in quarters of the room left over, rows and columns each a permutation of
/// 0 to 4), so that no two windows' seams fall on the same line of the photo; fewer where the
/// photo leaves no room to move them.
fn windows(path: &Path, side: usize, scratch: &Path) -> ipfn::Result<Vec<PathBuf>> {
    let photo = read_exemplar(path)?;
    let room = [
        photo.height.saturating_sub(side),
        photo.width.saturating_sub(side),
    ];
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let mut corners: Vec<[usize; 2]> = [(2, 2), (0, 1), (1, 4), (3, 0), (4, 3)]
        .iter()
        .map(|&(qy, qx)| [room[0] * qy / 4, room[1] * qx / 4])
        .collect();
    // A photo hardly larger than the window has fewer distinct windows.
    corners.dedup();
    corners
        .into_iter()
        .map(|at| {
            let cut = photo.window(at, [side, side]);
            let out = scratch.join(format!("{stem}@{},{}.png", at[0], at[1]));
            ipfn::io::write_png(&out, cut.width, cut.height, cut.channels, &cut.values)?;
            Ok(out)
        })
        .collect()
}

/// The seam scores of several fits' tiles of one size together, fitted and cross-faded.
fn pooled(rows: &[Row]) -> Option<[f64; 2]> {
    let first = rows.first()?;
    let (w, h) = first.size.split_once('x')?;
    let (w, h): (usize, usize) = (w.parse().ok()?, h.parse().ok()?);
    let score = |k: usize| {
        let tiles: Vec<&[f32]> = rows.iter().map(|r| r.tiles[k].as_slice()).collect();
        seam_score_of_tiles(&tiles, h, w, first.channels).map(|s| s.overall)
    };
    Some([score(0).ok()?, score(1).ok()?])
}

/// One step of the default last stage on the centre of a photo (at most 512x512) (the seam band's share of points
/// with tangents) beside the same products as bare GEMMs on the same threads.
fn step_against_floor(photo: &Path, scratch: &Path) -> ipfn::Result<()> {
    let image = read_exemplar(photo)?;
    let cut = ipfn::exemplar::Exemplar::centre(&image, 512.min(image.width).min(image.height));
    let path = scratch.join("step.png");
    ipfn::io::write_png(&path, cut.width, cut.height, cut.channels, &cut.values)?;
    let config = FitConfig {
        photo: Some(path),
        stages: 1,
        iterations: vec![13],
        checkpoint_every: 1000,
        ..FitConfig::default()
    };
    let batch = config.batch;
    let mut fitter = Fitter::start(config, &scratch.join("step"), None)?;
    // Steps 3 to 12: after the first (the stage's targets, warm-up), before the last (a
    // checkpoint).
    let mut marks = Vec::new();
    fitter.run(&AtomicBool::new(false), None, |p| {
        if p.iteration == 2 || p.iteration == 12 {
            marks.push(Instant::now());
        }
    })?;
    let step = (marks[1] - marks[0]).as_secs_f64() / 10.0;

    let shape = &fitter.net.shape;
    let stage = Stage::new(
        &shape.stages[0],
        &fitter.net.params[0],
        shape.channels,
        shape.omega0,
        shape.period,
    );
    let lambda = seam_mask(
        cut.height,
        cut.width,
        fitter.config.seam_band_for([cut.height, cut.width]),
    );
    let seam = lambda.iter().filter(|&&l| l > 0.0).count() as f64 / lambda.len() as f64;
    let streams = (1.0 - seam) + 3.0 * seam;
    let layers = stage.shape.layers(shape.channels);
    // Forward, weight gradient and input gradient: three products per layer and stream.
    let flops: f64 = layers
        .iter()
        .map(|(i, o)| 6.0 * (*i * *o) as f64)
        .sum::<f64>()
        * streams
        * batch as f64;
    let rows = CHUNK * 3;
    let parts = 16;
    let repeats = 8;
    let t = Instant::now();
    (0..parts).into_par_iter().for_each(|_| {
        for (i, o) in &layers {
            let (a, b) = (vec![0.5f32; rows * i], vec![0.25f32; i * o]);
            let mut c = vec![0f32; rows * o];
            for _ in 0..repeats {
                matmul_into(&mut c, &a, &b, rows, *o, *i);
            }
        }
    });
    let rate = (parts * repeats) as f64
        * layers
            .iter()
            .map(|(i, o)| 2.0 * (rows * i * o) as f64)
            .sum::<f64>()
        / t.elapsed().as_secs_f64();
    let floor = flops / rate;
    println!();
    println!(
        "| one step, {}x{}, widths {:?}, batch {batch} ({:.0}% with tangents) | seconds | GFLOP/s |",
        cut.width,
        cut.height,
        stage.shape.hidden,
        seam * 100.0
    );
    println!("| --- | --- | --- |");
    println!(
        "| fused CPU step (forward, tangents, backward, Adam) | {step:.3} | {:.1} |",
        flops / step / 1e9
    );
    println!(
        "| GEMM floor: the same products as bare gemm, same threads | {floor:.3} | {:.1} |",
        rate / 1e9
    );
    println!("| ratio | {:.2}x | |", step / floor);
    Ok(())
}

fn print_row(r: &Row) {
    println!(
        "| {} | {} | {} / {} = {:.2} | {:.0} | {:.2} ({:.2}) | {:.3} | {:.2} ({:.2}) | {:.3} | {:.3} | {} |",
        r.name,
        r.size,
        r.params,
        r.pixels,
        r.params as f64 / r.pixels as f64,
        r.seconds,
        r.fit[0],
        r.fit[1],
        r.fit[2],
        r.crossfade[0],
        r.crossfade[1],
        r.crossfade[2],
        r.photo_seam,
        r.photo_lines
    );
}

fn main() -> ipfn::Result<()> {
    let budget = ipfn::train::config::parse_duration(
        &std::env::var("IPFN_FIT_BUDGET").unwrap_or_else(|_| "60s".into()),
    )?;
    let scratch = tempfile::tempdir().expect("a temporary folder");
    let iterations: Option<u64> = std::env::var("IPFN_FIT_ITERATIONS")
        .ok()
        .and_then(|n| n.parse().ok());
    let side: Option<usize> = std::env::var("IPFN_FIT_WINDOWS")
        .ok()
        .and_then(|n| n.parse().ok());
    let work = match iterations {
        Some(n) => format!("{n} steps of the last stage"),
        None => format!("{:.0} s budget", budget.as_secs_f64()),
    };
    println!(
        "ipfn fit, default settings, {work} per photo{}, {} threads",
        side.map(|s| format!(" (five {s}x{s} windows of each)"))
            .unwrap_or_default(),
        rayon::current_num_threads()
    );
    println!();
    println!(
        "| photo | size | params / pixels | fit s | fit PSNR dB (interior) | fit seam 2x2 | cross-fade PSNR dB (interior) | cross-fade seam 2x2 | photo seam 2x2 | photo's own lines (5-95%) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let mut first = None;
    for photo in photos() {
        first.get_or_insert(photo.clone());
        let paths = match side {
            Some(side) => windows(&photo, side, scratch.path())?,
            None => vec![photo.clone()],
        };
        let mut rows = Vec::new();
        for path in paths {
            match measure(&path, budget, iterations, scratch.path()) {
                Ok(r) => {
                    print_row(&r);
                    rows.push(r);
                }
                Err(e) => println!("| {} | error: {e} | | | | | | | | |", path.display()),
            }
        }
        if side.is_some()
            && let Some([fit, crossfade]) = pooled(&rows)
        {
            println!(
                "| {}: the {} windows pooled | | | | | **{fit:.3}** | | {crossfade:.3} | | |",
                photo.display(),
                rows.len()
            );
        }
    }
    println!(
        "| paper (RTX 3090, 512², 500 epochs): 3 hidden of 256 | 512x512 | | 23.8 | 32.51 | | | | | |"
    );
    println!("| paper: 1 hidden of 512, band limit 64 | 512x512 | | | 36.38 | | | | | |");
    println!(
        "| paper: headline tile | 1024x1024 | 855,572 / 1,048,576 = 0.82 | | 31.8 | | | | | |"
    );
    if let Some(photo) = first {
        step_against_floor(&photo, scratch.path())?;
    }
    Ok(())
}
