//! The valid file of every input format, and the loader the CLI runs on it.

use std::io::Cursor;
use std::path::Path;

use super::Format;

fn encode(image: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut bytes = Cursor::new(Vec::new());
    image.write_to(&mut bytes, format).unwrap();
    bytes.into_inner()
}

fn ipfn_bytes(dir: &Path, args: &[&str], out: &str) -> Vec<u8> {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(dir.join(out)).unwrap()
}

const CUBE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

const TINY_TOML: &str = "batch = 2\ncrop = 16\ncritic_widths = [4, 8, 8, 8]\nhidden_layers = 2\n\
width = 16\nlr = 2e-4\ncheckpoint_every = 1\nresize = 0.5\niterations = 10\ntime = \"5m\"\n";

const RUN_TOML: &str = "batch = 2\ncrop = 16\ncritic_widths = [4, 8, 8, 8]\nhidden_layers = 2\n\
width = 8\niterations = 2\ncheckpoint_every = 1\npreview_every = 100\nlog_every = 100\n\
score_samples = 0\n";

/// The valid files and the loaders the CLI runs on them.
pub fn formats(dir: &Path) -> Vec<Format> {
    let rgb = image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(24, 20, |x, y| {
        image::Rgb([(x * 10) as u8, (y * 12) as u8, ((x + y) * 5) as u8])
    }));
    let gray16 = image::DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(24, 20, |x, y| {
        image::Luma([(x * 2000 + y * 700) as u16])
    }));
    std::fs::write(dir.join("cube.obj"), CUBE_OBJ).unwrap();
    // A 3D model, for meshes out of `synth`.
    let config = ipfn::generator::GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_hidden_layers(2)
        .with_width(8)
        .with_crop(16);
    let mut model = ipfn::checkpoint::Checkpoint::new();
    ipfn::generator::GeneratorWeights::random(&config, 0).write_to(&config, &mut model);
    let model_bytes = model.to_bytes();
    let image_model = {
        let config = ipfn::generator::GeneratorConfig::new()
            .with_hidden_layers(2)
            .with_width(8);
        let mut m = ipfn::checkpoint::Checkpoint::new();
        ipfn::generator::GeneratorWeights::random(&config, 1).write_to(&config, &mut m);
        m.to_bytes()
    };
    let run_state = {
        // A run folder after 2 iterations of a tiny run; its exemplar at an absolute path.
        std::fs::write(
            dir.join("ex.png"),
            encode(rgb.clone(), image::ImageFormat::Png),
        )
        .unwrap();
        let config: ipfn::train::TrainConfig = toml::from_str(RUN_TOML).unwrap();
        let device = burn::prelude::Device::flex();
        let run = dir.join("run");
        let mut trainer = ipfn::train::Trainer::new(config, dir.join("ex.png"), &run, &device)
            .and_then(|t| t.start())
            .unwrap();
        trainer
            .run(&std::sync::atomic::AtomicBool::new(false), |_, _| {})
            .unwrap();
        std::fs::read(run.join("latest.ipfn")).unwrap()
    };
    vec![
        Format {
            name: "run state (latest.ipfn)",
            file_name: "run/latest.ipfn",
            valid: run_state,
            text: false,
            load: |p| {
                let run = p.parent().expect("in the run folder");
                ipfn::train::Trainer::resume(run, None, &burn::prelude::Device::flex()).map(drop)
            },
        },
        Format {
            name: "PNG 8-bit",
            file_name: "m.png",
            valid: encode(rgb.clone(), image::ImageFormat::Png),
            text: false,
            load: |p| ipfn::exemplar::read_exemplar(p).map(drop),
        },
        Format {
            name: "PNG 16-bit",
            file_name: "m16.png",
            valid: encode(gray16.clone(), image::ImageFormat::Png),
            text: false,
            load: |p| ipfn::exemplar::read_exemplar(p).map(drop),
        },
        Format {
            name: "JPEG",
            file_name: "m.jpg",
            valid: encode(rgb, image::ImageFormat::Jpeg),
            text: false,
            load: |p| ipfn::exemplar::read_exemplar(p).map(drop),
        },
        Format {
            name: "EXR",
            file_name: "m.exr",
            valid: ipfn_bytes(
                dir,
                &["synth", "--size", "24x20", "--out", "v.exr"],
                "v.exr",
            ),
            text: false,
            load: |p| ipfn::exemplar::read_exemplar(p).map(drop),
        },
        Format {
            name: ".npy image",
            file_name: "m.npy",
            valid: ipfn_bytes(
                dir,
                &["synth", "--size", "24x20", "--out", "v.npy"],
                "v.npy",
            ),
            text: false,
            load: |p| ipfn::io::read_npy(p).map(drop),
        },
        Format {
            name: ".npy volume",
            file_name: "mv.npy",
            valid: ipfn_bytes(
                dir,
                &["draw", "gyroid", "--size", "16", "-o", "g.npy"],
                "g.npy",
            ),
            text: false,
            load: |p| ipfn::exemplar::read_sdf_volume(p, 0.1).map(drop),
        },
        Format {
            name: ".ipfn image model",
            file_name: "m.ipfn",
            valid: image_model,
            text: false,
            load: |p| ipfn::model::choose_model(Some(p), Path::new(".")).map(drop),
        },
        Format {
            name: ".ipfn volume model",
            file_name: "mv.ipfn",
            valid: model_bytes,
            text: false,
            load: |p| ipfn::model::choose_model(Some(p), Path::new(".")).map(drop),
        },
        Format {
            name: "PyTorch .pth",
            file_name: "m.pth",
            valid: std::fs::read(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/data/official-honeycomb/netG.pth"
            ))
            .unwrap(),
            text: false,
            load: |p| ipfn::generator::import_pytorch(p, 5, 128).map(drop),
        },
        Format {
            name: "OBJ",
            file_name: "m.obj",
            valid: CUBE_OBJ.as_bytes().to_vec(),
            text: true,
            load: |p| ipfn::mesh::read_mesh(p).map(drop),
        },
        Format {
            name: "PLY",
            file_name: "m.ply",
            valid: {
                let cube = ipfn::mesh::read_mesh(&dir.join("cube.obj")).unwrap();
                ipfn::mesh::write_mesh(&cube, &dir.join("cube.ply")).unwrap();
                std::fs::read(dir.join("cube.ply")).unwrap()
            },
            text: false,
            load: |p| ipfn::mesh::read_mesh(p).map(drop),
        },
        Format {
            name: "TOML config",
            file_name: "m.toml",
            valid: TINY_TOML.as_bytes().to_vec(),
            text: true,
            load: |p| ipfn::train::TrainConfig::from_file(p).map(drop),
        },
        Format {
            name: "guide image",
            file_name: "g.png",
            valid: encode(gray16, image::ImageFormat::Png),
            text: false,
            load: |p| ipfn::condition::Guide::from_image(p).map(drop),
        },
    ]
}
