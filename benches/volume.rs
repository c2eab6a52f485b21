//! Volume synthesis speed on the CPU: a 3D generator of the paper's size (10 hidden layers of
//! 128, 3 coordinates, 1 channel) painting cubes in slabs, beside the GEMM floor for the same
//! FLOPs measured in the same run, and the paper's 22.9 s for 512³ (on a GPU, as reported;
//! not re-run).
//!
//! `cargo bench --bench volume`; `IPFN_BENCH_SIDES=128,256,512` chooses the cube sides (default
//! 128,256), `IPFN_BENCH_RUNS` the runs per figure (default 1).

use ipfn::bench::{gemm_floor, time};
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::synth::Synth;

const PAPER_512_S: f64 = 22.9;

fn main() {
    let runs: usize = std::env::var("IPFN_BENCH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let sides: Vec<usize> = std::env::var("IPFN_BENCH_SIDES")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![128, 256]);
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_crop(64);
    let shapes = config.layer_shapes();
    let flop_per_point = 2.0 * config.macs_per_point() as f64;
    let painter = Synth::new(config.clone(), GeneratorWeights::random(&config, 0))
        .seed(1)
        .painter()
        .unwrap();
    println!(
        "volume synth on CPU ({} threads), 3D generator 10x128 (input {}), median of {runs} runs",
        rayon::current_num_threads(),
        config.input_width()
    );
    println!(
        "| side | voxels | ours | GEMM floor | ours / floor | ours GFLOP/s | paper (GPU, 512³) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for &n in &sides {
        let voxels = n * n * n;
        // Slabs of about a million voxels, as `ipfn synth --depth` writes them.
        let slab = (1usize << 20).div_ceil(n * n).max(1);
        let ours = time(runs, || {
            let mut z = 0;
            while z < n {
                let d = slab.min(n - z);
                std::hint::black_box(painter.render(&[z as i64, 0, 0], &[d, n, n]));
                z += d;
            }
        });
        let floor = time(runs, || gemm_floor(&shapes, voxels));
        let paper = if n == 512 {
            format!("{PAPER_512_S} s (reported)")
        } else {
            "-".into()
        };
        println!(
            "| {n}³ | {voxels} | {ours:.2} s | {floor:.2} s | {:.2} | {:.0} | {paper} |",
            ours / floor,
            flop_per_point * voxels as f64 / ours / 1e9
        );
    }
}
