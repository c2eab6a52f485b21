//! Training speed on the CPU: one iteration (5 critic + 5 generator steps) of the two configs a
//! CPU run uses (`configs/quick.toml`'s, which `ipfn train` takes on a CPU, and the authors'
//! `configs/default.toml`: batch 4, crop 128, 10x128), each
//! - with the fused steps (`ipfn train`'s CPU path) and through burn's autodiff (the GPU path,
//!   here on flex), timed in the same run;
//! - beside its floor measured now: both networks' matrix products as bare GEMMs
//!   (`ipfn::bench::floor`);
//! - and, for the authors' config, beside the authors' PyTorch code on the same 2-core machine
//!   (40.6 s, measured separately: the book's performance page; not re-run here).
//!
//! A third row times `quick.toml` with the diversity hinge (`diversity = 1`, what a photo with
//! no clear period trains with), whose floor adds the twins' generator forward and backward.
//!
//! `cargo bench --bench train` prints the median of `IPFN_BENCH_RUNS` iterations (default 3)
//! after one warm-up, and where the fused iteration's time went. `IPFN_BENCH_CONFIG=FILE`
//! times that config instead of the two.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::prelude::*;
use ipfn::bench::floor;
use ipfn::train::{StepTimes, TrainConfig, Trainer};

const AUTHORS_ITERATION_S: f64 = 40.6;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time_iteration(
    exemplar: &Path,
    config: &TrainConfig,
    framework: bool,
    runs: usize,
) -> (f64, StepTimes) {
    let dir = tempfile::tempdir().unwrap();
    let trainer = Trainer::new(config.clone(), exemplar, dir.path(), &Device::flex()).unwrap();
    let mut trainer = if framework {
        trainer.framework_steps()
    } else {
        trainer
    };
    trainer.step(); // warm-up
    let mut parts = Default::default();
    let time = median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                parts = trainer.step().times;
                t.elapsed().as_secs_f64()
            })
            .collect(),
    );
    (time, parts)
}

fn main() {
    let runs: usize = std::env::var("IPFN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let exemplar = root.join("exemplars/honeycomb.png");
    let read = |path: PathBuf| {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        (name, TrainConfig::from_file(&path).unwrap().0)
    };
    let configs: Vec<(String, TrainConfig)> = match std::env::var("IPFN_BENCH_CONFIG") {
        Ok(path) => vec![read(path.into())],
        Err(_) => {
            let quick = read(root.join("configs/quick.toml"));
            let hinge = (
                format!("{} + diversity 1", quick.0),
                TrainConfig {
                    diversity: 1.0,
                    ..quick.1.clone()
                },
            );
            vec![quick, read(root.join("configs/default.toml")), hinge]
        }
    };
    println!(
        "training on the CPU ({} threads), honeycomb exemplar, median of {runs}",
        rayon::current_num_threads()
    );
    println!(
        "| config | fused (ipfn train) | burn autodiff | GEMM floor of both networks | fused / floor | authors' code | authors / fused |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut splits = Vec::new();
    for (name, config) in configs {
        let (fused, parts) = time_iteration(&exemplar, &config, false, runs);
        let (framework, _) = time_iteration(&exemplar, &config, true, runs);
        let kind = config.run_kind().unwrap();
        let products = floor::iteration_products(&config, &kind, 3);
        let floor_s = ipfn::bench::time(runs, floor::run_products(&products));
        let authors = if name == "default.toml" {
            format!(
                "{AUTHORS_ITERATION_S:.1} s (reference) | {:.1}x",
                AUTHORS_ITERATION_S / fused
            )
        } else {
            "- | -".into()
        };
        println!(
            "| {name} (batch {}, crop {}, {}x{}) | {fused:.3} s | {framework:.3} s | {floor_s:.3} s ({:.0} GFLOP) | {:.2}x | {authors} |",
            config.batch,
            config.crop,
            config.hidden_layers,
            config.width,
            floor::flops(&products) / 1e9,
            fused / floor_s,
        );
        splits.push((name, parts));
    }
    println!();
    println!("where the fused iteration's time went (seconds, summed over its steps):");
    println!(
        "| config | critic: crops + fakes | critic: weights in | critic: loss, penalty, gradients | critic: Adam | generator: fakes + critic | generator: backward | generator: Adam |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, t) in splits {
        println!(
            "| {name} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |",
            t.critic_data,
            t.critic_forward,
            t.critic_backward,
            t.critic_update,
            t.generator_forward,
            t.generator_backward,
            t.generator_update
        );
    }
}
