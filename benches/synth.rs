//! Synthesis speed on the CPU, beside floors measured in the same run.
//!
//! `cargo bench --bench synth` prints, for 256², 512² and 1024²:
//! - ours: `Painter::render` with the fused CPU evaluator (encoding, latent field and MLP);
//! - burn floor: the same MLP as a chain of plain burn-flex matmuls + ReLU with identical FLOPs
//!   (chunks of 4096 points, random inputs), the floor named by the design notes;
//! - GEMM floor: the same FLOPs as bare `gemm` calls on all cores (no encoding, no latent, no
//!   bias), the most the matrix products alone can do here;
//! - the authors' PyTorch code (21.9 s for 1024² on the 2-core reference machine: measured
//!   separately, see DESIGN.md; not re-run here).
//!
//! Medians of `IPFN_BENCH_RUNS` runs (default 3). `IPFN_BENCH_SIZES=256,512` limits the sizes.

use std::time::Instant;

use burn::prelude::*;
use burn::tensor::activation::relu;
use ipfn::checkpoint::Checkpoint;
use ipfn::generator::GeneratorWeights;
use ipfn::synth::{DeviceChoice, Synth};
use rayon::prelude::*;

const AUTHORS_1024_S: f64 = 21.9;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn time(runs: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm-up
    median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

/// The MLP as plain burn matmuls + ReLU on flex over `points` points, chunks of 4096.
fn burn_floor(shapes: &[(usize, usize)], points: usize) {
    let device = Device::flex();
    let chunk = 4096;
    let weights: Vec<Tensor<2>> = shapes
        .iter()
        .map(|&(i, o)| {
            Tensor::random(
                [i, o],
                burn::tensor::Distribution::Uniform(-0.1, 0.1),
                &device,
            )
        })
        .collect();
    let x0 = Tensor::<2>::random(
        [chunk, shapes[0].0],
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        &device,
    );
    let mut done = 0;
    while done < points {
        let mut x = x0.clone();
        for w in &weights {
            x = relu(x.matmul(w.clone()));
        }
        let _ = x.into_data();
        done += chunk;
    }
}

/// The same FLOPs as bare single-threaded GEMMs per 512-point chunk, chunks spread on all cores.
fn gemm_floor(shapes: &[(usize, usize)], points: usize) {
    let chunk = 512;
    let widest = shapes.iter().map(|&(i, o)| i.max(o)).max().unwrap();
    let weights: Vec<Vec<f32>> = shapes.iter().map(|&(i, o)| vec![0.01; i * o]).collect();
    (0..points.div_ceil(chunk)).into_par_iter().for_each_init(
        || (vec![0.5f32; chunk * widest], vec![0f32; chunk * widest]),
        |(a, b), _| {
            for (w, &(k, n)) in weights.iter().zip(shapes) {
                unsafe {
                    gemm::gemm(
                        chunk,
                        n,
                        k,
                        b.as_mut_ptr(),
                        1,
                        n as isize,
                        false,
                        a.as_ptr(),
                        1,
                        k as isize,
                        w.as_ptr(),
                        1,
                        n as isize,
                        0.0,
                        1.0,
                        false,
                        false,
                        false,
                        gemm::Parallelism::None,
                    );
                }
                std::mem::swap(a, b);
            }
        },
    );
}

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
        ipfn::cli::SHIPPED_HONEYCOMB,
        std::path::Path::new("shipped"),
    )
    .unwrap();
    let (config, weights) = GeneratorWeights::read_from(&shipped).unwrap();
    let shapes = config.layer_shapes();
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
            std::hint::black_box(painter.render(0, 0, n, n));
        });
        let burn = time(runs, || burn_floor(&shapes, points));
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
}
