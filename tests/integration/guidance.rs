//! Directional guidance (conditional IPFN) end to end: train with `--guide x` on stripes that
//! brighten from left to right, then paint with a ramp the exemplar never had.

use crate::common::{assert_error, ipfn, max_abs_diff, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::condition::Guide;
use ipfn::device::DeviceChoice;
use ipfn::generator::GeneratorWeights;
use ipfn::io::read_npy;
use ipfn::synth::Synth;

use crate::common::SMALL_CONFIG as CONFIG;

/// Mean of the first channel over the left and the right third of `[h, w, c]` values.
fn left_right(values: &[f32], w: usize, c: usize) -> (f64, f64) {
    let (mut l, mut r, mut nl, mut nr) = (0.0, 0.0, 0, 0);
    for (i, px) in values.chunks_exact(c).enumerate() {
        let x = i % w;
        if x < w / 3 {
            l += px[0] as f64;
            nl += 1;
        } else if x >= w - w / 3 {
            r += px[0] as f64;
            nr += 1;
        }
    }
    (l / nl as f64, r / nr as f64)
}

#[test]
fn a_guided_model_follows_a_ramp_the_exemplar_never_had() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("g.toml"), CONFIG).unwrap();
    assert!(
        ipfn(d, &["draw", "graded", "--size", "128", "-o", "graded.png"])
            .status
            .success()
    );
    let out = ipfn(
        d,
        &[
            "train",
            "graded.png",
            "--config",
            "g.toml",
            "--guide",
            "x",
            "--iterations",
            "300",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));

    let synth = |guide: &str, out: &str| {
        let o = ipfn(
            d,
            &[
                "synth",
                "--model",
                "run/latest.ipfn",
                "--size",
                "96",
                &format!("--guide={guide}"),
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        read_npy(&d.join(out)).unwrap().1
    };
    // As trained: brighter to the right.
    let (l, r) = left_right(&synth("x", "x.npy"), 96, 3);
    eprintln!("--guide x: left {l:.3}, right {r:.3}");
    assert!(r - l > 0.3, "--guide x: left {l}, right {r}");
    // Reversed, which the exemplar never showed: brighter to the left.
    let (l, r) = left_right(&synth("-x", "rev.npy"), 96, 3);
    eprintln!("--guide -x: left {l:.3}, right {r:.3}");
    assert!(l - r > 0.3, "--guide -x: left {l}, right {r}");
    // The same reversed ramp painted as a grayscale image.
    let ramp: Vec<f32> = (0..96 * 96)
        .map(|i| 1.0 - 2.0 * ((i % 96) as f32 + 0.5) / 96.0)
        .collect();
    ipfn::io::write_png(&d.join("ramp.png"), 96, 96, 1, &ramp).unwrap();
    let (l, r) = left_right(&synth("ramp.png", "img.npy"), 96, 3);
    assert!(l - r > 0.3, "--guide ramp.png: left {l}, right {r}");

    // The fused CPU evaluator and burn agree on a guided model.
    let ckpt = Checkpoint::load(&d.join("run/latest.ipfn")).unwrap();
    let (config, weights) = GeneratorWeights::read_from(&ckpt).unwrap();
    assert_eq!(config.guidance, 1);
    let render = |device| {
        Synth::new(config.clone(), weights.clone())
            .seed(2)
            .offset(&[3, -7])
            .guide(
                Guide::Line {
                    a: -0.5,
                    b: 0.8,
                    c: 0.1,
                },
                [30, 40],
            )
            .device(device)
            .painter()
            .unwrap()
            .render(&[0, 0], &[30, 40])
    };
    let diff = max_abs_diff(&render(DeviceChoice::Cpu), &render(DeviceChoice::Flex));
    assert!(diff < 1e-4, "fused vs flex on a guided model: {diff}");

    // Errors: a guided model without --guide, a guide image of another size, a bad line,
    // --guide on a model trained without it, and changing the guide on resume.
    assert_error(
        &ipfn(
            d,
            &["synth", "--model", "run/latest.ipfn", "--out", "a.png"],
        ),
        &["guided", "--guide"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "run/latest.ipfn",
                "--size",
                "64",
                "--guide",
                "ramp.png",
                "--out",
                "b.png",
            ],
        ),
        &["--guide", "96x96", "64x64"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "run/latest.ipfn",
                "--guide",
                "sideways",
                "--out",
                "c.png",
            ],
        ),
        &["--guide sideways"],
    );
    assert_error(
        &ipfn(d, &["synth", "--guide", "x", "--out", "e.png"]),
        &["--guide", "without guidance"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "train",
                "graded.png",
                "--config",
                "g.toml",
                "--guide",
                "1,2",
                "--out",
                "bad",
            ],
        ),
        &["--guide 1,2"],
    );
    assert_error(
        &ipfn(d, &["train", "--resume", "run", "--guide", "y"]),
        &["--guide", "cannot change"],
    );
}
