//! `ipfn view` in headless chromium (Debian's, driven by tests/browser's playwright-core): the
//! plane shows exactly what `ipfn synth` paints, pans, zooms and lives in the URL; a run folder's
//! page and its `report.html` draw their plots and previews.

use crate::common;

use std::path::Path;
use std::process::Command;

use crate::common::tiny_run_folder;
use crate::common::view::{assert_same, pixels, synth, train_quietly, view};

/// Headless chromium: Debian's `chromium` and tests/browser's playwright-core (`npm ci`), as
/// `.ci/run` installs them. Skipped (with a message) only outside CI when they are missing.
fn assert_browser_ready() {
    let chromium =
        Path::new(&std::env::var("CHROMIUM").unwrap_or("/usr/bin/chromium".into())).is_file();
    let driver = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/browser/node_modules/playwright-core")
        .is_dir();
    assert!(
        chromium && driver,
        "the browser tests need /usr/bin/chromium (apt-get install chromium) and \
         `npm ci --prefix tests/browser`"
    );
}

fn browse(mode: &str, url: &str, out: &Path, env: &[(&str, String)]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser/view.mjs");
    let status = Command::new("node")
        .arg(&script)
        .args([mode, url, out.to_str().unwrap()])
        .envs(env.iter().map(|(k, v)| (k, v)))
        .status()
        .unwrap();
    assert!(status.success());
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("record.json")).unwrap()).unwrap();
    assert!(record.get("error").is_none(), "{record:#}");
    record
}

/// `IPFN_SCREENSHOTS=DIR`: the browser tests also save the README's screenshots there.
fn screenshot(name: &str) -> Vec<(&'static str, String)> {
    std::env::var("IPFN_SCREENSHOTS")
        .map(|dir| vec![("SCREENSHOT", format!("{dir}/{name}"))])
        .unwrap_or_default()
}

#[test]
#[ignore = "needs chromium and `npm ci --prefix tests/browser`; run by `cargo test --release -- --ignored`"]
fn chromium_shows_the_plane_as_synth_paints_it_and_pans() {
    assert_browser_ready();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let viewer = view(d, &[]);
    let record = browse(
        "plane",
        &format!("{}/#seed=3&zoom=1.5&noise=0.8&cx=300&cy=-200", viewer.url),
        d,
        &screenshot("view-plane.png"),
    );
    // Every tile the page fetched is `ipfn synth` at its offset.
    let tiles = record["tiles"].as_array().unwrap();
    assert!(tiles.len() >= 12, "{}", tiles.len());
    for tile in tiles {
        let url = tile["url"].as_str().unwrap();
        let q: std::collections::HashMap<String, String> =
            form_urlencoded::parse(url.split_once('?').unwrap().1.as_bytes())
                .into_owned()
                .collect();
        let offset = format!("{},{}", q["x"], q["y"]);
        let zoom = q["zoom"].as_str();
        assert!(zoom == "1.5" || zoom == "1.875", "{url}");
        let expected = synth(
            d,
            &[
                "--seed",
                "3",
                "--zoom",
                zoom,
                "--noise-scale",
                "0.8",
                "--offset",
                &offset,
                "--size",
                "256",
            ],
        );
        let shown = pixels(&std::fs::read(tile["file"].as_str().unwrap()).unwrap());
        assert_same(&shown, &expected, &format!("tile at {offset}"));
    }
    // Placed where the view says: the view's centre (cx, cy) is the plane's centre.
    let place = |view: &serde_json::Value, cx: i64, cy: i64| {
        let [w, h] = [
            view["plane"][0].as_i64().unwrap(),
            view["plane"][1].as_i64().unwrap(),
        ];
        for t in view["tiles"].as_array().unwrap() {
            let (x, y) = (t["x"].as_i64().unwrap(), t["y"].as_i64().unwrap());
            assert_eq!(t["left"].as_i64().unwrap(), x - (cx - w / 2), "{t}");
            assert_eq!(t["top"].as_i64().unwrap(), y - (cy - h / 2), "{t}");
        }
    };
    place(&record["before"], 300, -200);
    // Dragged 100 px left and 50 up: the plane moved with the pointer, and the URL says so.
    place(&record["after"], 400, -150);
    let hash = record["after"]["hash"].as_str().unwrap();
    assert!(
        hash.contains("cx=400") && hash.contains("cy=-150"),
        "{hash}"
    );
    assert_eq!(
        record["reopened"]["tiles"], record["after"]["tiles"],
        "the URL reopens the view"
    );
    // One wheel notch at the centre: zoom x1.25 about it, every tile painted at the new zoom.
    let zoomed = &record["zoomed"];
    let hash = zoomed["hash"].as_str().unwrap();
    assert!(
        hash.contains("zoom=1.875") && hash.contains("cx=500"),
        "{hash}"
    );
    // -150 x 1.25 = -187.5, which the page rounds as JavaScript's Math.round does: to -187.
    assert!(hash.contains("cy=-187"), "{hash}");
    place(zoomed, 500, -187);
    for t in zoomed["tiles"].as_array().unwrap() {
        assert!(t["src"].as_str().unwrap().contains("zoom=1.875"), "{t}");
    }
}

#[test]
#[ignore = "needs chromium and `npm ci --prefix tests/browser`; run by `cargo test --release -- --ignored`"]
fn chromium_shows_a_run_and_its_report() {
    assert_browser_ready();
    let dir = tiny_run_folder();
    let d = dir.path();
    train_quietly(d, "tiny.toml", "12", &["ex.png", "--out", "run"]);
    let viewer = view(d, &["run"]);
    let mut env = screenshot("view-run.png");
    env.push((
        "REPORT",
        format!("file://{}", d.join("run/report.html").display()),
    ));
    let record = browse("run", &format!("{}/", viewer.url), d, &env);
    for key in ["run", "report"] {
        let series: Vec<&str> = record[key]["series"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap())
            .collect();
        for expected in common::view::PLOTTED {
            assert!(series.contains(&expected), "{key}: {series:?}");
        }
        assert_eq!(record[key]["state"], "finished", "{key}");
    }
    assert_eq!(record["run"]["previews"], 6);
    assert_eq!(record["report"]["previews"], 6);
}
