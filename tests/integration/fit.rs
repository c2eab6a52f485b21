//! `ipfn fit` end to end: a photo that does not tile becomes a tile that does, painted exactly
//! periodic at any size on every device; masks are filled in; `--resume` continues bit for bit;
//! bad input gets one-line errors.

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::common::{assert_error, ipfn, stderr};
use ipfn::device::DeviceChoice;
use ipfn::fit::{FitConfig, FitEnd, Fitter};

/// The flags of a small, quick fit (two stages of 64-wide layers).
const SMALL: &[&str] = &[
    "--stages",
    "2",
    "--frequencies",
    "64",
    "--hidden",
    "64,64",
    "--batch",
    "2048",
    "--quiet",
];

/// Bricks (period 32 across and down) cut to 120x104, so the photo itself does not tile.
fn photo(dir: &Path) -> PathBuf {
    let out = ipfn(
        dir,
        &["draw", "bricks", "--size", "128", "--out", "bricks.png"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let image = image::open(dir.join("bricks.png")).unwrap().to_rgb8();
    let cut = image::imageops::crop_imm(&image, 0, 0, 120, 104).to_image();
    cut.save(dir.join("photo.png")).unwrap();
    dir.join("photo.png")
}

/// Fits `photo.png` into `run/` with `iterations` steps of the last stage.
fn fit(dir: &Path, iterations: &str, extra: &[&str]) {
    let mut args = vec![
        "fit",
        "photo.png",
        "--iterations",
        iterations,
        "--run",
        "run",
    ];
    args.extend_from_slice(SMALL);
    args.extend_from_slice(extra);
    let out = ipfn(dir, &args);
    assert!(out.status.success(), "{}", stderr(&out));
}

fn read_npy(path: &Path) -> (Vec<usize>, Vec<f32>) {
    ipfn::io::read_npy(path).expect("synth wrote a readable .npy")
}

#[test]
fn a_photo_that_does_not_tile_becomes_a_seamless_tile() {
    let dir = tempfile::tempdir().unwrap();
    photo(dir.path());
    fit(dir.path(), "600", &[]);
    for file in [
        "run/tile.ipfn",
        "run/tile.png",
        "run/latest.ipfn",
        "run/metrics.csv",
    ] {
        assert!(dir.path().join(file).is_file(), "{file} is missing");
    }
    let out = ipfn(
        dir.path(),
        &[
            "eval",
            "--model",
            "run",
            "--exemplar",
            "photo.png",
            "--json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let tile = report["seam_tile"]["overall"].as_f64().unwrap();
    let photo = report["seam_photo"]["overall"].as_f64().unwrap();
    let psnr = report["psnr"].as_f64().unwrap();
    eprintln!("seam score: tile {tile:.3}, photo {photo:.3}; PSNR {psnr:.2} dB");
    assert!(
        photo > 2.0,
        "the cut photo should not tile (seam score {photo})"
    );
    assert!(
        (0.85..1.2).contains(&tile),
        "the tile's seam score is {tile}"
    );
    let lines = &report["seam_photo_lines"];
    let (p5, p95) = (
        lines["p5"].as_f64().unwrap(),
        lines["p95"].as_f64().unwrap(),
    );
    assert!(
        p5 < 1.0 && 1.0 < p95 && photo > p95,
        "the photo's own lines score {p5} to {p95}, its wrap {photo}"
    );
    assert!(
        psnr > 24.0,
        "the tile is far from the photo: PSNR {psnr:.2} dB"
    );
}

/// `synth --size 120x104 --width 240 --height 208` repeats the tile 2x2, equal to float
/// precision on `device`, and agrees with the fused CPU path.
fn tile_repeats_on(device: DeviceChoice) {
    let dir = tempfile::tempdir().unwrap();
    photo(dir.path());
    fit(dir.path(), "20", &[]);
    let name = format!("{device:?}").to_lowercase();
    let paint = |device: &str, out: &str| {
        let args = [
            "synth",
            "--model",
            "run/tile.ipfn",
            "--size",
            "120x104",
            "--width",
            "240",
            "--height",
            "208",
            "--device",
            device,
            "--out",
            out,
            "--quiet",
        ];
        let o = ipfn(dir.path(), &args);
        assert!(o.status.success(), "{}", stderr(&o));
        read_npy(&dir.path().join(out))
    };
    let (shape, values) = paint(&name, "big.npy");
    assert_eq!(shape, vec![208, 240, 3]);
    let at = |y: usize, x: usize, c: usize| values[(y * 240 + x) * 3 + c];
    let mut worst = 0f32;
    for y in 0..104 {
        for x in 0..120 {
            for c in 0..3 {
                for (dy, dx) in [(0, 120), (104, 0), (104, 120)] {
                    worst = worst.max((at(y, x, c) - at(y + dy, x + dx, c)).abs());
                }
            }
        }
    }
    assert!(worst <= 1e-6, "{name}: repeats differ by {worst}");
    let (_, cpu) = paint("cpu", "cpu.npy");
    let diff = common::max_abs_diff(&values, &cpu);
    assert!(diff < 1e-3, "{name} and cpu differ by {diff}");
}

test_device!(
    tile_repeats_on,
    tile_repeats_cpu,
    tile_repeats_flex,
    tile_repeats_wgpu
);

#[test]
fn masked_pixels_are_filled_in_by_the_periodic_structure() {
    let dir = tempfile::tempdir().unwrap();
    // Weave, period 16: a 64x64 image holds 4x4 periods, and a tile of one period
    // (`--period 16`) sees the hole (the central 32x32, a quarter of the pixels) elsewhere.
    let out = ipfn(
        dir.path(),
        &["draw", "weave", "--size", "64", "--out", "photo.png"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let mask = image::GrayImage::from_fn(64, 64, |x, y| {
        let hole = (16..48).contains(&x) && (16..48).contains(&y);
        image::Luma([if hole { 0 } else { 255 }])
    });
    mask.save(dir.path().join("mask.png")).unwrap();
    let args = [
        "--mask",
        "mask.png",
        "--period",
        "16",
        "--band-limit",
        "4",
        "--out",
        "tile.npy",
    ];
    fit(dir.path(), "300", &args);
    let photo = ipfn::exemplar::read_exemplar(&dir.path().join("photo.png")).unwrap();
    // The tile is one 16x16 period; the photo holds 4x4 of them.
    let (shape, period) = read_npy(&dir.path().join("tile.npy"));
    assert_eq!(shape, vec![16, 16, 3]);
    let tile: Vec<f32> = (0..64 * 64)
        .flat_map(|i| {
            let (y, x) = (i / 64 % 16, i % 64 % 16);
            period[(y * 16 + x) * 3..][..3].to_vec()
        })
        .collect();
    let hole = |i: usize| (16..48).contains(&(i % 64)) && (16..48).contains(&(i / 64));
    let inside = ipfn::fit::psnr(&tile, &photo.values, 3, hole);
    let outside = ipfn::fit::psnr(&tile, &photo.values, 3, |i| !hole(i));
    eprintln!("PSNR in the hole {inside:.2} dB, around it {outside:.2} dB");
    assert!(
        inside > 30.0,
        "the hole is not recovered: PSNR {inside:.2} dB"
    );
}

fn config(dir: &Path) -> FitConfig {
    FitConfig {
        photo: Some(photo(dir)),
        stages: 2,
        frequencies: 32,
        hidden: vec![32, 32],
        batch: 512,
        iterations: vec![6, 12],
        checkpoint_every: 5,
        ..FitConfig::default()
    }
}

#[test]
fn resume_continues_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let whole = {
        let mut f = Fitter::start(config(dir.path()), &dir.path().join("a"), None).unwrap();
        assert_eq!(
            f.run(&AtomicBool::new(false), None, |_| {}).unwrap(),
            FitEnd::Done
        );
        f.net.params.clone()
    };
    let stop = AtomicBool::new(false);
    {
        let mut f = Fitter::start(config(dir.path()), &dir.path().join("b"), None).unwrap();
        let end = f
            .run(&stop, None, |p| {
                if p.stage == 1 && p.iteration == 7 {
                    stop.store(true, Ordering::SeqCst);
                }
            })
            .unwrap();
        assert_eq!(end, FitEnd::Stopped);
    }
    let mut f = Fitter::resume(&dir.path().join("b"), None).unwrap();
    assert_eq!((f.stage, f.iteration), (1, 7));
    assert_eq!(
        f.run(&AtomicBool::new(false), None, |_| {}).unwrap(),
        FitEnd::Done
    );
    assert!(
        f.net.params == whole,
        "a resumed fit differs from one run in one go"
    );
}

#[test]
fn bad_input_gets_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    photo(dir.path());
    image::GrayImage::new(10, 10)
        .save(dir.path().join("small-mask.png"))
        .unwrap();
    let out = ipfn(
        dir.path(),
        &["fit", "photo.png", "--mask", "small-mask.png"],
    );
    assert_error(&out, &["small-mask.png", "10x10", "120x104"]);
    let out = ipfn(dir.path(), &["fit", "photo.png", "--band-limit", "53"]);
    assert_error(&out, &["--band-limit 53", "Nyquist", "52"]);
    let out = ipfn(dir.path(), &["fit", "photo.png", "--period", "0x20"]);
    assert_error(&out, &["photo.png", "a period of 0x20"]);
    fit(dir.path(), "2", &[]);
    let out = ipfn(
        dir.path(),
        &["synth", "--model", "run/tile.ipfn", "--lod", "3"],
    );
    assert_error(&out, &["--lod 3", "2 stages"]);
    let out = ipfn(
        dir.path(),
        &["synth", "--model", "run/tile.ipfn", "--size", "0"],
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let out = ipfn(dir.path(), &["fit", "photo.png", "--run", "run"]);
    assert_error(&out, &["already holds a fit", "--resume"]);
    // A finished fit has nothing left to resume: it says so and names its tile.
    let out = ipfn(dir.path(), &["fit", "--resume", "run"]);
    assert_error(&out, &["latest.ipfn", "this fit is complete", "tile.ipfn"]);
}

/// `--device flex` (burn's autodiff, the path GPUs take) fits what the fused CPU path fits.
#[test]
fn burn_devices_fit_what_the_cpu_fits() {
    let dir = tempfile::tempdir().unwrap();
    let fitted = |name: &str, device: Option<burn::tensor::Device>| {
        let mut f = Fitter::start(config(dir.path()), &dir.path().join(name), device).unwrap();
        f.run(&AtomicBool::new(false), None, |_| {}).unwrap();
        f.net.params.concat()
    };
    let cpu = fitted("cpu", None);
    let flex = fitted("flex", Some(burn::tensor::Device::flex()));
    let diff = common::max_abs_diff(&flex, &cpu);
    assert!(diff < 1e-3, "flex and cpu fits differ by {diff}");
}

/// A map set is fitted by one network; the tile and synth write one file per map, at the maps'
/// bit depth (16-bit PNGs here).
#[test]
fn a_map_set_fits_as_one_network() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &["draw", "material", "--size", "96", "--out", "mat"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let maps = "mat/albedo.png,mat/normal.png,mat/roughness.png,mat/height.png";
    let mut args = vec!["fit", "--maps", maps, "--iterations", "20", "--run", "run"];
    args.extend_from_slice(SMALL);
    let out = ipfn(dir.path(), &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let args = [
        "synth", "--model", "run", "--size", "48", "--out", "s.png", "--quiet",
    ];
    let out = ipfn(dir.path(), &args);
    assert!(out.status.success(), "{}", stderr(&out));
    for map in ["albedo", "normal", "roughness", "height"] {
        for file in [format!("run/tile-{map}.png"), format!("s-{map}.png")] {
            let image = image::open(dir.path().join(&file)).unwrap();
            assert_eq!(
                image.color().bits_per_pixel() % 16,
                0,
                "{file} is not 16-bit"
            );
        }
    }
    let size = image::image_dimensions(dir.path().join("s-albedo.png")).unwrap();
    assert_eq!(size, (48, 48));
}
