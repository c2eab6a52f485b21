//! Solid textures from a 2D exemplar (Henzler et al. 2020): `train --solid` learns a
//! 3D generator whose axis-aligned slices look like the exemplar; `synth --slice` writes those
//! slices and `synth --solid --size WxHxD` the volume.

use crate::common::{assert_error, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::exemplar::read_exemplar;
use ipfn::generator::GeneratorWeights;
use ipfn::io::read_npy;
use ipfn::metrics::{sifid, to_unit_rgb};
use ipfn::synth::Synth;

use crate::common::SMALL_CONFIG as CONFIG;

const SIDE: usize = 96;

/// SIFID of each axis's slice (x, y, z at index 40 of a SIDE³ volume) against the exemplar.
fn slice_scores(
    d: &std::path::Path,
    model: &str,
    exemplar: &[f32],
    ex_side: usize,
) -> Vec<(char, f64)> {
    let size = format!("{SIDE}x{SIDE}x{SIDE}");
    ['x', 'y', 'z']
        .iter()
        .map(|&axis| {
            let out = format!("{model}-{axis}.npy");
            let o = ipfn(
                d,
                &[
                    "synth",
                    "--model",
                    model,
                    "--solid",
                    "--size",
                    &size,
                    "--slice",
                    &format!("{axis}=40"),
                    "--out",
                    &out,
                ],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            let (shape, values) = read_npy(&d.join(&out)).unwrap();
            assert_eq!(
                shape,
                vec![SIDE, SIDE, 3],
                "slice {axis} is {SIDE}x{SIDE} RGB"
            );
            let score = sifid(
                (&to_unit_rgb(&values, 3).unwrap(), SIDE, SIDE),
                (&to_unit_rgb(exemplar, 3).unwrap(), ex_side, ex_side),
            )
            .unwrap();
            (axis, score)
        })
        .collect()
}

#[test]
fn slices_of_a_solid_texture_resemble_the_exemplar_along_every_axis() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("s.toml"), CONFIG).unwrap();
    assert!(
        ipfn(d, &["draw", "weave", "--size", "128", "-o", "weave.png"])
            .status
            .success()
    );
    let exemplar = read_exemplar(&d.join("weave.png")).unwrap();
    // The same run, 1 iteration (nearly untrained) and 300 iterations.
    for (iterations, run) in [("1", "untrained"), ("300", "run")] {
        let out = ipfn(
            d,
            &[
                "train",
                "weave.png",
                "--solid",
                "--config",
                "s.toml",
                "--iterations",
                iterations,
                "--out",
                run,
            ],
        );
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let model = Checkpoint::load(&d.join("run/latest.ipfn")).unwrap();
    let (config, _) = GeneratorWeights::read_from(&model).unwrap();
    assert_eq!((config.dims, config.channels), (3, 3), "a 3D RGB generator");

    let trained = slice_scores(d, "run/latest.ipfn", &exemplar.values, 128);
    let untrained = slice_scores(d, "untrained/latest.ipfn", &exemplar.values, 128);
    for ((axis, t), (_, u)) in trained.iter().zip(&untrained) {
        eprintln!("slice {axis}: SIFID trained {t:.2}, untrained {u:.2}");
    }
    for ((axis, t), (_, u)) in trained.iter().zip(&untrained) {
        assert!(
            *t < 0.5 * u,
            "slice {axis}: SIFID {t:.2} trained is not under half of {u:.2} untrained"
        );
    }

    // The whole volume: [D, H, W, 3], and its z=40 plane is the z slice written above.
    let o = ipfn(
        d,
        &[
            "synth",
            "--model",
            "run/latest.ipfn",
            "--solid",
            "--size",
            &format!("{SIDE}x{SIDE}x{SIDE}"),
            "--out",
            "volume.npy",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, volume) = read_npy(&d.join("volume.npy")).unwrap();
    assert_eq!(shape, vec![SIDE, SIDE, SIDE, 3]);
    let (_, z40) = read_npy(&d.join("run/latest.ipfn-z.npy")).unwrap();
    let plane = SIDE * SIDE * 3;
    assert_eq!(
        &volume[40 * plane..41 * plane],
        &z40[..],
        "slice z=40 is plane 40"
    );

    // The library gives the same plane.
    let (config, weights) = GeneratorWeights::read_from(&model).unwrap();
    let painter = Synth::new(config, weights).painter().unwrap();
    assert_eq!(painter.render(&[40, 0, 0], &[1, SIDE, SIDE]), z40);
}

#[test]
fn slice_and_solid_errors_are_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The shipped model is 2D.
    assert_error(
        &ipfn(d, &["synth", "--slice", "z=0", "--out", "s.png"]),
        &["--slice", "3D model"],
    );
    assert_error(
        &ipfn(d, &["synth", "--solid", "--size", "64", "--out", "s.png"]),
        &["--solid", "WxHxD"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth", "--slice", "z=64", "--size", "32x32x64", "--out", "s.png",
            ],
        ),
        &["--slice z=64", "64 voxels along z"],
    );
    // Malformed values are clap's errors (exit 2, with a usage hint).
    let bad = ipfn(d, &["synth", "--slice", "w=3", "--out", "s.png"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("AXIS=INDEX"), "{}", stderr(&bad));
    assert_error(
        &ipfn(d, &["synth", "--size", "64x0x4", "--out", "s.npy"]),
        &["at least 1"],
    );
    std::fs::write(d.join("s.toml"), CONFIG).unwrap();
    assert!(
        ipfn(d, &["draw", "weave", "--size", "64", "-o", "w.png"])
            .status
            .success()
    );
    assert_error(
        &ipfn(
            d,
            &[
                "train", "w.png", "--solid", "--guide", "x", "--config", "s.toml",
            ],
        ),
        &["--solid", "--guide"],
    );
}
