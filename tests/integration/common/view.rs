//! Helpers for the `ipfn view` tests: start a viewer, fetch from it, compare its tiles.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use super::{ipfn, stderr};

/// A running `ipfn view`, killed when dropped.
pub struct Viewer {
    pub child: Child,
    pub url: String,
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The metrics.csv columns a scored image run's page plots.
pub const PLOTTED: [&str; 7] = [
    "wasserstein",
    "penalty",
    "k_rows",
    "k_cols",
    "sifid",
    "structure",
    "repeat",
];

pub fn view(dir: &Path, args: &[&str]) -> Viewer {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .arg("view")
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.starts_with("http://127.0.0.1:"), "printed {line:?}");
    Viewer {
        child,
        url: line.trim().trim_end_matches('/').to_string(),
    }
}

pub fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(120)))
        .build()
        .into()
}

/// GET (or POST) `path` of the viewer: status and body.
pub fn fetch(viewer: &Viewer, method: &str, path: &str) -> (u16, Vec<u8>) {
    let url = format!("{}{path}", viewer.url);
    let mut response = match method {
        "POST" => agent().post(&url).header("X-Ipfn", "1").send_empty(),
        _ => agent().get(&url).call(),
    }
    .unwrap();
    let body = response
        .body_mut()
        .with_config()
        .limit(1 << 30)
        .read_to_vec()
        .unwrap();
    (response.status().as_u16(), body)
}

/// Decoded 8-bit pixels of a PNG: (width, height, bytes).
pub fn pixels(png: &[u8]) -> (u32, u32, Vec<u8>) {
    let image = image::load_from_memory(png).unwrap();
    (image.width(), image.height(), image.into_bytes())
}

pub fn synth(dir: &Path, args: &[&str]) -> (u32, u32, Vec<u8>) {
    let mut all = vec!["synth", "-q", "--out", "expected.png"];
    all.extend_from_slice(args);
    let out = ipfn(dir, &all);
    assert!(out.status.success(), "{}", stderr(&out));
    pixels(&std::fs::read(dir.join("expected.png")).unwrap())
}

/// The tile at `query` equals `ipfn synth ARGS`, pixel for pixel.
pub fn assert_tile_is(viewer: &Viewer, dir: &Path, query: &str, args: &[&str]) {
    let (status, png) = fetch(viewer, "GET", &format!("/tile?{query}"));
    assert_eq!(status, 200, "{query}: {}", String::from_utf8_lossy(&png));
    let tile = pixels(&png);
    let expected = synth(dir, args);
    assert_eq!((tile.0, tile.1), (expected.0, expected.1), "{query}: size");
    assert_same(
        &tile,
        &expected,
        &format!("{query} against ipfn synth {args:?}"),
    );
}

/// Two decoded images are the same, pixel for pixel (without printing them).
pub fn assert_same(a: &(u32, u32, Vec<u8>), b: &(u32, u32, Vec<u8>), what: &str) {
    assert_eq!((a.0, a.1, a.2.len()), (b.0, b.1, b.2.len()), "{what}: size");
    let differ = a.2.iter().zip(&b.2).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{what}: {differ} values differ");
}

/// `ipfn train --config CONFIG --iterations N -q --device flex ARGS` in `dir`, which must succeed:
/// the small runs the viewer's tests look at.
pub fn train_quietly(dir: &Path, config: &str, iterations: &str, args: &[&str]) {
    let head = [
        "train",
        "--config",
        config,
        "--iterations",
        iterations,
        "-q",
        "--device",
        "flex",
    ];
    let out = ipfn(dir, &[&head[..], args].concat());
    assert!(out.status.success(), "{}", stderr(&out));
}
