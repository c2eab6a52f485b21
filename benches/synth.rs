//! Synthesis speed on the CPU, beside floors measured in the same run.
//!
//! `cargo bench --bench synth` prints, for 256², 512² and 1024²:
//! - ours: `Painter::render` with the fused CPU evaluator (encoding, latent field and MLP);
//! - burn floor: the same MLP as a chain of plain burn-flex matmuls + ReLU with identical FLOPs
//!   (chunks of 4,096 points, random inputs), the floor named by the design notes;
//! - GEMM floor: the same FLOPs as bare `gemm` calls on all cores (no encoding, no latent, no
//!   bias), the most the matrix products alone can do here;
//! - the authors' PyTorch code (21.9 s for 1024² on the 2-core reference machine: measured
//!   separately, see the book's performance page; not re-run here).
//!
//! A second table times 1, 3 and 9 output channels (a material map set) at the largest size.
//!
//! Medians of `IPFN_BENCH_RUNS` runs (default 3). `IPFN_BENCH_SIZES=256,512` limits the sizes.

use ipfn::bench::{gemm_floor, matmul_floor, time};
use ipfn::checkpoint::Checkpoint;
use ipfn::device::DeviceChoice;
use ipfn::generator::GeneratorWeights;
use ipfn::synth::Synth;

const AUTHORS_1024_S: f64 = ipfn::bench::AUTHORS_SYNTH_1024_S;

fn main() {
    let runs: usize = std::env::var("IPFN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let sizes: Vec<usize> = std::env::var("IPFN_BENCH_SIZES")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![256, 512, 1024]);
    let shipped = Checkpoint::from_bytes(
        ipfn::model::SHIPPED_HONEYCOMB,
        std::path::Path::new("shipped"),
    )
    .unwrap();
    let (config, weights) = GeneratorWeights::read_from(&shipped).unwrap();
    let shapes = config.layer_shapes();
    let base_config = config.clone();
    let flop_per_point = 2.0 * config.macs_per_point() as f64;
    let painter = Synth::new(config, weights)
        .seed(1)
        .device(DeviceChoice::Cpu)
        .painter()
        .unwrap();

    println!(
        "synth on CPU ({} threads), honeycomb generator (10x128 MLP), median of {runs} runs",
        rayon::current_num_threads()
    );
    println!(
        "| size | ours | burn floor | ours / burn floor | GEMM floor | ours / GEMM floor | ours GFLOP/s | authors' code | authors / ours |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for &n in &sizes {
        let points = n * n;
        let gflop = flop_per_point * points as f64 / 1e9;
        let ours = time(runs, || {
            std::hint::black_box(painter.render(&[0, 0], &[n, n]));
        });
        let burn = time(runs, || {
            matmul_floor(&shapes, points, 4096, &burn::prelude::Device::flex())
        });
        let gemm = time(runs, || gemm_floor(&shapes, points));
        let authors = if n == 1024 {
            format!("{AUTHORS_1024_S:.1} s (reference)")
        } else {
            "-".into()
        };
        let speedup = if n == 1024 {
            format!("{:.1}x", AUTHORS_1024_S / ours)
        } else {
            "-".into()
        };
        println!(
            "| {n}² | {ours:.3} s | {burn:.3} s ({:.0} GFLOP/s) | {:.2} | {gemm:.3} s ({:.0} GFLOP/s) | {:.2} | {:.0} | {authors} | {speedup} |",
            gflop / burn,
            ours / burn,
            gflop / gemm,
            ours / gemm,
            gflop / ours
        );
    }

    // Channels: a map set paints more channels with the same MLP; only the last layer grows.
    // Same architecture, random weights, 1, 3 and 9 output channels (3 is the honeycomb's shape).
    let n = *sizes.last().unwrap_or(&1024);
    println!();
    println!("channels at {n}² (same 10x128 MLP, random weights), median of {runs} runs");
    println!("| channels | ours | / 3 channels | MACs per point | / 3 channels |");
    println!("|---|---|---|---|---|");
    let time_channels = |channels: usize| {
        let config = ipfn::generator::GeneratorConfig {
            channels,
            ..base_config.clone()
        };
        let macs = config.macs_per_point();
        let painter = Synth::new(config.clone(), GeneratorWeights::random(&config, 0))
            .seed(1)
            .device(DeviceChoice::Cpu)
            .painter()
            .unwrap();
        let t = time(runs, || {
            std::hint::black_box(painter.render(&[0, 0], &[n, n]));
        });
        (t, macs)
    };
    let (t3, m3) = time_channels(3);
    for channels in [1, 3, 9] {
        let (t, m) = if channels == 3 {
            (t3, m3)
        } else {
            time_channels(channels)
        };
        println!(
            "| {channels} | {t:.3} s | {:.3} | {m} | {:.3} |",
            t / t3,
            m as f64 / m3 as f64
        );
    }
}
