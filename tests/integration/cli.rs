//! The `ipfn` binary end to end: outputs on real files, and one-line errors with exit code 2.

use std::path::Path;

use crate::common::{assert_error, data, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;
use ipfn::generator::GeneratorWeights;
use ipfn::io::read_npy;

fn decode_png(path: &Path) -> (png::OutputInfo, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info, buf)
}

#[test]
fn synth_on_a_fresh_folder_uses_the_shipped_model_and_writes_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(dir.path(), &["synth", "--size", "64", "--seed", "3"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("shipped honeycomb"),
        "should say which model: {}",
        stderr(&out)
    );
    let (info, pixels) = decode_png(&dir.path().join("synth.png"));
    assert_eq!(
        (info.width, info.height, info.color_type, info.bit_depth),
        (64, 64, png::ColorType::Rgb, png::BitDepth::Eight)
    );
    let mean = pixels.iter().map(|&v| v as f64).sum::<f64>() / pixels.len() as f64;
    let var = pixels
        .iter()
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / pixels.len() as f64;
    assert!(
        var.sqrt() > 20.0,
        "a honeycomb has contrast; std {}",
        var.sqrt()
    );
}

#[test]
fn import_then_synth_uses_the_imported_model_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let pth = data("official-honeycomb/netG.pth");
    let out = ipfn(
        dir.path(),
        &["import", pth.to_str().unwrap(), "-o", "honey.ipfn"],
    );
    assert!(out.status.success(), "{}", stderr(&out));

    // The imported weights are the shipped model's.
    let imported =
        GeneratorWeights::read_from(&Checkpoint::load(&dir.path().join("honey.ipfn")).unwrap())
            .unwrap();
    let shipped_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.ipfn");
    let shipped = GeneratorWeights::read_from(&Checkpoint::load(&shipped_path).unwrap()).unwrap();
    assert_eq!(imported, shipped);

    let out = ipfn(
        dir.path(),
        &[
            "synth", "--width", "40", "--height", "24", "--out", "a.npy", "--seed", "7",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("honey.ipfn"),
        "should use the model just imported: {}",
        stderr(&out)
    );
    let (shape, raw) = read_npy(&dir.path().join("a.npy")).unwrap();
    assert_eq!(shape, [24, 40, 3]);
    assert!(raw.iter().all(|v| (-1.0..=1.0).contains(v)));

    let out = ipfn(
        dir.path(),
        &[
            "synth", "--width", "40", "--height", "24", "--out", "a16.png", "--bits", "16",
            "--seed", "7",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (info, bytes) = decode_png(&dir.path().join("a16.png"));
    assert_eq!(
        (info.width, info.height, info.bit_depth),
        (40, 24, png::BitDepth::Sixteen)
    );
    let first = u16::from_be_bytes([bytes[0], bytes[1]]);
    assert_eq!(
        first,
        ipfn::io::to_unit_u16(raw[0]),
        "16-bit PNG holds the same pixels as the npy"
    );

    let out = ipfn(
        dir.path(),
        &[
            "synth", "--width", "40", "--height", "24", "--out", "a.exr", "--seed", "7",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let exr = exr::prelude::read_first_flat_layer_from_file(dir.path().join("a.exr")).unwrap();
    assert_eq!(exr.layer_data.size, exr::math::Vec2(40, 24));
    let red = exr
        .layer_data
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "R")
        .unwrap();
    let r0 = red.sample_data.value_by_flat_index(0).to_f32();
    assert!(
        (r0 - (raw[0] + 1.0) / 2.0).abs() < 1e-6,
        "EXR holds (v + 1) / 2"
    );
}

#[test]
fn offset_paints_the_neighbouring_piece() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| assert!(ipfn(dir.path(), args).status.success());
    run(&[
        "synth",
        "--width",
        "20",
        "--height",
        "8",
        "--out",
        "whole.npy",
    ]);
    run(&[
        "synth",
        "--width",
        "10",
        "--height",
        "8",
        "--offset",
        "10,0",
        "--out",
        "right.npy",
    ]);
    let (_, whole) = read_npy(&dir.path().join("whole.npy")).unwrap();
    let (_, right) = read_npy(&dir.path().join("right.npy")).unwrap();
    let window: Vec<f32> = (0..8)
        .flat_map(|r| whole[(r * 20 + 10) * 3..(r * 20 + 20) * 3].to_vec())
        .collect();
    assert_eq!(window, right);
}

#[test]
fn tile_reports_how_far_k_moved() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &["synth", "--size", "100", "--tile", "--out", "t.png"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("K snapped"), "{}", stderr(&out));
}

#[test]
fn bad_input_gets_one_line_and_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_error(&ipfn(d, &["synth", "--size", "0"]), &["size", "at least 1"]);
    assert_error(
        &ipfn(d, &["synth", "--model", "nope.ipfn"]),
        &["nope.ipfn", "no such model"],
    );
    assert_error(
        &ipfn(d, &["synth", "--out", "x.bmp"]),
        &["x.bmp", "unknown extension"],
    );
    assert_error(
        &ipfn(d, &["synth", "--out", "no/such/dir/x.png"]),
        &["x.png", "does not exist"],
    );
    assert_error(
        &ipfn(d, &["synth", "--device", "tpu"]),
        &["unknown device", "tpu"],
    );
    assert_error(&ipfn(d, &["synth", "--size", "3000000000"]), &["too large"]);
    assert_error(&ipfn(d, &["synth", "--zoom", "0"]), &["--zoom"]);
    assert_error(
        &ipfn(d, &["synth", "--noise-scale", "0"]),
        &["--noise-scale"],
    );
    let both = ipfn(d, &["synth", "--tile", "--mirror"]);
    assert_eq!(both.status.code(), Some(2), "{}", stderr(&both));
    std::fs::write(
        d.join("junk.ipfn"),
        b"\x10\x00\x00\x00\x00\x00\x00\x00{\"a\": trunc",
    )
    .unwrap();
    assert_error(
        &ipfn(d, &["synth", "--model", "junk.ipfn"]),
        &["junk.ipfn", "corrupt"],
    );
    std::fs::write(d.join("photo.png"), b"not a model").unwrap();
    assert_error(
        &ipfn(d, &["synth", "--model", "photo.png"]),
        &["photo.png", "not an ipfn model"],
    );
    assert_error(
        &ipfn(d, &["import", "missing.pth", "-o", "m.ipfn"]),
        &["missing.pth"],
    );
    assert_error(
        &ipfn(d, &["import", "photo.png", "-o", "m.ipfn"]),
        &["photo.png", "PyTorch"],
    );

    // A checkpoint whose tensors do not fit its config: another model shape.
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.ipfn");
    let mut ckpt = Checkpoint::load(&shipped).unwrap();
    let config = ckpt.metadata["generator_config"].replace("\"width\":128", "\"width\":64");
    ckpt.metadata.insert("generator_config".into(), config);
    ckpt.save(&d.join("other.ipfn")).unwrap();
    assert_error(
        &ipfn(d, &["synth", "--model", "other.ipfn"]),
        &["other.ipfn", "another model shape"],
    );

    // Nothing half-written was left behind by any of the failures.
    let mut names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["junk.ipfn", "other.ipfn", "photo.png"]);
}

#[test]
fn unknown_flags_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(dir.path(), &["synth", "--sizee", "10"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--sizee"));
}

#[test]
fn bench_prints_ours_beside_a_floor_measured_in_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &[
            "bench",
            "--sizes",
            "32",
            "--runs",
            "1",
            "--no-train",
            "--devices",
            "cpu,flex",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    // The row `| work | device | ours | floor | ratio |` names `floor`, with a positive ratio.
    let has_floor = |table: &str, work: &str, device: &str, floor: &str| {
        let row = table
            .lines()
            .find(|l| l.starts_with(&format!("| {work} | {device} |")))
            .unwrap_or_else(|| panic!("no {work} row for {device} in:\n{table}"));
        assert!(row.contains(floor), "{row}");
        let ratio: f64 = row.split('|').nth(5).unwrap().trim().parse().unwrap();
        assert!(ratio > 0.0, "{row}");
    };
    let table = String::from_utf8_lossy(&out.stdout);
    has_floor(&table, "synth 32²", "cpu", "GEMM floor");
    has_floor(&table, "synth 32²", "flex", "matmul floor");
    // A training iteration and a volume, with their floors (batch 1 and 8³, to stay quick).
    let out = ipfn(
        dir.path(),
        &[
            "bench",
            "--sizes",
            "8",
            "--runs",
            "1",
            "--devices",
            "flex",
            "--batches",
            "1",
            "--volumes",
            "8",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let table = String::from_utf8_lossy(&out.stdout);
    has_floor(
        &table,
        "train iteration (batch 1, crop 128)",
        "flex",
        "GEMM floor of both networks",
    );
    has_floor(&table, "volume 8³ (3D 10x128 MLP)", "flex", "matmul floor");
    assert_error(&ipfn(dir.path(), &["bench", "--sizes", "0"]), &["--sizes"]);
    assert_error(
        &ipfn(dir.path(), &["bench", "--devices", "tpu"]),
        &["unknown device", "tpu"],
    );
}

/// Without the `cuda` feature, `--device cuda` says how to get it (with it, on a machine
/// without a driver, it says that instead); never a panic.
#[test]
fn device_cuda_without_cuda_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &["synth", "--size", "8", "--device", "cuda", "--out", "c.png"],
    );
    if cfg!(feature = "cuda") && out.status.success() {
        return; // a CUDA build on a machine with a GPU
    }
    let needle = if cfg!(feature = "cuda") {
        "no usable CUDA device"
    } else {
        "built without CUDA"
    };
    assert_error(&out, &["--device cuda", needle]);
}

/// A machine with no GPU driver gets one line that says what to install, not a panic. The
/// Vulkan loader and glvnd's EGL (wgpu's GL backend) are pointed at driver lists that do not
/// exist, so no adapter is found.
#[test]
fn device_wgpu_without_an_adapter_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args(["synth", "--size", "8", "--device", "wgpu", "--out", "w.png"])
        .current_dir(dir.path())
        .env("VK_ICD_FILENAMES", dir.path().join("no-driver.json"))
        .env("VK_DRIVER_FILES", dir.path().join("no-driver.json"))
        .env(
            "__EGL_VENDOR_LIBRARY_FILENAMES",
            dir.path().join("no-driver.json"),
        )
        .env("XDG_RUNTIME_DIR", dir.path())
        .output()
        .unwrap();
    let needle = if cfg!(feature = "wgpu") {
        "no usable GPU adapter"
    } else {
        "built without wgpu"
    };
    assert_error(&out, &["--device wgpu", needle, "--device cpu"]);
    assert!(!dir.path().join("w.png").exists());
}
