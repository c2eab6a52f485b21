//! `ipfn view` over HTTP: tiles equal `ipfn synth`, bad requests get 400, runs are followed
//! live and reported, exports go through synth, Ctrl-C leaves nothing behind, load does not
//! stall the page. `tests/integration/view_browser.rs` opens the page in headless chromium.

use crate::common;

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use crate::common::view::{
    Viewer, agent, assert_same, assert_tile_is, fetch, pixels, train_quietly, view,
};
use crate::common::{TINY, ipfn, stderr, tiny_run_folder};

#[test]
fn tiles_hold_exactly_the_pixels_of_ipfn_synth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let viewer = view(d, &[]); // the shipped honeycomb
    let plain = "seed=3&zoom=1.5&noise=0.8&size=256";
    for (x, y) in [(256, -512), (-256, 0)] {
        let offset = format!("{x},{y}");
        assert_tile_is(
            &viewer,
            d,
            &format!("{plain}&x={x}&y={y}"),
            &[
                "--seed",
                "3",
                "--zoom",
                "1.5",
                "--noise-scale",
                "0.8",
                "--offset",
                &offset,
                "--size",
                "256",
            ],
        );
    }
    // Tile mode: every tile is the one period that `synth --tile` paints.
    assert_tile_is(
        &viewer,
        d,
        "seed=5&tile=200x160&x=4096&y=-512",
        &["--seed", "5", "--tile", "--width", "200", "--height", "160"],
    );
}

#[test]
fn tiles_of_map_sets_guided_and_3d_models_equal_synth() {
    let dir = tiny_run_folder();
    let d = dir.path();
    assert!(
        ipfn(d, &["draw", "material", "--size", "64", "-o", "mat"])
            .status
            .success()
    );
    let maps = ["--maps", "mat/albedo.png,mat/normal.png", "--out", "maps"];
    train_quietly(d, "tiny.toml", "2", &maps);
    train_quietly(
        d,
        "tiny.toml",
        "2",
        &["ex.png", "--solid", "--out", "solid"],
    );
    std::fs::write(d.join("guided.toml"), format!("{TINY}\nguide = \"x\"\n")).unwrap();
    train_quietly(d, "guided.toml", "2", &["ex.png", "--out", "guided"]);

    // A map set: the normal map (renormalised), as synth writes normal.png.
    let viewer = view(d, &["maps/latest.ipfn"]);
    let (_, png) = fetch(&viewer, "GET", "/tile?map=1&size=64&x=32&y=-64&seed=2");
    let tile = pixels(&png);
    // After the maps, the material lit, as synth --preview renders it.
    let (_, png) = fetch(&viewer, "GET", "/tile?map=2&size=64&x=32&y=-64&seed=2");
    let lit = pixels(&png);
    let (status, text) = fetch(&viewer, "GET", "/tile?map=3");
    assert_eq!(status, 400, "{}", String::from_utf8_lossy(&text));
    assert!(String::from_utf8_lossy(&text).contains("2 map(s) and the lit material"));
    let out = ipfn(
        d,
        &[
            "synth",
            "-q",
            "--model",
            "maps/latest.ipfn",
            "--seed",
            "2",
            "--offset",
            "32,-64",
            "--size",
            "64",
            "--bits",
            "8",
            "--preview",
            "m-lit.png",
            "--out",
            "m.png",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let expected = pixels(&std::fs::read(d.join("m-normal.png")).unwrap());
    assert_same(&tile, &expected, "the normal map's tile");
    let expected = pixels(&std::fs::read(d.join("m-lit.png")).unwrap());
    assert_same(&lit, &expected, "the lit material's tile");
    drop(viewer);

    // A solid texture: planes across z and across y.
    let viewer = view(d, &["solid/latest.ipfn"]);
    assert_tile_is(
        &viewer,
        d,
        "axis=z&depth=3&size=64",
        &[
            "--model",
            "solid/latest.ipfn",
            "--slice",
            "z=3",
            "--size",
            "64x64x4",
        ],
    );
    assert_tile_is(
        &viewer,
        d,
        "axis=y&depth=5&size=32&seed=1",
        &[
            "--model",
            "solid/latest.ipfn",
            "--seed",
            "1",
            "--slice",
            "y=5",
            "--size",
            "32x6x32",
        ],
    );
    let x_plane = "axis=x&depth=2&size=32";
    let args = [
        "--model",
        "solid/latest.ipfn",
        "--slice",
        "x=2",
        "--size",
        "3x32x32",
    ];
    assert_tile_is(&viewer, d, x_plane, &args);
    // Its export: the same plane, through synth, with the command that paints it.
    let (status, body) = fetch(&viewer, "POST", "/export?axis=x&depth=2&size=32x32");
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let answer: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let command = answer["command"].as_str().unwrap();
    assert!(command.contains("--size 3x32x32 --slice x=2"), "{command}");
    let (_, tile) = fetch(&viewer, "GET", &format!("/tile?{x_plane}"));
    let exported = std::fs::read(d.join(answer["file"].as_str().unwrap())).unwrap();
    assert_same(&pixels(&tile), &pixels(&exported), "the 3D export");
    drop(viewer);

    // A guided model: the guide's frame starts at the origin.
    let viewer = view(d, &["guided/latest.ipfn"]);
    assert_tile_is(
        &viewer,
        d,
        "guide=-y&frame=64x64&size=64",
        &[
            "--model",
            "guided/latest.ipfn",
            "--guide",
            "-y",
            "--size",
            "64",
        ],
    );
    // In tile mode the guide's frame is the tile, as `synth --tile --guide` has it.
    assert_tile_is(
        &viewer,
        d,
        "guide=-y&frame=512x512&tile=128x64",
        &[
            "--model",
            "guided/latest.ipfn",
            "--guide",
            "-y",
            "--tile",
            "--width",
            "128",
            "--height",
            "64",
        ],
    );
    let (status, body) = fetch(&viewer, "GET", "/tile?guide=/etc/passwd");
    assert_eq!(
        status,
        400,
        "a guide image path is refused: {}",
        String::from_utf8_lossy(&body)
    );
}

#[test]
fn bad_requests_get_400_with_a_message_and_the_server_lives_on() {
    let dir = tempfile::tempdir().unwrap();
    let viewer = view(dir.path(), &[]);
    let cases: &[(&str, &str, u16, &str)] = &[
        ("GET", "/tile?zoom=0", 400, "zoom 0"),
        ("GET", "/tile?zoom=nan", 400, "zoom"),
        ("GET", "/tile?x=1000000000", 400, "within 1000000 pixels"),
        (
            "GET",
            "/tile?x=-9223372036854775808",
            400,
            "within 1000000 pixels",
        ),
        (
            "GET",
            "/tile?y=99999999999999999999",
            400,
            "not a valid value",
        ),
        ("GET", "/tile?depth=-1", 400, "depth -1"),
        ("GET", "/tile?tile=32x32", 400, "64 to 2048"),
        (
            "POST",
            "/export?size=5000x5000",
            400,
            "at most 16777216 pixels",
        ),
        ("GET", "/tile?seed=abc", 400, "seed 'abc'"),
        ("GET", "/tile?seed=-1", 400, "seed"),
        ("GET", "/tile?size=0", 400, "size 0"),
        ("GET", "/tile?size=100000", 400, "size 100000"),
        ("GET", "/tile?tile=0x0", 400, "tile"),
        ("GET", "/tile?tile=100000x100000", 400, "tile"),
        ("GET", "/tile?noise=1e300", 400, "noise"),
        ("GET", "/tile?map=3", 400, "map 3"),
        ("GET", "/tile?axis=y", 400, "slices"),
        ("GET", "/tile?seed=1&seed=2", 400, "twice"),
        ("GET", "/tile?what=1", 400, "unknown parameter"),
        ("GET", "/tile?guide=x", 400, "not guided"),
        ("GET", "/tile?%ff%fe=1", 400, "unknown parameter"),
        ("POST", "/export?size=99999x1", 400, "size"),
        ("GET", "/../../etc/passwd", 404, "no such page"),
        ("GET", "/preview/../config.toml", 404, "no such"),
        ("GET", "/preview/iter-1.png", 404, "no run folder"),
        (
            "GET",
            "/exports/..%2f..%2fetc%2fpasswd",
            404,
            "no such export",
        ),
        ("GET", "/api/run", 404, "not a run folder"),
        ("POST", "/", 405, "not allowed"),
    ];
    for (method, path, status, needle) in cases {
        let (got, body) = fetch(&viewer, method, path);
        let body = String::from_utf8_lossy(&body);
        assert_eq!(got, *status, "{method} {path}: {body}");
        assert!(
            body.contains(needle),
            "{method} {path}: {body:?} lacks {needle:?}"
        );
        assert_eq!(
            body.trim().lines().count(),
            1,
            "{method} {path}: one line: {body:?}"
        );
    }
    let long = format!("/tile?seed={}", "9".repeat(10_000));
    assert_eq!(fetch(&viewer, "GET", &long).0, 400);
    assert_eq!(fetch(&viewer, "GET", "/api/info").0, 200, "still serving");
}

#[test]
fn a_run_is_followed_live_and_reported_at_its_end() {
    use std::sync::atomic::AtomicBool;
    use std::sync::mpsc;

    let dir = tiny_run_folder();
    let d = dir.path().to_path_buf();
    // A run that trains in this process while the viewer watches it. After each of its first
    // three checkpoints it waits for the test to look (an event, not a clock), so the viewer
    // is seen following a run that is still running.
    let (seen_tx, seen_rx) = mpsc::channel::<u64>();
    let (go_tx, go_rx) = mpsc::channel::<()>();
    let trainer = {
        let d = d.clone();
        std::thread::spawn(move || {
            let config = ipfn::train::TrainConfig {
                iterations: 400,
                ..ipfn::train::TrainConfig::from_toml(common::TINY, &d.join("tiny.toml")).unwrap()
            };
            let device = burn::prelude::Device::flex();
            let mut trainer =
                ipfn::train::Trainer::new(config, d.join("ex.png"), &d.join("run"), &device)
                    .unwrap();
            let stop = AtomicBool::new(false);
            trainer
                .run(&stop, |_, stats| {
                    // Called once iteration i's checkpoint is saved.
                    if (1..=3).contains(&stats.iteration) {
                        seen_tx.send(stats.iteration).unwrap();
                        go_rx.recv().unwrap();
                    }
                })
                .unwrap();
        })
    };
    let checkpoint = seen_rx.recv().unwrap();
    assert_eq!(checkpoint, 1);
    let viewer = view(&d, &["run"]);
    let run = |v: &Viewer| -> serde_json::Value {
        serde_json::from_slice(&fetch(v, "GET", "/api/run").1).unwrap()
    };
    let info = |v: &Viewer| -> serde_json::Value {
        serde_json::from_slice(&fetch(v, "GET", "/api/info").1).unwrap()
    };
    let first = run(&viewer);
    assert_eq!(first["state"], "running", "{first}");
    // The plane follows the newest checkpoint.
    let mut versions = std::collections::HashSet::new();
    for expected in 1..=3 {
        if expected > 1 {
            go_tx.send(()).unwrap();
            assert_eq!(seen_rx.recv().unwrap(), expected);
        }
        assert_eq!(run(&viewer)["state"], "running");
        versions.insert(info(&viewer)["model"]["version"].to_string());
        let (status, _) = fetch(&viewer, "GET", "/tile?size=32");
        assert_eq!(status, 200);
    }
    assert_eq!(
        versions.len(),
        3,
        "the model changed at each checkpoint: {versions:?}"
    );
    go_tx.send(()).unwrap();
    trainer.join().unwrap();
    let last = run(&viewer);
    assert_eq!(last["state"], "finished", "{last}");
    assert_eq!(last["iteration"], 400);
    let d = d.as_path();
    let metrics = &last["metrics"];
    for column in std::iter::once("iteration").chain(common::view::PLOTTED) {
        assert!(
            metrics[column].as_array().is_some_and(|c| !c.is_empty()),
            "{column}"
        );
    }
    let previews = last["previews"].as_array().unwrap();
    assert_eq!(previews.len(), 200, "a preview every 2 iterations");
    let name = previews[0].as_str().unwrap();
    let (status, png) = fetch(&viewer, "GET", &format!("/preview/{name}"));
    assert_eq!(status, 200);
    assert_eq!(
        png,
        std::fs::read(d.join("run/previews").join(name)).unwrap()
    );
    assert!(
        last["config"]
            .as_str()
            .unwrap()
            .contains("iterations = 400")
    );

    // report.html: the same data, embedded.
    let report = std::fs::read_to_string(d.join("run/report.html")).unwrap();
    assert!(report.contains("window.IPFN_REPORT = {"), "data embedded");
    assert!(report.contains("\"state\":\"finished\""));
    assert!(report.contains(name), "previews by name");
    assert!(
        !report.contains("src=\"http"),
        "nothing fetched from elsewhere"
    );

    drop(viewer);
    let out = ipfn(d, &["view", "nope"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("nope: no such file or folder"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn export_writes_the_view_through_synth_and_shows_the_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("exports")).unwrap();
    let viewer = view(d, &["--export-dir", "exports"]);
    let (status, body) = fetch(
        &viewer,
        "POST",
        "/export?seed=4&zoom=2&x=-100&y=30&size=300x200",
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let answer: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let command = answer["command"].as_str().unwrap();
    let file = answer["file"].as_str().unwrap();
    assert!(file.starts_with("view-seed4-300x200-at-100_30-") && file.ends_with(".png"));
    assert_eq!(
        command,
        format!(
            "ipfn synth --seed 4 --zoom 2 --noise-scale 1 --width 300 --height 200 --offset -100,30 --out exports/{file}"
        )
    );
    let written = std::fs::read(d.join("exports").join(file)).unwrap();
    let (status, served) = fetch(&viewer, "GET", &format!("/exports/{file}"));
    assert_eq!((status, &served), (200, &written));
    // The command, run as shown, paints the same pixels.
    let words: Vec<&str> = command
        .split(' ')
        .skip(1)
        .map(|w| {
            if w.starts_with("exports/") {
                "again.png"
            } else {
                w
            }
        })
        .collect();
    let out = ipfn(d, &words);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_same(
        &pixels(&written),
        &pixels(&std::fs::read(d.join("again.png")).unwrap()),
        "export",
    );
    // Another view never takes its name; a file the viewer did not write is never replaced.
    let (_, other) = fetch(
        &viewer,
        "POST",
        "/export?seed=4&zoom=2.5&x=-100&y=30&size=300x200",
    );
    let other: serde_json::Value = serde_json::from_slice(&other).unwrap();
    assert_ne!(other["file"], answer["file"]);
    std::fs::write(
        d.join("exports").join(other["file"].as_str().unwrap()),
        b"mine",
    )
    .unwrap();
    let (status, body) = fetch(
        &viewer,
        "POST",
        "/export?seed=4&zoom=2.5&x=-100&y=30&size=300x200",
    );
    assert_eq!(
        status,
        200,
        "rewriting its own export is fine: {}",
        String::from_utf8_lossy(&body)
    );
    let (status, body) = fetch(&viewer, "POST", "/export?seed=9&size=64x64");
    assert_eq!(status, 200);
    let name: serde_json::Value = serde_json::from_slice(&body).unwrap();
    drop(viewer);
    let viewer = view(d, &["--export-dir", "exports"]); // a new server: none of these are its own
    let (status, body) = fetch(&viewer, "POST", "/export?seed=9&size=64x64");
    assert_eq!(status, 400);
    let body = String::from_utf8_lossy(&body);
    assert!(
        body.contains(name["file"].as_str().unwrap())
            && body.contains("not written by this viewer"),
        "{body}"
    );
}

#[test]
fn only_its_own_address_and_the_page_reach_the_server() {
    use std::io::{Read, Write};
    let dir = tempfile::tempdir().unwrap();
    let viewer = view(dir.path(), &[]);
    let addr = viewer.url.trim_start_matches("http://").to_string();
    let status_of = |request: String| {
        let mut stream = std::net::TcpStream::connect(&addr).unwrap();
        stream.write_all(request.as_bytes()).unwrap();
        let mut answer = String::new();
        let _ = stream.read_to_string(&mut answer);
        answer.lines().next().unwrap_or("").to_string()
    };
    // A page elsewhere that rebinds its DNS name to 127.0.0.1 sends its own Host.
    let rebound = status_of(
        "GET /api/info HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n".into(),
    );
    assert!(rebound.contains("403"), "{rebound}");
    let own = status_of(format!(
        "GET /api/info HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    ));
    assert!(own.contains("200"), "{own}");
    // A cross-site form can POST, but cannot add the header the page sends.
    let form = status_of(format!(
        "POST /export HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    ));
    assert!(form.contains("403"), "{form}");
}

#[test]
fn ctrl_c_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("exports")).unwrap();
    let mut viewer = view(d, &["--export-dir", "exports"]);
    // An export in progress when the server is stopped.
    let url = format!("{}/export?size=4096x4096", viewer.url);
    let pending = std::thread::spawn(move || {
        let post = agent().post(&url).header("X-Ipfn", "1");
        post.send_empty().map(|r| r.status().as_u16())
    });
    while std::fs::read_dir(d.join("exports")).unwrap().count() == 0 {
        assert!(
            !pending.is_finished(),
            "the export ended before it wrote anything"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let pid = viewer.child.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .unwrap()
            .success()
    );
    let status = viewer.child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "Ctrl-C's exit status");
    assert!(pending.join().unwrap().is_err(), "the export was cut off");
    let left: Vec<PathBuf> = std::fs::read_dir(d.join("exports"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn many_tile_requests_do_not_stall_the_page() {
    let dir = tempfile::tempdir().unwrap();
    let viewer = view(dir.path(), &[]);
    let base = viewer.url.clone();
    // 96 clients at once, 2 distinct 128-pixel tiles each: more than the 64 the queue holds.
    let clients: Vec<_> = (0..96)
        .map(|c| {
            let base = base.clone();
            std::thread::spawn(move || {
                (0..2)
                    .map(|t| {
                        let url = format!("{base}/tile?size=128&x={}&y={}", 128 * c, 128 * t);
                        agent()
                            .get(&url)
                            .call()
                            .map(|r| r.status().as_u16())
                            .unwrap()
                    })
                    .collect::<Vec<u16>>()
            })
        })
        .collect();
    // While tiles queue, the page and its info answer (the queue is seen non-empty).
    let mut busy_seen = false;
    for _ in 0..200 {
        let (status, page) = fetch(&viewer, "GET", "/");
        assert_eq!(status, 200);
        assert!(String::from_utf8_lossy(&page).contains("ipfn view"));
        let info: serde_json::Value =
            serde_json::from_slice(&fetch(&viewer, "GET", "/api/info").1).unwrap();
        if info["queued"].as_u64().unwrap() + info["rendering"].as_u64().unwrap() > 0 {
            busy_seen = true;
            break;
        }
    }
    assert!(
        busy_seen,
        "the page was answered while tiles were being painted"
    );
    let statuses: Vec<u16> = clients
        .into_iter()
        .flat_map(|c| c.join().unwrap())
        .collect();
    assert_eq!(statuses.len(), 192);
    assert!(
        statuses.iter().all(|s| *s == 200 || *s == 503),
        "{statuses:?}"
    );
    assert!(statuses.contains(&200));
    assert!(
        statuses.contains(&503),
        "the queue is bounded: the oldest requests were told to retry"
    );
    let info: serde_json::Value =
        serde_json::from_slice(&fetch(&viewer, "GET", "/api/info").1).unwrap();
    assert!(info["cache_bytes"].as_u64().unwrap() <= 256 << 20);
}
