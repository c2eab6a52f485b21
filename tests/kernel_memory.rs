//! The generator kernel's device memory is bounded by one launch, not by the size of what it
//! paints (the target: peak memory under 512 MiB at any size). A test binary of its own, so no
//! other test allocates on the device while this one reads the device's memory report.
#![cfg(feature = "wgpu")]

use ipfn::device::DeviceChoice;
use ipfn::generator::kernel::KernelGenerator;
use ipfn::generator::{GeneratorConfig, GeneratorWeights};
use ipfn::latent::LatentField;

#[test]
#[ignore = "needs a wgpu adapter (CI: lavapipe); run by `cargo test --release -- --ignored`"]
fn kernel_device_memory_is_bounded_by_the_launch_not_the_image() {
    let device = DeviceChoice::Wgpu.burn_device().unwrap().unwrap();
    // A small RGB model, so that lavapipe paints 384² in about a second.
    let config = GeneratorConfig::new().with_hidden_layers(3).with_width(32);
    let weights = GeneratorWeights::random(&config, 0);
    let field = LatentField::hashed(5, 2, config.latent_dim);
    let side = 384;
    let axes: Vec<Vec<f32>> = (0..2)
        .map(|_| (0..side).map(|i| -3.0 + 0.02 * i as f32).collect())
        .collect();
    let output_bytes = (side * side * config.channels * 4) as u64;
    let launch = 2048;

    let kernel = KernelGenerator::new(&weights, &device)
        .expect("the model fits the kernel")
        .with_launch_points(launch);
    let chunked = kernel.render(&field, &[1.0, 1.0], &axes, |_, _| Vec::new());
    assert_eq!(chunked.len(), side * side * config.channels);
    let largest = kernel.largest_device_allocation();
    eprintln!(
        "{side}² in launches of {launch} points: largest device allocation {largest} bytes, \
         output {output_bytes} bytes"
    );
    // One launch's output is 24 KiB and the weights 15 KiB; the whole output is 1.7 MiB.
    assert!(
        largest * 16 <= output_bytes,
        "a {largest}-byte device buffer for a {output_bytes}-byte image painted in \
         {launch}-point launches: something is sized by the image, not the launch"
    );

    // The same measure sees a buffer sized by the image when one launch paints it all.
    let whole = KernelGenerator::new(&weights, &device)
        .unwrap()
        .with_launch_points(side * side);
    assert_eq!(
        whole.render(&field, &[1.0, 1.0], &axes, |_, _| Vec::new()),
        chunked
    );
    let largest = whole.largest_device_allocation();
    assert!(
        largest >= output_bytes,
        "one launch for the whole image allocated at most {largest} bytes, less than its \
         {output_bytes}-byte output: the memory report does not see the kernel's buffers"
    );
}
