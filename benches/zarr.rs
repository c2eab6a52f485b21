//! Sharded Zarr output: what sharding buys and what the store costs, measured by running the
//! `ipfn` binary as a user would.
//!
//! - Worker scaling: the same image rendered into a Zarr store by 1 worker process and by 2
//!   concurrent workers (`--shard 0/2`, `--shard 1/2`), each worker on one thread
//!   (`RAYON_NUM_THREADS=1`, as one machine of a cluster is one worker). The ratio is the
//!   speed-up of two workers over one.
//! - Format overhead: the same render to `.npy`, `.png` and `.zarr` (float32 and uint8) by one
//!   process on all cores.
//! - A volume: a 3D generator of the paper's size (10x128) to `.npy` and `.zarr`.
//! - On paper, from the measured one-core cost per pixel and per voxel: the machine time of a
//!   10^12-pixel texture and a 4096³ volume, and the machines that finish each in one hour.
//!
//! `cargo bench --bench zarr`; `IPFN_BENCH_ZARR_SIZE` (default 4096) and
//! `IPFN_BENCH_ZARR_CUBE` (default 256) choose the sizes.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use ipfn::checkpoint::Checkpoint;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};

fn ipfn(dir: &Path, args: &[&str], threads: Option<usize>) -> Child {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ipfn"));
    cmd.args(args)
        .arg("--quiet")
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::inherit());
    if let Some(n) = threads {
        cmd.env("RAYON_NUM_THREADS", n.to_string());
    }
    cmd.spawn().expect("ipfn runs")
}

/// Seconds for `workers` concurrent runs of `args` (shard flags added when more than one).
fn timed(dir: &Path, args: &[&str], workers: usize, threads: Option<usize>) -> f64 {
    let start = Instant::now();
    let children: Vec<Child> = (0..workers)
        .map(|k| {
            let shard = format!("{k}/{workers}");
            let mut all = args.to_vec();
            if workers > 1 {
                all.extend(["--shard", &shard]);
            }
            ipfn(dir, &all, threads)
        })
        .collect();
    for mut child in children {
        assert!(child.wait().unwrap().success(), "ipfn {args:?} failed");
    }
    start.elapsed().as_secs_f64()
}

fn clean(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let p = entry.path();
        if p.is_dir() {
            std::fs::remove_dir_all(p).unwrap();
        } else if p.extension().is_some_and(|e| e != "ipfn") {
            std::fs::remove_file(p).unwrap();
        }
    }
}

fn env_size(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let n = env_size("IPFN_BENCH_ZARR_SIZE", 4096);
    let cube = env_size("IPFN_BENCH_ZARR_CUBE", 256);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let size = n.to_string();
    let pixels = (n * n) as f64;
    let image = |out: &str| -> Vec<String> {
        ["synth", "--size", &size, "--seed", "7", "--out", out]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    let run = |args: &[String], workers: usize, threads: Option<usize>| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        clean(d);
        timed(d, &args, workers, threads)
    };

    println!(
        "shipped honeycomb model, {n}x{n} (seed 7), {} cores",
        num_cpus()
    );
    println!("\n| workers (1 thread each) | seconds | Mpixel/s | speed-up over 1 worker |");
    println!("|---|---|---|---|");
    let one = run(&image("w.zarr"), 1, Some(1));
    let two = run(&image("w.zarr"), 2, Some(1));
    for (workers, s) in [(1, one), (2, two)] {
        println!(
            "| {workers} | {s:.2} | {:.2} | {:.2} |",
            pixels / s / 1e6,
            one / s
        );
    }

    println!("\n| output (1 process, all cores) | seconds | / .npy |");
    println!("|---|---|---|");
    let npy = run(&image("o.npy"), 1, None);
    let mut bits8 = image("o8.zarr");
    bits8.extend(["--bits".to_string(), "8".to_string()]);
    let formats = [
        (".npy (float32)", npy),
        (".png (8-bit)", run(&image("o.png"), 1, None)),
        (".zarr (float32, gzip)", run(&image("o.zarr"), 1, None)),
        (".zarr (uint8, gzip)", run(&bits8, 1, None)),
    ];
    for (name, s) in formats {
        println!("| {name} | {s:.2} | {:.2} |", s / npy);
    }

    // A volume: the paper's 3D generator size, random weights.
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_crop(64);
    let mut ckpt = Checkpoint::new();
    GeneratorWeights::random(&config, 0).write_to(&config, &mut ckpt);
    ckpt.save(&d.join("v.ipfn")).unwrap();
    let side = cube.to_string();
    let volume = |out: &str| -> Vec<String> {
        [
            "synth",
            "--model",
            "v.ipfn",
            "--size",
            &format!("{side}x{side}x{side}"),
            "--out",
            out,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let voxels = (cube * cube * cube) as f64;
    println!("\n| volume {cube}³, 10x128 generator | seconds | / .npy |");
    println!("|---|---|---|");
    let vnpy = run(&volume("v.npy"), 1, None);
    let vzarr = run(&volume("v.zarr"), 1, None);
    let vone = run(&volume("v1.zarr"), 1, Some(1));
    for (name, s) in [
        (".npy, all cores", vnpy),
        (".zarr, all cores", vzarr),
        (".zarr, 1 thread", vone),
    ] {
        println!("| {name} | {s:.2} | {:.2} |", s / vnpy);
    }

    // On paper: one core's measured cost, scaled to the jobs.
    let per_pixel = one / pixels;
    let per_voxel = vone / voxels;
    let texture = 1e12 * per_pixel / 3600.0;
    let big_volume = 4096f64.powi(3) * per_voxel / 3600.0;
    println!(
        "\n| job (on paper, from the 1-thread figures above) | core-hours | 16-core machines for 1 hour |"
    );
    println!("|---|---|---|");
    println!(
        "| 10^12-pixel texture, shipped honeycomb | {texture:.0} | {:.0} |",
        (texture / 16.0).ceil()
    );
    println!(
        "| 4096³ volume, 10x128 generator | {big_volume:.0} | {:.0} |",
        (big_volume / 16.0).ceil()
    );
}

fn num_cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
