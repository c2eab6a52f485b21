//! The generator kernel (`generator::kernel`, one CubeCL kernel per launch) paints what the
//! fused CPU evaluator and burn's generator paint, on wgpu (lavapipe in CI): for the authors'
//! honeycomb model and for small 3D guided models whose widths are not multiples of 16, across
//! launch boundaries.
#![cfg(feature = "wgpu")]

use crate::common::{honeycomb, max_abs_diff};
use ipfn::device::DeviceChoice;
use ipfn::generator::fused::{FusedGenerator, Scratch};
use ipfn::generator::kernel::KernelGenerator;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::latent::LatentField;
use ipfn::synth::Synth;

fn wgpu() -> burn::tensor::Device {
    DeviceChoice::Wgpu.burn_device().unwrap().unwrap()
}

/// The fused CPU evaluator on the grid `axes[0] x axes[1] (x axes[2])`.
fn cpu_render(
    weights: &GeneratorWeights,
    field: &LatentField,
    latent_scale: &[f32],
    axes: &[Vec<f32>],
    guide: &[f32],
) -> Vec<f32> {
    let mut points = vec![Vec::new()];
    for axis in axes {
        points = points
            .into_iter()
            .flat_map(|p| {
                axis.iter().map(move |&v| {
                    let mut p = p.clone();
                    p.push(v);
                    p
                })
            })
            .collect();
    }
    let channels = weights.layers.last().unwrap().outputs;
    let mut out = vec![0f32; points.len() * channels];
    FusedGenerator::new(weights.clone()).eval(
        &points.concat(),
        field,
        latent_scale,
        guide,
        &mut out,
        &mut Scratch::default(),
    );
    out
}

#[test]
#[ignore = "needs a wgpu adapter (CI: lavapipe); run by `cargo test --release -- --ignored`"]
fn wgpu_synthesis_paints_with_the_kernel_and_agrees_with_burn_and_cpu() {
    wgpu();
    let (config, weights) = honeycomb();
    let painter = |device, kernel| {
        Synth::new(config.clone(), weights.clone())
            .seed(3)
            .offset(&[40, -17])
            .device(device)
            .gpu_kernel(kernel)
            .painter()
            .unwrap()
    };
    let kernel = painter(DeviceChoice::Wgpu, true);
    let burn = painter(DeviceChoice::Wgpu, false);
    assert_eq!(kernel.engine(), "kernel", "wgpu paints with the kernel");
    assert_eq!(burn.engine(), "burn");
    let cpu = painter(DeviceChoice::Cpu, true).render(&[0, 0], &[45, 61]);
    let by_kernel = kernel.render(&[0, 0], &[45, 61]);
    let by_burn = burn.render(&[0, 0], &[45, 61]);
    let (to_cpu, to_burn) = (
        max_abs_diff(&by_kernel, &cpu),
        max_abs_diff(&by_kernel, &by_burn),
    );
    eprintln!("honeycomb: kernel vs cpu {to_cpu:.2e}, kernel vs burn {to_burn:.2e}");
    assert!(to_cpu < 1e-4, "kernel differs from the CPU by {to_cpu}");
    assert!(to_burn < 1e-4, "kernel differs from burn by {to_burn}");
}

/// A 3D guided model 40 units wide (padded to 48 in the kernel), 3 octaves, 4 latent channels,
/// on a periodic latent field: the kernel agrees with the CPU, whatever the launch size.
#[test]
#[ignore = "needs a wgpu adapter (CI: lavapipe); run by `cargo test --release -- --ignored`"]
fn the_kernel_agrees_with_the_cpu_on_3d_guided_models_across_launches() {
    let device = wgpu();
    let config = GeneratorConfig::new()
        .with_dims(3)
        .with_channels(2)
        .with_octaves(3)
        .with_latent_dim(4)
        .with_hidden_layers(3)
        .with_width(40)
        .with_guidance(1);
    let weights = GeneratorWeights::random(&config, 0);
    let field = LatentField::hashed(9, 3, 4)
        .with_sigma(0.3)
        .periodic(&[3, 4, 5]);
    let latent_scale = [0.7f32, 0.5, 0.45];
    let axes: Vec<Vec<f32>> = [(5, -3.1f32), (7, 0.4), (9, 2.0)]
        .iter()
        .map(|&(n, o)| (0..n).map(|i| o + 0.37 * i as f32).collect())
        .collect();
    let total = 5 * 7 * 9;
    let guide: Vec<f32> = (0..total).map(|i| (i as f32 * 0.37).sin()).collect();
    let cpu = cpu_render(&weights, &field, &latent_scale, &axes, &guide);
    for launch_points in [total, 100, 33] {
        let kernel = KernelGenerator::new(&weights, &device)
            .expect("the model fits the kernel")
            .with_launch_points(launch_points);
        let ours = kernel.render(&field, &latent_scale, &axes, |start, count| {
            guide[start..start + count].to_vec()
        });
        let diff = max_abs_diff(&ours, &cpu);
        eprintln!("3D guided, {launch_points} points per launch: kernel vs cpu {diff:.2e}");
        assert!(
            diff < 1e-5,
            "{launch_points} points per launch: kernel differs from the CPU by {diff}"
        );
    }
}
