//! SIFID, seam score and periods: against an independent evaluation (TensorFlow.js running the
//! Keras model, scipy's sqrtm), on properties any working metric has, and through `ipfn eval`.
//!
//! tests/data/sifid/expected.json was made by tools/inception-stem/{reference.js,reference.py};
//! see tools/inception-stem/README.md to rerun them. Never edit the expected values to pass.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{assert_error, ipfn, stderr};
use ipfn::metrics::{self, Gaussian, InceptionStem, frechet_distance};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(root().join("tests/data/sifid/expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A square crop (`[size, size, 3]` in [0, 1]) of an image, as the reference script takes it.
fn crop(file: &str, x0: usize, y0: usize, size: usize) -> Vec<f32> {
    let image = ipfn::exemplar::read_exemplar(&root().join(file)).unwrap();
    let rgb = metrics::to_unit_rgb(&image.values, image.channels).unwrap();
    let mut out = Vec::with_capacity(size * size * 3);
    for y in y0..y0 + size {
        let at = (y * image.width + x0) * 3;
        out.extend_from_slice(&rgb[at..at + size * 3]);
    }
    out
}

fn reference_input(expected: &serde_json::Value, name: &str) -> Vec<f32> {
    let spec = &expected["inputs"][name];
    let n = |i: usize| spec[i].as_u64().unwrap() as usize;
    crop(spec[0].as_str().unwrap(), n(1), n(2), n(3))
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn features_match_tensorflow_js_running_the_keras_model() {
    let expected = expected();
    let stem = InceptionStem::embedded();
    let probes: Vec<usize> = floats(&expected["probe_positions"])
        .iter()
        .map(|&p| p as usize)
        .collect();
    for name in ["honeycomb_a", "honeycomb_b", "bricks"] {
        let f = stem
            .features(&reference_input(&expected, name), 128, 128)
            .unwrap();
        assert_eq!(
            [f.height, f.width, f.channels],
            [28, 28, 192],
            "feature map shape"
        );
        let means = floats(&expected["channel_means"][name]);
        let positions = (f.height * f.width) as f64;
        let mut worst = 0.0f64;
        for (c, want) in means.iter().enumerate() {
            let got: f64 = f.values[c..]
                .iter()
                .step_by(192)
                .map(|&v| v as f64)
                .sum::<f64>()
                / positions;
            worst = worst.max((got - want).abs() / (1.0 + want.abs()));
        }
        for (row, &p) in expected["probe_features"][name]
            .as_array()
            .unwrap()
            .iter()
            .zip(&probes)
        {
            for (c, want) in floats(row).iter().enumerate() {
                let got = f.values[p * 192 + c] as f64;
                worst = worst.max((got - want).abs() / (1.0 + want.abs()));
            }
        }
        // f32 convolutions in another order (and tfjs' own dequantization) agree this closely;
        // a wrong padding, layout or batch-norm fold is off by far more than 1e-3.
        assert!(worst < 1e-3, "{name}: worst relative difference {worst:e}");
        eprintln!("{name}: worst relative difference to tfjs {worst:.2e}");
    }
}

#[test]
fn sifid_matches_scipy_and_separates_textures() {
    let expected = expected();
    let stem = InceptionStem::embedded();
    let gauss = |name: &str| {
        Gaussian::fit(
            &stem
                .features(&reference_input(&expected, name), 128, 128)
                .unwrap(),
        )
        .unwrap()
    };
    let (a, b, bricks) = (gauss("honeycomb_a"), gauss("honeycomb_b"), gauss("bricks"));
    let same = frechet_distance(&a, &a);
    let crops = frechet_distance(&a, &b);
    let other = frechet_distance(&a, &bricks);
    let want = &expected["sifid"];
    let want_crops = want["honeycomb_a/honeycomb_b"].as_f64().unwrap();
    let want_other = want["honeycomb_a/bricks"].as_f64().unwrap();
    eprintln!(
        "SIFID self {same:.2e}, crops {crops:.5} (scipy {want_crops:.5}), bricks {other:.4} (scipy {want_other:.4})"
    );
    // An image with itself: 0 up to rounding.
    assert!(same.abs() < 1e-6, "self SIFID {same}");
    assert!(
        (crops - want_crops).abs() < 1e-3 * want_crops,
        "{crops} vs {want_crops}"
    );
    assert!(
        (other - want_other).abs() < 1e-3 * want_other,
        "{other} vs {want_other}"
    );
    // Two crops of one stationary texture score far lower than two textures.
    assert!(crops * 10.0 < other, "crops {crops}, other texture {other}");
}

#[test]
fn other_textures_score_far_above_crops_of_one() {
    let sifid = |a: &[f32], b: &[f32]| metrics::sifid((a, 96, 96), (b, 96, 96)).unwrap();
    let honey = [
        crop("exemplars/honeycomb.png", 0, 0, 96),
        crop("exemplars/honeycomb.png", 150, 40, 96),
    ];
    let weave = [
        crop("exemplars/weave.png", 10, 10, 96),
        crop("exemplars/weave.png", 140, 120, 96),
    ];
    let within = sifid(&honey[0], &honey[1]).max(sifid(&weave[0], &weave[1]));
    let across = sifid(&honey[0], &weave[0]).min(sifid(&honey[1], &weave[1]));
    assert!(within * 5.0 < across, "within {within}, across {across}");
}

/// `npm pack nsfwjs@4.4.0` + convert.js must give the committed asset byte for byte. Runs where
/// npm and its registry are reachable (CI installs npm).
#[test]
#[ignore = "needs npm and its registry; run by `cargo test --release -- --ignored`"]
fn inception_stem_is_rederived_from_the_npm_tarball() {
    assert!(
        Command::new("npm").arg("--version").output().is_ok(),
        "npm is not installed (apt-get install npm)"
    );
    let dir = tempfile::tempdir().unwrap();
    let pack = Command::new("npm")
        .args(["pack", "--silent", "nsfwjs@4.4.0"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(pack.status.success(), "npm pack failed: {}", stderr(&pack));
    let tarball = dir.path().join("nsfwjs-4.4.0.tgz");
    let out = dir.path().join("stem.safetensors");
    let convert = Command::new("node")
        .arg(root().join("tools/inception-stem/convert.js"))
        .args([&tarball, &out])
        .output()
        .unwrap();
    assert!(
        convert.status.success(),
        "convert.js failed: {}",
        stderr(&convert)
    );
    let rebuilt = std::fs::read(&out).unwrap();
    let committed = std::fs::read(root().join("assets/inception_v3_stem.safetensors")).unwrap();
    assert!(
        rebuilt == committed,
        "assets/inception_v3_stem.safetensors differs from the one derived from the tarball"
    );
}

fn json(out: &std::process::Output) -> serde_json::Value {
    assert!(out.status.success(), "ipfn eval failed: {}", stderr(out));
    serde_json::from_slice(&out.stdout).expect("--json prints one JSON object")
}

#[test]
fn eval_images_compares_two_files() {
    let dir = tempfile::tempdir().unwrap();
    let honey = root().join("exemplars/honeycomb.png");
    let bricks = root().join("exemplars/bricks.png");
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let same = json(&ipfn(
        dir.path(),
        &["eval", "--images", &path(&honey), &path(&honey), "--json"],
    ));
    let other = json(&ipfn(
        dir.path(),
        &["eval", "--images", &path(&honey), &path(&bricks), "--json"],
    ));
    assert!(same["sifid"].as_f64().unwrap().abs() < 1e-6, "{same}");
    assert!(other["sifid"].as_f64().unwrap() > 50.0, "{other}");
    assert!(other["metric"].as_str().unwrap().contains("not comparable"));
    // Structure: an image against itself is exactly 0; bricks against the honeycomb (its lags,
    // its floor) are far above the honeycomb's own halves (measured: 0.331 against 0.038).
    assert_eq!(same["structure"].as_f64(), Some(0.0), "{same}");
    assert_eq!(same["structure_floor"], other["structure_floor"]);
    assert_eq!(other["structure_lags"], 64, "a quarter of 256");
    let floor = other["structure_floor"].as_f64().unwrap();
    let apart = other["structure"].as_f64().unwrap();
    assert!(
        floor > 0.0 && apart > 3.0 * floor,
        "bricks {apart}, floor {floor}"
    );
    let text = ipfn(
        dir.path(),
        &["eval", "--images", &path(&honey), &path(&bricks)],
    );
    assert!(text.status.success(), "{}", stderr(&text));
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(
        text.contains("SIFID ") && text.contains("structure "),
        "{text}"
    );
}

#[test]
fn eval_scores_the_shipped_model_against_its_exemplar() {
    let dir = tempfile::tempdir().unwrap();
    let exemplar = root().join("exemplars/honeycomb.png");
    let report = json(&ipfn(
        dir.path(),
        &[
            "eval",
            "--exemplar",
            exemplar.to_str().unwrap(),
            "--samples",
            "4",
            "--json",
        ],
    ));
    let sifid = &report["sifid"];
    assert_eq!(sifid["values"].as_array().unwrap().len(), 4);
    // The structure distance of the same samples, beside the exemplar's own floor: the
    // authors' model paints the honeycomb's arrangement, so about as close as the exemplar's
    // halves are to it (measured: 0.025 against a floor of 0.038; bricks score 0.33).
    let structure = &report["structure"];
    assert_eq!(structure["values"].as_array().unwrap().len(), 4);
    let (distance, floor) = (
        structure["mean"].as_f64().unwrap(),
        report["structure_floor"].as_f64().unwrap(),
    );
    assert!(floor.is_finite() && floor > 0.0, "floor {floor}");
    assert!(
        distance.is_finite() && distance > 0.0 && distance < 1.5 * floor,
        "structure {distance}, floor {floor}"
    );
    let mean = sifid["mean"].as_f64().unwrap();
    // The authors' trained model paints honeycomb: far closer to its exemplar than bricks are.
    let bricks = metrics::sifid(
        (&crop("exemplars/bricks.png", 0, 0, 256), 256, 256),
        (&crop("exemplars/honeycomb.png", 0, 0, 256), 256, 256),
    )
    .unwrap();
    assert!(
        mean > 0.0 && mean * 5.0 < bricks,
        "model {mean}, bricks {bricks}"
    );
    // --tile samples wrap without a visible seam (one seamless line scores 0.7 to 1.5 depending
    // on where it falls in the pattern; four tiles average that); the exemplar image, not a tile, does not.
    let seam = report["seam_model_tile"]["overall"].as_f64().unwrap();
    assert!((0.75..1.3).contains(&seam), "tile seam score {seam}");
    let photo_seam = report["seam_exemplar"]["overall"].as_f64().unwrap();
    assert!(
        photo_seam > 3.0,
        "exemplar seam score {photo_seam}, tile {seam}"
    );
    // The learned period and the exemplar's autocorrelation period agree (within 10%, or one is
    // a whole multiple of the other's harmonic).
    for axis in 0..2 {
        let model = report["period_model"][axis].as_f64().unwrap();
        let photo = report["period_exemplar"][axis].as_f64().unwrap();
        let ratio = model / photo;
        let nearest = ratio.round().max(1.0);
        assert!(
            (ratio - nearest).abs() < 0.1 * nearest,
            "axis {axis}: model period {model}, exemplar {photo}"
        );
    }
    // A honeycomb repeats clearly, and the authors' model about as strongly as its photo
    // (measured: 0.61 x 0.56 against 0.53 x 0.49); a grid of copies would be near 1.
    for axis in 0..2 {
        let model = report["repeat_model"][axis].as_f64().unwrap();
        let photo = report["repeat_exemplar"][axis].as_f64().unwrap();
        assert!(
            photo > 0.4 && (model - photo).abs() < 0.15,
            "axis {axis}: {model}, {photo}"
        );
    }
}

#[test]
fn eval_bad_input_gets_one_line_and_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ipfn::io::write_png(&d.join("tiny.png"), 8, 8, 3, &[0.0; 8 * 8 * 3]).unwrap();
    std::fs::write(d.join("junk.png"), b"not a png").unwrap();
    let honey = root().join("exemplars/honeycomb.png");
    let honey = honey.to_str().unwrap();
    assert_error(
        &ipfn(d, &["eval", "--images", "tiny.png", honey]),
        &["tiny.png", "too small"],
    );
    assert_error(
        &ipfn(d, &["eval", "--images", "missing.png", honey]),
        &["missing.png"],
    );
    assert_error(
        &ipfn(d, &["eval", "--images", "junk.png", honey]),
        &["junk.png"],
    );
    assert_error(
        &ipfn(d, &["eval", "--exemplar", "tiny.png"]),
        &["tiny.png", "too small"],
    );
    assert_error(
        &ipfn(d, &["eval", "--exemplar", honey, "--samples", "0"]),
        &["--samples"],
    );
    // Neither --exemplar nor --images: clap's usage error (exit 2).
    let out = ipfn(d, &["eval"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}
