//! Training speed: one iteration (5 critic + 5 generator steps, batch 4, crop 128) on flex,
//! beside the authors' PyTorch code on the same 2-core machine (40.6 s, measured separately:
//! DESIGN.md §3; not re-run here).
//!
//! `cargo bench --bench train` prints the median of `IPFN_BENCH_RUNS` iterations (default 3)
//! and a split into critic and generator steps (from runs with 5+1 and 1+5 steps).

use std::time::Instant;

use burn::prelude::*;
use ipfn::train::{TrainConfig, Trainer};

const AUTHORS_ITERATION_S: f64 = 40.6;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn time_iteration(
    exemplar: &std::path::Path,
    critic_steps: usize,
    generator_steps: usize,
    runs: usize,
) -> (f64, ipfn::train::StepTimes) {
    let dir = tempfile::tempdir().unwrap();
    let base = match std::env::var("IPFN_BENCH_CONFIG") {
        Ok(path) => {
            TrainConfig::from_file(std::path::Path::new(&path))
                .unwrap()
                .0
        }
        Err(_) => TrainConfig {
            batch: 4,
            crop: 128,
            ..TrainConfig::default()
        },
    };
    let config = TrainConfig {
        critic_steps,
        generator_steps,
        ..base
    };
    let mut trainer = Trainer::new(config, exemplar, dir.path(), &Device::flex()).unwrap();
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
    let exemplar = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars/honeycomb.png");
    let (full, t) = time_iteration(&exemplar, 5, 5, runs);
    println!(
        "training on flex ({} threads), batch 4, crop 128, honeycomb exemplar, median of {runs}",
        rayon::current_num_threads()
    );
    println!("| work | ours | authors' code | authors / ours |");
    println!("|---|---|---|---|");
    println!(
        "| one iteration (5 critic + 5 generator steps) | {full:.2} s | {AUTHORS_ITERATION_S:.1} s (reference) | {:.1}x |",
        AUTHORS_ITERATION_S / full
    );
    println!();
    println!("where the last iteration's time went (seconds, summed over its steps):");
    println!(
        "| critic: crops + fakes | critic: forward + penalty | critic: backward | critic: Adam | generator: forward (G + D) | generator: backward | generator: Adam |"
    );
    println!("|---|---|---|---|---|---|---|");
    println!(
        "| {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
        t.critic_data,
        t.critic_forward,
        t.critic_backward,
        t.critic_update,
        t.generator_forward,
        t.generator_backward,
        t.generator_update
    );
}
