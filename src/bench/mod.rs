//! Speed on the machine at hand (`ipfn bench`), beside floors measured in the same run.
//!
//! - synth: `Painter::render` of the shipped honeycomb generator (10x128 MLP) at each size, on
//!   each device asked for;
//! - floors, same FLOPs as the MLP, measured now:
//!   - *GEMM floor* (CPU): bare single-threaded `gemm` calls per 512-point chunk on all cores,
//!     with no encoding, latent field or bias: the most the matrix products alone can do;
//!   - *matmul floor* (a burn device): a chain of plain burn matmuls + ReLU on that device, in
//!     the chunks our burn path uses there (4,096 points on flex, 65,536 on a GPU): what the
//!     framework's own kernels do for these shapes;
//! - training: one iteration (5 critic + 5 generator steps, batch 4 (or `batches`), crop 128, a
//!   256² RGB exemplar), after one warm-up iteration, beside a floor measured now: on the CPU
//!   both networks' products as bare GEMMs ([`floor`]); on GPUs the generator's FLOPs of the
//!   iteration (20 MLP passes over the batch's crops) as the matmul floor; and the authors'
//!   PyTorch code measured on the 2-core
//!   reference machine or, on a GPU, on one H100, not re-run here (the book's performance
//!   page has both measurements);
//! - volumes (`volumes`): cubes painted in slabs by a 3D generator of the paper's size, beside
//!   the same floors and the paper's 22.9 s for 512³.
//!
//! The benches in `benches/` print the same figures in more detail.

pub mod floor;

use std::time::Instant;

use burn::prelude::*;
use burn::tensor::activation::relu;
use rayon::prelude::*;

use crate::device::DeviceChoice;
use crate::error::Result;
use crate::generator::fused::matmul_into;
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
pub use crate::model::shipped_model;
use crate::synth::Synth;
use crate::train::{TrainConfig, Trainer};

/// The authors' PyTorch code on the 2-core reference machine: synth 1024².
pub const AUTHORS_SYNTH_1024_S: f64 = 21.9;
/// The authors' PyTorch code on the 2-core reference machine: one training iteration, batch 4.
pub const AUTHORS_ITERATION_S: f64 = 40.6;
/// The authors' PyTorch code (PyTorch 2.11) on one H100: synth at
/// 1024² and 2048², and one training iteration at batch 4 and 8.
pub const AUTHORS_H100_SYNTH_S: [(usize, f64); 2] = [(1024, 0.0143), (2048, 0.0527)];
pub const AUTHORS_H100_ITERATION_S: [(usize, f64); 2] = [(4, 0.105), (8, 0.145)];
/// The paper's 512³ volume synthesis (on a GPU, as reported; not re-run).
pub const PAPER_VOLUME_512_S: f64 = 22.9;

/// Median of `runs` timed calls after one warm-up call.
pub fn time(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut v: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The MLP's FLOPs as a chain of plain burn matmuls + ReLU on `device`, over `points` points in
/// chunks of `chunk` (random inputs; the result is read back so the device has finished).
pub fn matmul_floor(shapes: &[(usize, usize)], points: usize, chunk: usize, device: &Device) {
    let chunk = chunk.min(points);
    let uniform = burn::tensor::Distribution::Uniform(-0.1, 0.1);
    let weights: Vec<Tensor<2>> = shapes
        .iter()
        .map(|&(i, o)| Tensor::random([i, o], uniform, device))
        .collect();
    let x0 = Tensor::<2>::random([chunk, shapes[0].0], uniform, device);
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

/// The MLP's FLOPs as bare single-threaded GEMMs per 512-point chunk, chunks on all cores.
pub fn gemm_floor(shapes: &[(usize, usize)], points: usize) {
    let chunk = 512;
    let widest = shapes.iter().map(|&(i, o)| i.max(o)).max().unwrap_or(1);
    let weights: Vec<Vec<f32>> = shapes.iter().map(|&(i, o)| vec![0.01; i * o]).collect();
    (0..points.div_ceil(chunk)).into_par_iter().for_each_init(
        || (vec![0.5f32; chunk * widest], vec![0f32; chunk * widest]),
        |(a, b), _| {
            for (w, &(k, n)) in weights.iter().zip(shapes) {
                matmul_into(b, a, w, chunk, n, k);
                std::mem::swap(a, b);
            }
        },
    );
}

/// The floor beside a synthesis row on `device`, timed now over `points` points: its name and
/// median time. The GEMM floor on the fused CPU evaluator, the matmul floor on a burn device.
fn floor(
    device: DeviceChoice,
    burn_device: Option<&Device>,
    shapes: &[(usize, usize)],
    points: usize,
    runs: usize,
) -> (String, f64) {
    match burn_device {
        None => (
            "GEMM floor".into(),
            time(runs, || gemm_floor(shapes, points)),
        ),
        Some(d) => (
            "matmul floor".into(),
            time(runs, || {
                matmul_floor(shapes, points, device.chunk_points(), d)
            }),
        ),
    }
}

/// One row of the table.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    pub work: String,
    pub device: String,
    pub ours_s: f64,
    pub floor: String,
    pub floor_s: Option<f64>,
}

impl Row {
    /// A published figure that is not re-run here, and how it compares with ours.
    fn reference(work: impl Into<String>, who: &str, seconds: f64, compared: String) -> Self {
        Row {
            work: work.into(),
            device: who.into(),
            ours_s: seconds,
            floor: compared,
            floor_s: None,
        }
    }

    pub fn markdown(&self) -> String {
        let (floor, ratio) = match self.floor_s {
            Some(f) => (
                format!("{} {f:.3} s", self.floor),
                format!("{:.2}", self.ours_s / f),
            ),
            None => (self.floor.clone(), "-".into()),
        };
        format!(
            "| {} | {} | {:.3} s | {floor} | {ratio} |",
            self.work, self.device, self.ours_s
        )
    }
}

/// What to measure.
#[derive(Debug, Clone)]
pub struct BenchPlan {
    pub sizes: Vec<usize>,
    pub devices: Vec<DeviceChoice>,
    pub runs: usize,
    /// Also time one training iteration on each device that trains (flex, wgpu, cuda).
    pub train: bool,
    /// Batch sizes of the training iterations.
    pub batches: Vec<usize>,
    /// Also paint cubes of these sides with a 3D generator of the paper's size (random weights).
    pub volumes: Vec<usize>,
}

/// `ipfn bench` as a request: the flags as given, checked once into a [`BenchPlan`].
#[derive(Debug, Clone)]
pub struct BenchRequest {
    pub sizes: Vec<usize>,
    /// Devices by name; `None`: the CPU engines and every GPU that starts (not a software
    /// adapter, which is slow: it is timed only when named).
    pub devices: Option<Vec<String>>,
    pub runs: usize,
    pub train: bool,
    pub batches: Vec<usize>,
    pub volumes: Vec<usize>,
}

impl BenchRequest {
    /// The plan, and a line for each device looked for and skipped.
    pub fn plan(&self) -> Result<(BenchPlan, Vec<String>)> {
        if self.sizes.contains(&0) || self.volumes.contains(&0) {
            return Err(input_error!("--sizes/--volumes: sizes must be at least 1"));
        }
        if self.batches.contains(&0) {
            return Err(input_error!("--batches: batch sizes must be at least 1"));
        }
        if self.runs == 0 {
            return Err(crate::setting_error!("--runs", 0, "need at least one run"));
        }
        let (devices, skipped) = match &self.devices {
            Some(names) => (named_devices(names)?, Vec::new()),
            None => found_devices(),
        };
        let plan = BenchPlan {
            sizes: self.sizes.clone(),
            devices,
            runs: self.runs,
            train: self.train,
            batches: self.batches.clone(),
            volumes: self.volumes.clone(),
        };
        Ok((plan, skipped))
    }
}

/// Devices named by the user, each started now so that one missing fails with its own message.
fn named_devices(names: &[String]) -> Result<Vec<DeviceChoice>> {
    names
        .iter()
        .map(|n| {
            let d: DeviceChoice = n.parse()?;
            d.burn_device()?;
            Ok(d)
        })
        .collect()
}

/// The CPU engines and the GPUs that start, with a line for each GPU skipped.
fn found_devices() -> (Vec<DeviceChoice>, Vec<String>) {
    let (mut found, mut skipped) = (vec![DeviceChoice::Cpu, DeviceChoice::Flex], Vec::new());
    for gpu in [DeviceChoice::Wgpu, DeviceChoice::Cuda] {
        match gpu.burn_device() {
            Ok(_) if gpu == DeviceChoice::Wgpu && crate::device::wgpu_is_software() => skipped
                .push(
                "wgpu: software adapter only (no GPU); skipped, name it in --devices to time it"
                    .into(),
            ),
            Ok(_) => found.push(gpu),
            Err(e) => skipped.push(format!("{}: skipped ({e})", device_name(gpu))),
        }
    }
    (found, skipped)
}

/// The GPU engines to time on `device`: ipfn's generator kernel and burn's generator on GPUs
/// (`[true, false]`), one engine elsewhere.
fn engines(device: DeviceChoice) -> Vec<bool> {
    if is_gpu(device) {
        vec![true, false]
    } else {
        vec![true]
    }
}

/// The device column: the device, and on GPUs which engine painted.
fn engine_name(device: DeviceChoice, engine: &str) -> String {
    if is_gpu(device) {
        format!("{}, {engine}", device_name(device))
    } else {
        device_name(device)
    }
}

fn is_gpu(device: DeviceChoice) -> bool {
    matches!(device, DeviceChoice::Wgpu | DeviceChoice::Cuda)
}

/// Runs the plan, calling `row` as each row is measured.
pub fn run(plan: &BenchPlan, mut row: impl FnMut(&Row)) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let mut emit = |r: Row| {
        row(&r);
        rows.push(r);
    };
    synth_rows(plan, &mut emit)?;
    if !plan.volumes.is_empty() {
        volume_rows(plan, &mut emit)?;
    }
    if plan.train {
        train_rows(plan, &mut emit)?;
    }
    Ok(rows)
}

/// One engine that bench rows time: a model's painter on one device, the rows' device name,
/// and the burn device its floor runs on (none on the fused CPU path).
struct Engine {
    device: DeviceChoice,
    name: String,
    painter: crate::synth::Painter,
    burn_device: Option<Device>,
    shapes: Vec<(usize, usize)>,
}

impl Engine {
    /// The row of `work`, which took `ours` seconds over `points` points, beside the floor for
    /// as many points, timed now.
    fn row(&self, work: String, ours: f64, points: usize, runs: usize) -> Row {
        let burn_device = self.burn_device.as_ref();
        let (floor, floor_s) = floor(self.device, burn_device, &self.shapes, points, runs);
        Row {
            work,
            device: self.name.clone(),
            ours_s: ours,
            floor,
            floor_s: Some(floor_s),
        }
    }
}

/// Calls `f` with the model's painter on every device of the plan and each of its engines, one
/// painter at a time.
fn for_each_engine(
    plan: &BenchPlan,
    config: &GeneratorConfig,
    weights: &GeneratorWeights,
    mut f: impl FnMut(&Engine) -> Result<()>,
) -> Result<()> {
    for &device in &plan.devices {
        let burn_device = device.burn_device()?;
        for kernel in engines(device) {
            let painter = Synth::new(config.clone(), weights.clone())
                .seed(1)
                .device(device)
                .gpu_kernel(kernel)
                .painter()?;
            f(&Engine {
                device,
                name: engine_name(device, painter.engine()),
                painter,
                burn_device: burn_device.clone(),
                shapes: config.layer_shapes(),
            })?;
        }
    }
    Ok(())
}

/// Images of `plan.sizes` with the shipped model on every device and engine.
fn synth_rows(plan: &BenchPlan, emit: &mut impl FnMut(Row)) -> Result<()> {
    let (config, weights) = shipped_model()?;
    for_each_engine(plan, &config, &weights, |engine| {
        for &n in &plan.sizes {
            let ours = time(plan.runs, || {
                std::hint::black_box(engine.painter.render(&[0, 0], &[n, n]));
            });
            emit(engine.row(format!("synth {n}²"), ours, n * n, plan.runs));
            if let Some(&(_, authors)) = AUTHORS_H100_SYNTH_S.iter().find(|(s, _)| *s == n)
                && is_gpu(engine.device)
            {
                emit(Row::reference(
                    format!("synth {n}²"),
                    "authors' PyTorch on one H100 (not re-run)",
                    authors,
                    format!("ours is {:.2}x its time", ours / authors),
                ));
            }
            if n == 1024 && engine.device == DeviceChoice::Cpu {
                emit(Row::reference(
                    "synth 1024²",
                    "authors' PyTorch (reference machine, not re-run)",
                    AUTHORS_SYNTH_1024_S,
                    format!("{:.1}x slower than ours", AUTHORS_SYNTH_1024_S / ours),
                ));
            }
        }
        Ok(())
    })
}

/// Cubes of `plan.volumes` with a 3D generator of the paper's size (random weights).
fn volume_rows(plan: &BenchPlan, emit: &mut impl FnMut(Row)) -> Result<()> {
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(1)
        .with_crop(64);
    let weights = GeneratorWeights::random(&config, 0);
    let runs = plan.runs.min(2);
    for_each_engine(plan, &config, &weights, |engine| {
        for &n in &plan.volumes {
            // Slabs of about a million voxels, as `ipfn synth --depth` renders them.
            let slab = (crate::synth::DEFAULT_BAND_PIXELS).div_ceil(n * n).max(1);
            let ours = time(runs, || {
                let mut z = 0;
                while z < n {
                    let d = slab.min(n - z);
                    std::hint::black_box(engine.painter.render(&[z as i64, 0, 0], &[d, n, n]));
                    z += d;
                }
            });
            let work = format!("volume {n}³ (3D 10x128 MLP)");
            emit(engine.row(work, ours, n * n * n, runs));
            if n == 512 {
                emit(Row::reference(
                    "volume 512³",
                    "paper (GPU, reported)",
                    PAPER_VOLUME_512_S,
                    format!("ours is {:.2}x its time", ours / PAPER_VOLUME_512_S),
                ));
            }
        }
        Ok(())
    })
}

/// One training iteration per batch size on every device that trains.
fn train_rows(plan: &BenchPlan, emit: &mut impl FnMut(Row)) -> Result<()> {
    let exemplar = tempfile::Builder::new()
        .suffix(".png")
        .tempfile()
        .map_err(|e| crate::Error::Runtime(format!("temp file: {e}")))?;
    // A 256x256 RGB exemplar (the speed does not depend on what it shows).
    let bricks: Vec<f32> = crate::procedural::bricks(256, 256, 32, 16)
        .iter()
        .map(|v| v * 2.0 - 1.0)
        .collect();
    crate::io::write_png(exemplar.path(), 256, 256, 3, &bricks)?;
    for &device in &plan.devices {
        let Some(burn_device) = device.burn_device()? else {
            continue; // the fused CPU evaluator has no backward; flex trains on the CPU
        };
        for &batch in &plan.batches {
            let run_dir =
                tempfile::tempdir().map_err(|e| crate::Error::Runtime(format!("temp dir: {e}")))?;
            let config = TrainConfig {
                batch,
                crop: 128,
                ..TrainConfig::default()
            };
            let mut trainer = Trainer::new(
                config.clone(),
                exemplar.path(),
                run_dir.path(),
                &burn_device,
            )?;
            let ours = time(plan.runs.min(2), || {
                trainer.step();
            });
            let work = format!("train iteration (batch {batch}, crop 128)");
            let (floor, floor_s) = if is_gpu(device) {
                // The generator's share of the iteration's FLOPs: one forward pass per critic
                // step, and per generator step a forward and a backward (input and weight
                // gradients, two more passes' worth). The critic's convolutions are not in it.
                let passes = config.critic_steps + 3 * config.generator_steps;
                let points = passes * batch * config.crop * config.crop;
                let shapes = config
                    .generator_config(&config.run_kind()?, 3)
                    .layer_shapes();
                let (name, t) = self::floor(device, Some(&burn_device), &shapes, points, 2);
                (
                    format!("generator {name} ({passes} MLP passes, no critic)"),
                    t,
                )
            } else {
                let products = floor::iteration_products(&config, &config.run_kind()?, 3);
                let t = time(plan.runs.min(2), floor::run_products(&products));
                let gflop = floor::flops(&products) / 1e9;
                (format!("GEMM floor of both networks ({gflop:.0} GFLOP)"), t)
            };
            emit(Row {
                work: work.clone(),
                device: device_name(device),
                ours_s: ours,
                floor,
                floor_s: Some(floor_s),
            });
            let reference = if is_gpu(device) {
                AUTHORS_H100_ITERATION_S
                    .iter()
                    .find(|(b, _)| *b == batch)
                    .map(|&(_, t)| ("authors' PyTorch on one H100 (not re-run)", t))
            } else {
                (batch == 4).then_some((
                    "authors' PyTorch (reference machine, not re-run)",
                    AUTHORS_ITERATION_S,
                ))
            };
            if let Some((who, t)) = reference {
                emit(Row::reference(
                    work,
                    who,
                    t,
                    format!("{:.1}x ours", t / ours),
                ));
            }
        }
    }
    Ok(())
}

pub fn device_name(device: DeviceChoice) -> String {
    format!("{device:?}").to_ascii_lowercase()
}

/// One line about this machine: CPU model and threads.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!("{cpu}, {} threads", rayon::current_num_threads())
}
