//! Material map sets end to end: train on the procedural material (albedo, normal, roughness,
//! height), synthesize one file per map, and check alignment, precision, tiling, normal length,
//! and that the painted normals follow the painted height better than an untrained model's.

use crate::common;

use std::path::Path;

use crate::common::{assert_error, ipfn, stderr};
use burn::prelude::*;
use ipfn::checkpoint::Checkpoint;
use ipfn::generator::GeneratorWeights;
use ipfn::io::read_npy;
use ipfn::maps::MapSet;
use ipfn::synth::Synth;
use ipfn::train::{TrainConfig, Trainer};

use crate::common::SMALL_CONFIG as CONFIG;

const MAPS: &str = "mat/albedo.png,mat/normal.png,mat/roughness.png,mat/height.png";

fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &["draw", "material", "--size", "128", "-o", "mat"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::write(dir.path().join("m.toml"), CONFIG).unwrap();
    dir
}

/// Correlation between a normal map's tilt (x, y) and the tilt of the height map's normals
/// (-dh/dx, -dh/dy, central differences): 1 when they follow each other, 0 when unrelated.
/// `normal`: `[h, w, 3]`, `height`: `[h, w, 1]`, values in [-1, 1].
fn tilt_correlation(normal: &[f32], height: &[f32], w: usize, h: usize) -> f64 {
    let mut a = Vec::new();
    let mut b = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let hv = |yy: usize, xx: usize| height[yy * w + xx] as f64;
            a.push([
                -(hv(y, x + 1) - hv(y, x - 1)),
                -(hv(y + 1, x) - hv(y - 1, x)),
            ]);
            let at = (y * w + x) * 3;
            b.push([normal[at] as f64, normal[at + 1] as f64]);
        }
    }
    let mean = |v: &[[f64; 2]]| {
        let n = v.len() as f64;
        [
            v.iter().map(|p| p[0]).sum::<f64>() / n,
            v.iter().map(|p| p[1]).sum::<f64>() / n,
        ]
    };
    let (ma, mb) = (mean(&a), mean(&b));
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (p, q) in a.iter().zip(&b) {
        for k in 0..2 {
            let (u, v) = (p[k] - ma[k], q[k] - mb[k]);
            ab += u * v;
            aa += u * u;
            bb += v * v;
        }
    }
    if aa == 0.0 || bb == 0.0 {
        0.0
    } else {
        ab / (aa * bb).sqrt()
    }
}

/// Splits `[n, channels]` pixels into the maps' own arrays.
fn split(values: &[f32], set: &MapSet) -> Vec<Vec<f32>> {
    let c = set.channels();
    set.ranges()
        .into_iter()
        .map(|r| {
            values
                .chunks_exact(c)
                .flat_map(|px| px[r.clone()].to_vec())
                .collect()
        })
        .collect()
}

fn png_bits(path: &Path) -> (u8, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let reader = decoder.read_info().unwrap();
    let info = reader.info();
    (info.bit_depth as u8, info.color_type.samples())
}

#[test]
fn map_set_trains_and_paints_aligned_maps_whose_normals_follow_the_height() {
    let dir = setup();
    let d = dir.path();
    let out = ipfn(
        d,
        &[
            "train",
            "--maps",
            MAPS,
            "--config",
            "m.toml",
            "--iterations",
            "300",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("normal (3 ch, 16-bit, normal)"),
        "{}",
        stderr(&out)
    );
    // The preview shows the first map (albedo, RGB).
    assert_eq!(png_bits(&d.join("run/previews/iter-000300.png")).1, 3);

    // One file per map, named after the inputs, each at its input's precision (16-bit).
    let (w, h) = (96, 80);
    let size = ["--width", "96", "--height", "80", "--seed", "3"];
    let png_out = ipfn(
        d,
        &[
            &["synth", "--model", "run/latest.ipfn", "--out", "s.png"],
            &size[..],
        ]
        .concat(),
    );
    assert!(png_out.status.success(), "{}", stderr(&png_out));
    for (name, channels) in [
        ("albedo", 3),
        ("normal", 3),
        ("roughness", 1),
        ("height", 1),
    ] {
        assert_eq!(
            png_bits(&d.join(format!("s-{name}.png"))),
            (16, channels),
            "s-{name}.png"
        );
    }
    assert!(!d.join("s.png").exists());

    // The same synthesis as raw floats: every map equals its channels of one evaluation.
    let npy_out = ipfn(
        d,
        &[
            &["synth", "--model", "run/latest.ipfn", "--out", "s.npy"],
            &size[..],
        ]
        .concat(),
    );
    assert!(npy_out.status.success(), "{}", stderr(&npy_out));
    let ckpt = Checkpoint::load(&d.join("run/latest.ipfn")).unwrap();
    let set = MapSet::read_from(&ckpt, Path::new("latest.ipfn"))
        .unwrap()
        .expect("a map-set model");
    let (config, weights) = GeneratorWeights::read_from(&ckpt).unwrap();
    let full = Synth::new(config.clone(), weights.clone())
        .seed(3)
        .painter()
        .unwrap()
        .render(&[0, 0], &[h, w]);
    let maps = split(&full, &set);
    let written: Vec<Vec<f32>> = ["albedo", "normal", "roughness", "height"]
        .iter()
        .map(|n| read_npy(&d.join(format!("s-{n}.npy"))).unwrap().1)
        .collect();
    assert_eq!(
        written[0], maps[0],
        "albedo is its channels of the evaluation"
    );
    assert_eq!(written[2], maps[2], "roughness likewise");
    assert_eq!(written[3], maps[3], "height likewise");
    // The normal map is the same vectors, renormalised to unit length.
    for (px, raw) in written[1].chunks_exact(3).zip(maps[1].chunks_exact(3)) {
        let len = (px[0] * px[0] + px[1] * px[1] + px[2] * px[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "normal length {len}");
        let raw_len = (raw[0] * raw[0] + raw[1] * raw[1] + raw[2] * raw[2]).sqrt();
        for k in 0..3 {
            assert!((px[k] - raw[k] / raw_len).abs() < 1e-5);
        }
    }

    // The painted normals follow the painted height; an untrained model's do not.
    let trained = tilt_correlation(&written[1], &written[3], w, h);
    let config_toml = TrainConfig::from_toml(CONFIG, Path::new("m.toml")).unwrap();
    let untrained = {
        let files =
            ipfn::maps::MapFiles::new(MAPS.split(',').map(|f| d.join(f)).collect(), None, false)
                .unwrap();
        let t = Trainer::new(config_toml, files, &d.join("untrained"), &Device::flex()).unwrap();
        let (c, wts) = t.model();
        let v = Synth::new(c, wts)
            .seed(3)
            .painter()
            .unwrap()
            .render(&[0, 0], &[h, w]);
        let m = split(&v, &set);
        tilt_correlation(&m[1], &m[3], w, h)
    };
    eprintln!("normal/height tilt correlation: trained {trained:.3}, untrained {untrained:.3}");
    assert!(
        trained > 0.25 && trained > untrained + 0.2,
        "trained {trained}, untrained {untrained}"
    );

    // --tile holds for every map: the whole stacked pixel repeats with the tile's period.
    let tile = Synth::new(config, weights)
        .seed(3)
        .tile(&[h, w])
        .painter()
        .unwrap()
        .render(&[0, 0], &[h + 1, w + 1]);
    let c = set.channels();
    for y in 0..h {
        for k in 0..c {
            let (first, past) = (tile[(y * (w + 1)) * c + k], tile[(y * (w + 1) + w) * c + k]);
            assert!((first - past).abs() < 1e-4, "row {y} channel {k}");
        }
    }
}

#[test]
fn map_sets_refuse_mismatched_maps_with_one_line() {
    let dir = setup();
    let d = dir.path();
    // Another size.
    assert!(
        ipfn(d, &["draw", "material", "--size", "96", "-o", "small"])
            .status
            .success()
    );
    let mixed_size = "mat/albedo.png,small/height.png";
    assert_error(
        &ipfn(d, &["train", "--maps", mixed_size, "--config", "m.toml"]),
        &["small/height.png", "96x96", "--resize-maps"],
    );
    // Fit refuses the same sizes naming its own flag for it.
    assert_error(
        &ipfn(d, &["fit", "--maps", mixed_size, "--iterations", "1"]),
        &["small/height.png", "96x96", "--resize-maps"],
    );
    // Another bit depth (an 8-bit PNG beside 16-bit ones) is how published sets come: each
    // map is read at its own depth and painted back at it.
    assert!(
        ipfn(
            d,
            &["draw", "stripes", "--size", "128", "-o", "stripes.png"]
        )
        .status
        .success()
    );
    let depths = ipfn(
        d,
        &[
            "train",
            "--maps",
            "mat/albedo.png,stripes.png",
            "--config",
            "m.toml",
            "--iterations",
            "1",
            "--out",
            "depths",
        ],
    );
    assert!(depths.status.success(), "{}", stderr(&depths));
    let painted = ipfn(
        d,
        &[
            "synth", "--model", "depths", "--size", "32", "--out", "d.png",
        ],
    );
    assert!(painted.status.success(), "{}", stderr(&painted));
    // A PNG's bit depth is byte 24 (in IHDR, after the signature, length, type, width, height).
    let png_bits = |name: &str| std::fs::read(d.join(name)).unwrap()[24];
    assert_eq!(png_bits("d-albedo.png"), 16, "the 16-bit map stays 16-bit");
    assert_eq!(png_bits("d-stripes.png"), 8, "the 8-bit map stays 8-bit");
    assert_error(
        &ipfn(
            d,
            &["train", "--maps", "mat/albedo.png", "--config", "m.toml"],
        ),
        &["--maps", "two"],
    );
    assert_error(
        &ipfn(
            d,
            &[
                "train",
                "--maps",
                MAPS,
                "--normal-maps",
                "bump",
                "--config",
                "m.toml",
            ],
        ),
        &["--normal-maps bump", "albedo"],
    );
    assert_error(
        &ipfn(d, &["train", "--maps", "mat/albedo.png,nope.png"]),
        &["nope.png"],
    );
    // With --resize-maps, the mixed set trains (resampled), and resumes.
    let ok = ipfn(
        d,
        &[
            "train",
            "--maps",
            "mat/albedo.png,small/height.png,stripes.png",
            "--resize-maps",
            "--config",
            "m.toml",
            "--iterations",
            "1",
            "--out",
            "mixed",
        ],
    );
    assert!(ok.status.success(), "{}", stderr(&ok));
    let resumed = ipfn(d, &["train", "--resume", "mixed", "--iterations", "2"]);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    // A map-set model evaluated against a single image: a channel mismatch, not a crash.
    assert_error(
        &ipfn(
            d,
            &[
                "eval",
                "--model",
                "mixed/latest.ipfn",
                "--exemplar",
                "stripes.png",
            ],
        ),
        &["stripes.png", "channels"],
    );
}

/// Float (EXR) maps keep float precision: a set of EXR inputs is painted back as EXR files.
#[test]
fn float_maps_are_painted_as_exr() {
    let dir = setup();
    let d = dir.path();
    for (name, channels) in [("base", 3), ("mask", 1)] {
        let values: Vec<f32> = (0..64 * 64 * channels)
            .map(|i| ((i % 64) as f32 / 32.0).sin() * 0.9)
            .collect();
        let mut w = ipfn::io::ImageWriter::create(
            &d.join(format!("{name}.exr")),
            ipfn::io::OutputFormat::Exr,
            64,
            64,
            channels,
        )
        .unwrap();
        w.write_rows(&values).unwrap();
        w.finish().unwrap();
    }
    let out = ipfn(
        d,
        &[
            "train",
            "--maps",
            "base.exr,mask.exr",
            "--config",
            "m.toml",
            "--iterations",
            "1",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("base (3 ch, 32-bit)"),
        "{}",
        stderr(&out)
    );
    let synth = ipfn(
        d,
        &[
            "synth",
            "--model",
            "run/latest.ipfn",
            "--size",
            "32",
            "--out",
            "f.png",
        ],
    );
    assert!(synth.status.success(), "{}", stderr(&synth));
    for name in ["f-base.exr", "f-mask.exr"] {
        let image = ipfn::exemplar::read_exemplar(&d.join(name)).unwrap();
        assert_eq!((image.width, image.height), (32, 32), "{name}");
    }
    assert!(!d.join("f-base.png").exists());
}

/// A published set as it comes, in a folder: maps named by role in a library's spelling, a gray
/// roughness stored as RGB, a gray height stored as RGBA with an opaque alpha, a DirectX
/// normal map, and a preview image that is no map. The folder is read in role order, gray maps
/// as gray, the empty alpha dropped, the DirectX normal turned to OpenGL's; a fit writes the
/// normal map back in DirectX's convention.
#[test]
fn a_folder_of_scans_is_read_as_its_maps_say() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let set = d.join("Wall042");
    std::fs::create_dir(&set).unwrap();
    let (w, h) = (32, 32);
    let wave = |x: usize, y: usize, f: f32| (x as f32 * f).sin() * (y as f32 * 0.7 * f).cos();
    let pixels = |c: usize, f: &dyn Fn(usize, usize) -> Vec<f32>| -> Vec<f32> {
        let v: Vec<f32> = (0..h * w).flat_map(|i| f(i % w, i / w)).collect();
        assert_eq!(v.len(), h * w * c);
        v
    };
    let color = pixels(3, &|x, y| {
        vec![wave(x, y, 0.3), wave(y, x, 0.2), wave(x, x, 0.1)]
    });
    let gray = |x: usize, y: usize| wave(x, y, 0.25);
    let rough = pixels(3, &|x, y| vec![gray(x, y); 3]);
    let height = pixels(4, &|x, y| vec![gray(y, x), gray(y, x), gray(y, x), 1.0]);
    // A DirectX normal: green is the negated OpenGL green.
    let normal_dx = pixels(3, &|x, y| {
        let (nx, ny) = (0.4 * wave(x, y, 0.3), 0.4 * wave(y, x, 0.3));
        let nz = (1.0 - nx * nx - ny * ny).sqrt();
        vec![nx, -ny, nz]
    });
    let write = |name: &str, c: usize, v: &[f32]| {
        ipfn::io::write_png(&set.join(name), w, h, c, v).unwrap();
    };
    write("Wall042_1K-PNG_Color.png", 3, &color);
    write("Wall042_1K-PNG_Roughness.png", 3, &rough);
    write("Wall042_1K-PNG_Displacement.png", 4, &height);
    write("Wall042_1K-PNG_NormalDX.png", 3, &normal_dx);
    write("Wall042_preview.png", 3, &color);

    let files = ipfn::maps::MapFiles::new(vec![set.clone()], None, false).unwrap();
    let (exemplar, maps) = files.load().unwrap();
    let names: Vec<&str> = maps.maps.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "Wall042_1K-PNG_Color",
            "Wall042_1K-PNG_NormalDX",
            "Wall042_1K-PNG_Displacement",
            "Wall042_1K-PNG_Roughness"
        ],
        "role order, the preview left out"
    );
    let channels: Vec<(usize, Option<usize>)> = maps
        .maps
        .iter()
        .map(|m| (m.channels, m.stored_channels))
        .collect();
    assert_eq!(channels, [(3, None), (3, None), (1, Some(4)), (1, Some(3))]);
    assert!(maps.maps[1].normal && maps.maps[1].directx);
    use ipfn::maps::MapRole;
    let roles: Vec<Option<MapRole>> = maps.maps.iter().map(|m| m.role).collect();
    let expected = [
        MapRole::Color,
        MapRole::Normal,
        MapRole::Height,
        MapRole::Roughness,
    ];
    assert_eq!(roles, expected.map(Some));
    // The normal is learned in OpenGL's convention: green flipped back from the file's.
    let c = exemplar.channels;
    assert_eq!(c, 8);
    let step = 2.0 / 255.0 + 1e-6;
    for (p, px) in exemplar.values.chunks_exact(c).enumerate() {
        assert!((px[4] + normal_dx[p * 3 + 1]).abs() <= step, "green at {p}");
        assert!((px[6] - height[p * 4]).abs() <= step, "height at {p}");
        assert!((px[7] - rough[p * 3]).abs() <= step, "roughness at {p}");
    }
    // Written back by a fit: DirectX's convention again, and the gray maps as gray.
    let out = ipfn(
        d,
        &[
            "fit",
            "--maps",
            "Wall042",
            "--iterations",
            "150",
            "--run",
            "fit",
            "--device",
            "cpu",
            "--preview",
            "fit-preview.png",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let said = stderr(&out);
    assert!(
        said.contains("Wall042_1K-PNG_Roughness (1 ch, read from 3"),
        "{said}"
    );
    assert!(said.contains("normal, DirectX"), "{said}");
    let tile = |name: &str| {
        let path = d.join(format!("fit/tile-Wall042_1K-PNG_{name}.png"));
        ipfn::exemplar::read_exemplar(&path).unwrap()
    };
    let normal = tile("NormalDX");
    let greens = normal.values.chunks_exact(3).map(|px| px[1]);
    let agreement: f32 = greens
        .zip(normal_dx.chunks_exact(3))
        .map(|(a, b)| a * b[1])
        .sum();
    assert!(
        agreement > 0.0,
        "the fitted normal's green follows the DirectX file's"
    );
    assert_eq!(tile("Roughness").channels, 1);

    // The material lit: one period of the tile, and any size painted from it.
    let preview = |name: &str| image::open(d.join(name)).unwrap();
    let lit = preview("fit-preview.png");
    assert_eq!((lit.width(), lit.height()), (32, 32));
    assert_eq!(lit.color(), image::ColorType::Rgb8);
    let out = ipfn(
        d,
        &[
            "synth",
            "--model",
            "fit/tile.ipfn",
            "--size",
            "48x40",
            "-o",
            "t.png",
            "--preview",
            "t-preview.png",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let lit = preview("t-preview.png").to_rgb8();
    assert_eq!(lit.dimensions(), (48, 40));
    // Lit relief, not a flat fill: the pixels differ.
    let lum: Vec<f32> = lit
        .pixels()
        .map(|p| p.0.iter().map(|&v| v as f32).sum())
        .collect();
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let spread = lum.iter().map(|v| (v - mean).abs()).sum::<f32>() / lum.len() as f32;
    assert!(spread > 3.0, "a preview with relief varies ({spread})");
}

#[test]
fn a_preview_is_refused_where_there_is_no_material() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The shipped honeycomb is one image, not a map set.
    let out = ipfn(
        d,
        &["synth", "--size", "16", "-o", "h.png", "--preview", "p.png"],
    );
    assert_error(&out, &["--preview", "no map set"]);
    assert!(!d.join("h.png").exists() && !d.join("p.png").exists());
    let out = ipfn(
        d,
        &["synth", "--size", "16", "-o", "h.png", "--preview", "p.jpg"],
    );
    assert_error(&out, &["--preview p.jpg", ".png"]);
    let photo = Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.png");
    let photo = photo.to_str().unwrap();
    let out = ipfn(
        d,
        &["fit", photo, "--iterations", "1", "--preview", "p.png"],
    );
    assert_error(&out, &["--preview", "--maps"]);
}

#[test]
fn a_map_set_trains_with_the_cpu_recipe_and_is_scored_like_an_image() {
    let dir = setup();
    let d = dir.path();
    let out = ipfn(
        d,
        &[
            "train",
            "--maps",
            "mat",
            "--iterations",
            "4",
            "--checkpoint-every",
            "2",
            "--device",
            "cpu",
            "--out",
            "run",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let said = stderr(&out);
    // The CPU's network, crop and scale, and the recipe's measures of the colour map.
    assert!(said.contains("resize, crop as configs/cpu.toml"), "{said}");
    assert!(said.contains("batch 8, crop 32"), "{said}");
    assert!(said.contains("exemplar 128x128: period"), "{said}");
    assert!(said.contains("structure floor"), "{said}");
    // Scored at each checkpoint, and the best kept.
    let row = common::last_metrics_row(&d.join("run"));
    let header = std::fs::read_to_string(d.join("run/metrics.csv")).unwrap();
    let header: Vec<&str> = header.lines().next().unwrap().split(',').collect();
    let at = |name: &str| row[header.iter().position(|h| *h == name).unwrap()];
    assert!(at("sifid").is_finite() && at("sifid") > 0.0);
    assert!(at("structure").is_finite() && at("structure") > 0.0);
    // Each map's structure too, their mean the structure column; its floor printed per map.
    let per_map: Vec<f32> = (header.iter())
        .filter(|h| h.starts_with("structure_"))
        .map(|h| at(h))
        .collect();
    let maps = header
        .iter()
        .filter(|h| h.starts_with("structure_"))
        .count();
    assert!(maps >= 2, "{header:?}");
    assert!(
        per_map.iter().all(|v| v.is_finite() && *v > 0.0),
        "{per_map:?}"
    );
    let mean = per_map.iter().sum::<f32>() / maps as f32;
    assert!(
        (mean - at("structure")).abs() < 1e-5,
        "{mean} {}",
        at("structure")
    );
    let floor = said
        .lines()
        .find(|l| l.starts_with("structure floor"))
        .unwrap();
    let named = header.iter().filter_map(|h| h.strip_prefix("structure_"));
    assert!(
        named.clone().all(|n| floor.contains(&format!("{n} 0."))),
        "{floor}"
    );
    assert!(d.join("run/best.ipfn").exists());
}
