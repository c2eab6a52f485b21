//! Hard stops and damaged runs: SIGTERM is handled like Ctrl-C (a checkpoint, then exit 143),
//! a stopped `synth` leaves no temporary file, one process trains a run folder at a time, and a
//! damaged `latest.ipfn` offers `previous.ipfn`.

use crate::common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use crate::common::{assert_error, ipfn, stderr};
use ipfn::checkpoint::Checkpoint;

fn metrics_rows(run: &Path) -> usize {
    std::fs::read_to_string(run.join("metrics.csv")).map_or(0, |s| s.lines().count().max(1) - 1)
}

/// Starts `ipfn args` and waits until `run` has more than `rows` metrics rows.
fn train_until(d: &Path, args: &[&str], run: &str, rows: usize) -> Child {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ipfn"))
        .args(args)
        .current_dir(d)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    while metrics_rows(&d.join(run)) <= rows {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("training exited ({status}) before writing {rows} metrics rows");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

fn signal(child: &Child, name: &str) {
    let pid = child.id().to_string();
    let sent = Command::new("kill").args([name, &pid]).status().unwrap();
    assert!(sent.success());
}

/// Whether the child is stopped (state `T` in `/proc/PID/stat`): alive, and not running on.
fn process_is_stopped(child: &Child) -> bool {
    let stat = std::fs::read_to_string(format!("/proc/{}/stat", child.id())).unwrap();
    // The state follows the command name, which is in parentheses.
    let state = stat.rsplit_once(") ").map(|(_, rest)| rest.chars().next());
    state == Some(Some('T'))
}

fn iteration(file: &Path) -> u64 {
    Checkpoint::load(file).unwrap().metadata["iteration"]
        .parse()
        .unwrap()
}

fn temporaries(dir: &Path) -> Vec<String> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if entry.path().is_dir() {
            found.extend(temporaries(&entry.path()));
        } else if name.ends_with(".tmp") {
            found.push(entry.path().display().to_string());
        }
    }
    found
}

const TRAIN: [&str; 8] = [
    "train",
    "ex.png",
    "--config",
    "tiny.toml",
    "--out",
    "run",
    "--iterations",
    "100000",
];

#[test]
fn sigterm_saves_a_checkpoint_and_exits_143() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    let child = train_until(d, &TRAIN, "run", 3);
    signal(&child, "-TERM");
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(143), "{}", stderr(&out));
    assert!(stderr(&out).contains("SIGTERM"), "{}", stderr(&out));
    let it = iteration(&d.join("run/latest.ipfn"));
    assert_eq!(
        it as usize,
        metrics_rows(&d.join("run")),
        "the checkpoint holds the last iteration"
    );
    assert!(temporaries(d).is_empty(), "{:?}", temporaries(d));
    let out = ipfn(
        d,
        &[
            "train",
            "--resume",
            "run",
            "--iterations",
            &(it + 2).to_string(),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(iteration(&d.join("run/latest.ipfn")), it + 2);
}

/// A second signal exits at once, and what is on disk is still whole.
#[test]
fn second_signal_exits_at_once_leaving_whole_files() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    let child = train_until(d, &TRAIN, "run", 3);
    signal(&child, "-TERM");
    signal(&child, "-INT");
    let out = child.wait_with_output().unwrap();
    assert!(
        matches!(out.status.code(), Some(143) | Some(130)),
        "{:?}: {}",
        out.status.code(),
        stderr(&out)
    );
    iteration(&d.join("run/latest.ipfn"));
    assert!(temporaries(d).is_empty(), "{:?}", temporaries(d));
}

/// `synth` stopped in the middle of a large image removes its temporary file.
#[test]
fn stopped_synth_leaves_no_temporary_file() {
    for name in ["-TERM", "-INT"] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut child = Command::new(env!("CARGO_BIN_EXE_ipfn"))
            .args(["synth", "--size", "6000", "--out", "big.png"])
            .current_dir(d)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait for the temporary file to appear: the render is under way. Freeze it there
        // (SIGSTOP), see that it is frozen mid-render, and only then send the signal under test,
        // which it receives when it continues: the signal lands during the render by
        // construction, not because the render is slow.
        while temporaries(d).is_empty() {
            assert!(
                child.try_wait().unwrap().is_none(),
                "synth ended before it was stopped"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        signal(&child, "-STOP");
        while !process_is_stopped(&child) {
            assert!(
                child.try_wait().unwrap().is_none(),
                "synth ended before it was frozen"
            );
            std::thread::yield_now();
        }
        signal(&child, name);
        signal(&child, "-CONT");
        let status = child.wait().unwrap();
        let expected = if name == "-TERM" { 143 } else { 130 };
        assert_eq!(status.code(), Some(expected));
        assert!(temporaries(d).is_empty(), "{name}: {:?}", temporaries(d));
        assert!(!d.join("big.png").exists());
    }
}

/// A run folder in use refuses a second writer with one line naming the holder; the lock of a
/// killed process does not block.
#[test]
fn one_writer_per_run_folder() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    let mut child = train_until(d, &TRAIN, "run", 2);
    let second = ipfn(d, &["train", "--resume", "run", "--quiet"]);
    assert_error(&second, &["run", "in use", &format!("pid {}", child.id())]);
    let fresh = ipfn(
        d,
        &["train", "ex.png", "--config", "tiny.toml", "--out", "run"],
    );
    assert_eq!(fresh.status.code(), Some(2), "{}", stderr(&fresh));
    child.kill().unwrap(); // SIGKILL: the lock file stays, the lock does not
    child.wait().unwrap();
    assert!(d.join("run/run.lock").exists());
    let it = iteration(&d.join("run/latest.ipfn"));
    let out = ipfn(
        d,
        &[
            "train",
            "--resume",
            "run",
            "--iterations",
            &(it + 1).to_string(),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
}

/// A truncated `latest.ipfn` is refused with a line that offers `previous.ipfn`, and
/// `--from-previous` resumes from it.
#[test]
fn damaged_latest_offers_previous() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    let out = ipfn(d, &[&TRAIN[..6], &["--iterations", "3"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let run = d.join("run");
    assert_eq!(iteration(&run.join("latest.ipfn")), 3);
    assert_eq!(iteration(&run.join("previous.ipfn")), 2);
    let bytes = std::fs::read(run.join("latest.ipfn")).unwrap();
    std::fs::write(run.join("latest.ipfn"), &bytes[..bytes.len() / 2]).unwrap();
    let refused = ipfn(d, &["train", "--resume", "run", "--iterations", "5"]);
    assert_error(
        &refused,
        &[
            "latest.ipfn",
            "previous.ipfn",
            "iteration 2",
            "--from-previous",
        ],
    );
    let out = ipfn(
        d,
        &[
            "train",
            "--resume",
            "run",
            "--from-previous",
            "--iterations",
            "5",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(iteration(&run.join("latest.ipfn")), 5);
    assert_eq!(
        metrics_rows(&run),
        5,
        "rows after the resumed state were replaced"
    );
}

/// Settings that would size an allocation beyond reason are one-line errors, before any
/// allocation (the issue's config once took 11 GB and hung).
#[test]
fn absurd_settings_are_refused_before_allocation() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    std::fs::write(
        d.join("huge.toml"),
        "width = 100000000\nhidden_layers = 100000\n",
    )
    .unwrap();
    let cases: [(&[&str], &[&str]); 6] = [
        (
            &["--config", "huge.toml"],
            &["width = 100000000", "at most"],
        ),
        (&["--batch", "1000000"], &["batch = 1000000", "at most"]),
        (
            &["--iterations", "1000000000000"],
            &["iterations", "at most"],
        ),
        (&["--time", "99999999999h"], &["--time", "at most"]),
        (&["--crop", "1024", "--batch", "512"], &["values per batch"]),
        (&["--lr", "inf"], &["finite"]),
    ];
    for (flags, needles) in cases {
        let out = ipfn(d, &[&["train", "ex.png", "--out", "r"][..], flags].concat());
        assert_error(&out, needles);
        assert!(!d.join("r").exists(), "{flags:?}: nothing written");
    }
}

/// Runs `script` (bash, with `$D` the test folder and `$B` the binary) in a new user and mount
/// namespace, where it may mount small tmpfs file systems; `None` where this machine allows
/// neither (no user namespaces, no root).
fn in_mount_namespace(d: &Path, script: &str) -> Option<std::process::Output> {
    let probe = Command::new("unshare")
        .args([
            "-rm",
            "sh",
            "-c",
            "mkdir -p /tmp/.ipfn-probe && mount -t tmpfs -o size=64k tmpfs /tmp/.ipfn-probe",
        ])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        return None;
    }
    Some(
        Command::new("unshare")
            .args(["-rm", "bash", "-c", script])
            .env("D", d)
            .env("B", env!("CARGO_BIN_EXE_ipfn"))
            .output()
            .unwrap(),
    )
}

/// A full disk (a small tmpfs): training stops with one line and exit 1, the last checkpoint
/// stays whole, no temporary file is left, and `--resume` continues once there is space;
/// `synth` of an image and of a volume fail the same way, leaving nothing.
#[test]
#[ignore = "needs user and mount namespaces (unshare -rm); run by `cargo test --release -- --ignored`"]
fn full_disk_loses_nothing() {
    let dir = common::tiny_run_folder();
    let d = dir.path();
    let config = ipfn::generator::GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_hidden_layers(2)
        .with_width(8)
        .with_crop(16);
    let mut model = Checkpoint::new();
    ipfn::generator::GeneratorWeights::random(&config, 0).write_to(&config, &mut model);
    model.save(&d.join("vol.ipfn")).unwrap();
    let script = r#"
        set -u
        mkdir -p "$D/small" "$D/tiny"
        mount -t tmpfs -o size=256k tmpfs "$D/small"
        mount -t tmpfs -o size=32k tmpfs "$D/tiny"
        cp "$D/ex.png" "$D/tiny.toml" "$D/small/"
        cd "$D/small"
        "$B" train ex.png --config tiny.toml --out run --iterations 100000 -q 2> "$D/train.err"
        echo $? > "$D/train.code"
        find . -name '*.tmp' > "$D/train.tmps"
        "$B" synth --model run/latest.ipfn --size 8 --out "$D/check.png" -q
        echo $? > "$D/check.code"
        mount -o remount,size=16m tmpfs "$D/small"
        it=$(cat run/metrics.csv | tail -1 | cut -d, -f1)
        "$B" train --resume run --iterations $((it + 2)) -q 2> "$D/resume.err"
        echo $? > "$D/resume.code"
        "$B" synth --model run/latest.ipfn --size 8 --out "$D/resumed.png" -q
        "$B" synth --size 512 --out "$D/tiny/x.png" -q 2> "$D/image.err"
        echo $? > "$D/image.code"
        "$B" synth --model "$D/vol.ipfn" --size 40x40x40 --out "$D/tiny/v.npy" -q 2> "$D/volume.err"
        echo $? > "$D/volume.code"
        find "$D/tiny" -type f > "$D/tiny.files"
    "#;
    let out = in_mount_namespace(d, script)
        .expect("user and mount namespaces (unshare -rm) are needed for the full-disk test");
    assert!(out.status.success(), "{}", stderr(&out));
    let read = |name: &str| std::fs::read_to_string(d.join(name)).unwrap();
    assert_eq!(
        read("train.code").trim(),
        "1",
        "training on a full disk: {}",
        read("train.err")
    );
    assert_eq!(
        read("train.err").trim_end().lines().count(),
        1,
        "{}",
        read("train.err")
    );
    assert!(
        read("train.err").contains("No space left"),
        "{}",
        read("train.err")
    );
    assert!(
        read("train.err").contains("ipfn train --resume run"),
        "{}",
        read("train.err")
    );
    assert_eq!(read("train.tmps"), "", "temporary files left");
    assert_eq!(read("check.code").trim(), "0", "latest.ipfn is whole");
    assert_eq!(
        read("resume.code").trim(),
        "0",
        "resume with space: {}",
        read("resume.err")
    );
    assert!(d.join("resumed.png").exists());
    for what in ["image", "volume"] {
        let err = read(&format!("{what}.err"));
        assert_ne!(read(&format!("{what}.code")).trim(), "0", "{what}");
        assert_eq!(err.trim_end().lines().count(), 1, "{what}: {err}");
        assert!(err.contains("No space left"), "{what}: {err}");
    }
    assert_eq!(read("tiny.files"), "", "nothing left on the full disk");
}
