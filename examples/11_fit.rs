//! The guide's "`ipfn fit`: a photo into a seamless tile" (docs/guide/fit.md), as library calls.
//!
//! `cargo run --release --example 11_fit` draws bricks, cuts them to 100x76 pixels (so the photo
//! itself does not tile), fits a periodic network to the cut for 400 steps, writes the tile at
//! twice the photo's resolution laid 2x2 (`11_fit.png`) and a quarter-size rendering at level of
//! detail 1 (`11_fit_lod.png`), and prints the seam scores of the photo and of the tile.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use ipfn::exemplar::Exemplar;
use ipfn::fit::{FitConfig, Fitter, TilePainter};
use ipfn::io::write_png;
use ipfn::metrics::seam_score;

fn main() -> ipfn::Result<()> {
    let scratch = tempfile::tempdir().expect("a temporary folder");
    let bricks = ipfn::procedural::bricks(128, 128, 32, 16);
    let photo = Exemplar::from_unit(100, 76, 3, &crop(&bricks, 128, 100, 76));
    let photo_path = scratch.path().join("photo.png");
    write_png(&photo_path, photo.width, photo.height, 3, &photo.values)?;

    let config = FitConfig {
        photo: Some(photo_path),
        iterations: FitConfig::stage_steps(400, 3),
        frequencies: 128,
        hidden: vec![128, 128],
        batch: 4096,
        ..FitConfig::default()
    };
    let mut fitter = Fitter::start(config, &scratch.path().join("run"), None)?;
    fitter.run(&AtomicBool::new(false), None, |_| {})?;

    // Twice the resolution, laid 2x2: the network is continuous and exactly periodic.
    let mut painter = TilePainter::new(fitter.net.clone());
    painter.resolution = [152, 200];
    let big = painter.render([0, 0], [304, 400]);
    write_png(Path::new("11_fit.png"), 400, 304, 3, &big)?;
    // A quarter of the photo's size with the top stage faded out: anti-aliased, no resampling.
    painter.resolution = [19, 25];
    painter.lod = 1.0;
    let small = painter.render([0, 0], [19, 25]);
    write_png(Path::new("11_fit_lod.png"), 25, 19, 3, &small)?;

    let tile = TilePainter::new(fitter.net.clone()).render([0, 0], [76, 100]);
    let tile: Vec<f32> = tile.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
    println!(
        "seam score laid 2x2: photo {:.2}, fitted tile {:.2} (about 1 is seamless); wrote 11_fit.png and 11_fit_lod.png",
        seam_score(&photo.values, 76, 100, 3)?.overall,
        seam_score(&tile, 76, 100, 3)?.overall
    );
    Ok(())
}

/// The top-left `width x height` of a square RGB image of `side` pixels, as unit values.
fn crop(image: &[f32], side: usize, width: usize, height: usize) -> Vec<f32> {
    (0..height)
        .flat_map(|y| image[y * side * 3..(y * side + width) * 3].iter().copied())
        .collect()
}
