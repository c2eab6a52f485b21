//! Shared test helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ipfn::device::DeviceChoice;

pub mod view;

/// Runs one test body on every device, like candle's `test_device!`: the fused CPU evaluator,
/// burn-flex and burn-wgpu. Backends cannot drift apart unnoticed.
///
/// wgpu needs a Vulkan (or Metal/DX12) adapter, so the wgpu variant is compiled with the `wgpu`
/// feature and marked ignored: `cargo test --release` reports it as not run, and
/// `cargo test --release -- --ignored` runs it (CI does, on lavapipe).
#[macro_export]
macro_rules! test_device {
    ($body:ident, $cpu:ident, $flex:ident, $wgpu:ident) => {
        #[test]
        fn $cpu() {
            $body(ipfn::device::DeviceChoice::Cpu);
        }
        #[test]
        fn $flex() {
            $body(ipfn::device::DeviceChoice::Flex);
        }
        #[cfg(feature = "wgpu")]
        #[test]
        #[ignore = "needs a wgpu adapter (CI: lavapipe); run by `cargo test --release -- --ignored`"]
        fn $wgpu() {
            $body(ipfn::device::DeviceChoice::Wgpu);
        }
    };
}

pub fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "compared arrays differ in length");
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// The honeycomb generator converted from the authors' `netG.pth`.
pub fn honeycomb() -> (
    ipfn::generator::GeneratorConfig,
    ipfn::generator::GeneratorWeights,
) {
    ipfn::generator::import_pytorch(&data("official-honeycomb/netG.pth"), 5, 128)
        .expect("netG.pth imports")
}

pub fn all_devices() -> [DeviceChoice; 3] {
    [DeviceChoice::Cpu, DeviceChoice::Flex, DeviceChoice::Wgpu]
}

/// Runs the `ipfn` binary in `dir`.
pub fn ipfn(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("ipfn runs")
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts a failure with exit code 2 and a single stderr line containing every `needle`.
pub fn assert_error(out: &Output, needles: &[&str]) {
    let err = stderr(out);
    assert_eq!(
        out.status.code(),
        Some(2),
        "expected exit code 2, got {:?}; stderr: {err}",
        out.status.code()
    );
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "expected one line, got: {err}"
    );
    for needle in needles {
        assert!(
            err.contains(needle),
            "error should mention '{needle}': {err}"
        );
    }
}

/// A small model and critic for end-to-end training tests that must learn something in
/// about 30 s on 2 cores (crop 32, 4x32 generator).
pub const SMALL_CONFIG: &str = r#"
batch = 4
crop = 32
lr = 2e-4
critic_widths = [16, 32, 64, 64]
hidden_layers = 4
width = 32
checkpoint_every = 100
preview_every = 100
log_every = 100
"#;

/// The last row of a run's `metrics.csv`, as numbers (empty fields, such as the score of a run
/// that is not scored, left out).
pub fn last_metrics_row(run: &Path) -> Vec<f32> {
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    metrics
        .lines()
        .last()
        .unwrap()
        .split(',')
        .filter(|v| !v.is_empty())
        .map(|v| v.parse().unwrap())
        .collect()
}

/// A tiny model and critic so that a training iteration takes milliseconds, checkpointing every
/// iteration.
pub const TINY: &str = r#"
batch = 2
crop = 16
critic_steps = 2
generator_steps = 2
critic_widths = [4, 8, 8, 8]
hidden_layers = 2
width = 16
checkpoint_every = 1
preview_every = 2
log_every = 1
"#;

/// A folder with a 48 px stripes exemplar (`ex.png`) and [`TINY`] as `tiny.toml`.
pub fn tiny_run_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = ipfn(
        dir.path(),
        &["draw", "stripes", "--size", "48", "-o", "ex.png"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    dir
}
