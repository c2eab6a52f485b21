//! Volumes (groundwork for 3D): signed-distance volumes in, and chunked volume synthesis with a
//! 3D generator out, identical in any chunking.

use crate::common;

use crate::common::{assert_error, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::exemplar::read_sdf_volume;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::io::read_npy;
use ipfn::synth::Synth;
use npyz::WriterBuilder;

fn model_3d() -> (GeneratorConfig, GeneratorWeights) {
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_hidden_layers(3)
        .with_width(24)
        .with_crop(32);
    let mut weights = GeneratorWeights::random(&config, 0);
    // Centre the output on 0, so the volume has a zero level set to mesh.
    let probe = Synth::new(config.clone(), weights.clone())
        .seed(0)
        .painter()
        .unwrap()
        .render(&[0, 0, 0], &[8, 8, 8]);
    let mean = probe.iter().sum::<f32>() / probe.len() as f32;
    weights.layers.last_mut().unwrap().bias[0] -= mean.atanh();
    (config, weights)
}

#[test]
fn sdf_volumes_are_read_scaled_and_clamped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = ipfn(d, &["draw", "gyroid", "--size", "32", "-o", "g.npy"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (shape, raw) = read_npy(&d.join("g.npy")).unwrap();
    assert_eq!(shape, [32, 32, 32, 1]);
    let v = read_sdf_volume(&d.join("g.npy"), 10.0).unwrap();
    assert_eq!((v.depth, v.height, v.width, v.channels), (32, 32, 32, 1));
    for (a, b) in raw.iter().zip(&v.values) {
        assert_eq!((a * 10.0).clamp(-1.0, 1.0), *b);
    }
    // The gyroid sheet is porous: some of the volume is inside, most outside.
    let inside = v.values.iter().filter(|x| **x < 0.0).count() as f64 / v.values.len() as f64;
    assert!((0.1..0.5).contains(&inside), "solid fraction {inside}");

    // Not a 3D float volume: one line naming the file.
    {
        let file = std::io::BufWriter::new(std::fs::File::create(d.join("flat.npy")).unwrap());
        let mut w = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[4, 8])
            .writer(file)
            .begin_nd()
            .unwrap();
        w.extend([0.0f32; 32]).unwrap();
        w.finish().unwrap();
    }
    let err = read_sdf_volume(&d.join("flat.npy"), 10.0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("flat.npy") && err.contains("3D float array"),
        "{err}"
    );
    std::fs::write(d.join("junk.npy"), b"not numpy").unwrap();
    let err = read_sdf_volume(&d.join("junk.npy"), 10.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("junk.npy"), "{err}");
}

#[test]
fn volume_synthesis_is_the_same_in_any_chunking() {
    let (config, weights) = model_3d();
    let painter = Synth::new(config, weights).seed(9).painter().unwrap();
    let (dd, h, w) = (9, 11, 13);
    let whole = painter.render(&[0, 0, 0], &[dd, h, w]);
    // Slabs of one slice, and of four, concatenate to the whole.
    for slab in [1, 4] {
        let mut parts = Vec::new();
        let mut z = 0;
        while z < dd {
            let n = slab.min(dd - z);
            parts.extend(painter.render(&[z as i64, 0, 0], &[n, h, w]));
            z += n;
        }
        assert_eq!(parts, whole, "slabs of {slab}");
    }
    // A sub-box at an origin is that part of the whole (its rows are evaluated in other
    // chunks, so equal up to float rounding).
    let sub = painter.render(&[2, 3, 5], &[4, 5, 6]);
    for a in 0..4 {
        for b in 0..5 {
            for c in 0..6 {
                let i = ((a + 2) * h + b + 3) * w + c + 5;
                assert!((sub[(a * 5 + b) * 6 + c] - whole[i]).abs() < 1e-5);
            }
        }
    }
    // The field varies through depth.
    assert!(whole[..h * w] != whole[h * w..2 * h * w]);
}

/// The volume and its mesh come from one pass of overlapping mesh chunks: the file still holds
/// every slice once, equal to a plain render, and the mesh equals the mesh alone.
#[test]
fn volume_and_mesh_in_one_pass() {
    let dir = tempfile::tempdir().unwrap();
    let (config, weights) = model_3d();
    let painter = Synth::new(config, weights).seed(3).painter().unwrap();
    let (dd, h, w) = (11, 9, 10);
    for slab_slices in [1, 2, 4, 20] {
        let path = dir.path().join(format!("v{slab_slices}.npy"));
        let mut builder = ipfn::mesh::MeshBuilder::new(h, w);
        painter
            .write_volume(&path, [dd, h, w], slab_slices * h * w, Some(&mut builder))
            .unwrap();
        let (shape, values) = read_npy(&path).unwrap();
        assert_eq!(shape, [dd, h, w, 1]);
        assert_eq!(
            values,
            painter.render(&[0, 0, 0], &[dd, h, w]),
            "slabs of {slab_slices}"
        );
        let mesh = builder.finish();
        assert_eq!(mesh, painter.mesh([dd, h, w], slab_slices * h * w));
        assert!(!mesh.triangles.is_empty());
    }
}

#[test]
fn tiled_volumes_repeat_on_every_axis() {
    let (config, weights) = model_3d();
    let (dd, h, w) = (12, 10, 14);
    let painter = Synth::new(config.clone(), weights.clone())
        .seed(5)
        .tile(&[dd, h, w])
        .painter()
        .unwrap();
    assert_eq!(painter.tile_adjustment().unwrap().lattice_period.len(), 3);
    // One voxel past the tile on each axis equals the first voxel of that axis.
    let v = painter.render(&[0, 0, 0], &[dd + 1, h + 1, w + 1]);
    let at = |z: usize, y: usize, x: usize| v[(z * (h + 1) + y) * (w + 1) + x];
    let mut worst = 0f32;
    for a in 0..dd {
        for b in 0..h {
            worst = worst.max((at(a, b, w) - at(a, b, 0)).abs());
        }
        for c in 0..w {
            worst = worst.max((at(a, h, c) - at(a, 0, c)).abs());
        }
    }
    for b in 0..h {
        for c in 0..w {
            worst = worst.max((at(dd, b, c) - at(0, b, c)).abs());
        }
    }
    assert!(worst < 1e-4, "tiled volume wraps with a step of {worst}");
    // Without --tile it does not wrap.
    let plain = Synth::new(config.clone(), weights.clone())
        .seed(5)
        .painter()
        .unwrap()
        .render(&[0, 0, 0], &[dd + 1, 1, 1]);
    assert!((plain[dd] - plain[0]).abs() > 1e-4);

    // `ipfn synth --tile` paints that tile and says how far K moved; `--slice` writes one
    // plane of it as a PNG.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut ckpt = Checkpoint::new();
    weights.write_to(&config, &mut ckpt);
    ckpt.save(&d.join("m3.ipfn")).unwrap();
    let size = format!("{w}x{h}x{dd}");
    let out = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--size", &size, "--seed", "5", "--tile", "-o", "t.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("K snapped"), "{}", stderr(&out));
    let (shape, values) = read_npy(&d.join("t.npy")).unwrap();
    assert_eq!(shape, [dd, h, w, 1]);
    assert_eq!(values, painter.render(&[0, 0, 0], &[dd, h, w]));
    let out = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--size", &size, "--slice", "y=3", "-o", "y3.png",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let png = image::open(d.join("y3.png")).unwrap();
    assert_eq!(
        (png.width(), png.height()),
        (w as u32, dd as u32),
        "a D x W plane"
    );
}

#[test]
fn synth_depth_writes_a_volume_and_refuses_mismatches() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (config, weights) = model_3d();
    let mut ckpt = Checkpoint::new();
    weights.write_to(&config, &mut ckpt);
    ckpt.save(&d.join("m3.ipfn")).unwrap();

    let out = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--width", "12", "--height", "10", "--depth", "7",
            "--seed", "4", "--out", "v.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (shape, values) = read_npy(&d.join("v.npy")).unwrap();
    assert_eq!(shape, [7, 10, 12, 1]);
    let expected = Synth::new(config.clone(), weights.clone())
        .seed(4)
        .painter()
        .unwrap()
        .render(&[0, 0, 0], &[7, 10, 12]);
    assert_eq!(values, expected);

    // .raw: the same float32 values, little-endian, with no header.
    let out = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--width", "12", "--height", "10", "--depth", "7",
            "--seed", "4", "--out", "v.raw",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("little-endian float32 [D, H, W, C] = [7, 10, 12, 1]"));
    let raw: Vec<u8> = expected.iter().flat_map(|v| v.to_le_bytes()).collect();
    assert!(
        std::fs::read(d.join("v.raw")).unwrap() == raw,
        "v.raw holds the volume"
    );

    // Without --out a volume goes to synth.npy; --noise-scale applies to volumes too.
    let out = ipfn(
        d,
        &[
            "synth",
            "--model",
            "m3.ipfn",
            "--size",
            "6x5x4",
            "--noise-scale",
            "2.5",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (shape, values) = read_npy(&d.join("synth.npy")).unwrap();
    assert_eq!(shape, [4, 5, 6, 1]);
    let painter = |noise: f64| {
        Synth::new(config.clone(), weights.clone())
            .noise_scale(noise)
            .painter()
            .unwrap()
            .render(&[0, 0, 0], &[4, 5, 6])
    };
    assert_eq!(values, painter(2.5));
    assert_ne!(values, painter(1.0), "--noise-scale changes a volume");

    // --mesh: the zero level set, as OBJ or PLY, the same triangles the library extracts.
    let out = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--size", "16", "--depth", "9", "--seed", "4", "--out",
            "w.npy", "--mesh", "w.obj",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let obj = std::fs::read_to_string(d.join("w.obj")).unwrap();
    let faces = obj.lines().filter(|l| l.starts_with("f ")).count();
    let vertices = obj.lines().filter(|l| l.starts_with("v ")).count();
    let expected = Synth::new(config.clone(), weights.clone())
        .seed(4)
        .painter()
        .unwrap()
        .mesh([9, 16, 16], 1 << 20);
    assert_eq!(
        (vertices, faces),
        (expected.positions.len(), expected.triangles.len())
    );
    let ply = ipfn(
        d,
        &[
            "synth", "--model", "m3.ipfn", "--size", "16", "--depth", "9", "--out", "p.npy",
            "--mesh", "p.ply",
        ],
    );
    assert!(ply.status.success(), "{}", stderr(&ply));
    assert!(
        std::fs::read_to_string(d.join("p.ply"))
            .unwrap()
            .starts_with("ply\n")
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth", "--model", "m3.ipfn", "--depth", "4", "--out", "q.npy", "--mesh", "q.stl",
            ],
        ),
        &["q.stl", ".obj or .ply"],
    );
    assert_error(
        &ipfn(d, &["synth", "--model", "m3.ipfn", "--out", "x.png"]),
        &["2D model", "--depth"],
    );
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.ipfn");
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                shipped.to_str().unwrap(),
                "--depth",
                "4",
                "--out",
                "v2.npy",
            ],
        ),
        &["3D model"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth", "--model", "m3.ipfn", "--depth", "4", "--out", "v.png",
            ],
        ),
        &["v.png", ".npy"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth", "--model", "m3.ipfn", "--depth", "0", "--out", "z.npy",
            ],
        ),
        &["--depth 0"],
    );
    // Flags that do not apply to volumes, and a volume too large to paint, are refused.
    for (flag, value) in [("--offset", "3,4"), ("--bits", "16")] {
        assert_error(
            &ipfn(
                d,
                &[
                    "synth", "--model", "m3.ipfn", "--depth", "4", "-o", "o.npy", flag, value,
                ],
            ),
            &[flag, "images"],
        );
    }
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "m3.ipfn",
                "--size",
                "100000x100000x2",
                "-o",
                "big.npy",
            ],
        ),
        &["big.npy", "too large", "100000x100000"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "m3.ipfn",
                "--depth",
                "4",
                "--noise-scale",
                "0",
            ],
        ),
        &["--noise-scale 0"],
    );
    assert!(!d.join("big.npy").exists() && !d.join("o.npy").exists());

    // Density control: asked of a model trained without it, or left out for one trained with.
    assert_error(
        &ipfn(
            d,
            &[
                "synth",
                "--model",
                "m3.ipfn",
                "--depth",
                "4",
                "--density",
                "0.3",
            ],
        ),
        &["--density", "trained without density control"],
    );
    let dense = config.clone().with_guidance(1);
    let mut ckpt = Checkpoint::new();
    GeneratorWeights::random(&dense, 1).write_to(&dense, &mut ckpt);
    ckpt.save(&d.join("dense.ipfn")).unwrap();
    assert_error(
        &ipfn(d, &["synth", "--model", "dense.ipfn", "--depth", "4"]),
        &["trained with --density", "--density D"],
    );
    let out = ipfn(
        d,
        &[
            "synth",
            "--model",
            "dense.ipfn",
            "--size",
            "6x5x4",
            "--density",
            "0.2,0.4",
            "-o",
            "ramp.npy",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    // An image exemplar cannot be trained with --density.
    ipfn::io::write_png(&d.join("ex.png"), 8, 8, 3, &[0.0; 8 * 8 * 3]).unwrap();
    assert_error(
        &ipfn(d, &["train", "ex.png", "--density"]),
        &["--density is for volumes"],
    );
}

/// Volumes paint the same voxels on the fused CPU evaluator, burn-flex and burn-wgpu (where the
/// latent lattice is blended on the device), in any slab split.
fn volume_agrees_with_fused_cpu(device: ipfn::device::DeviceChoice) {
    let (config, weights) = model_3d();
    let painter = |device| {
        Synth::new(config.clone(), weights.clone())
            .seed(5)
            .device(device)
            .painter()
            .unwrap()
    };
    let reference = painter(ipfn::device::DeviceChoice::Cpu).render(&[-3, 2, -7], &[6, 9, 11]);
    let ours = painter(device);
    let whole = ours.render(&[-3, 2, -7], &[6, 9, 11]);
    let diff = common::max_abs_diff(&reference, &whole);
    eprintln!("{device:?} volume vs fused CPU: max abs difference {diff:.2e}");
    assert!(diff < 1e-4, "{device:?} differs by {diff}");
    // Slabs of 2 slices render the same chunks, so the same values.
    let mut parts = ours.render(&[-3, 2, -7], &[2, 9, 11]);
    parts.extend(ours.render(&[-1, 2, -7], &[4, 9, 11]));
    assert_eq!(parts, whole, "{device:?}: slabs of 2 + 4");
}

test_device!(
    volume_agrees_with_fused_cpu,
    volume_agrees_cpu,
    volume_agrees_flex,
    volume_agrees_wgpu
);
