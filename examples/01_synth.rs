//! The guide's "`ipfn synth`: paint a sample" (docs/guide/synth.md), as library calls.
//!
//! `cargo run --release --example 01_synth` writes `01_synth.png` (a 512x512 seamless tile)
//! with the shipped honeycomb model. The `Synth` builder's methods mirror `ipfn synth`'s flags.

use std::path::Path;

use ipfn::checkpoint::Checkpoint;
use ipfn::device::DeviceChoice;
use ipfn::generator::GeneratorWeights;
use ipfn::io::OutputFormat;
use ipfn::synth::{DEFAULT_BAND_PIXELS, Synth};

fn main() -> ipfn::Result<()> {
    let model =
        Checkpoint::from_bytes(ipfn::model::SHIPPED_HONEYCOMB, Path::new("honeycomb.ipfn"))?;
    let (config, weights) = GeneratorWeights::read_from(&model)?;
    let painter = Synth::new(config, weights)
        .seed(7) // --seed 7
        .tile(&[512, 512]) // --tile (at the output size)
        .device(DeviceChoice::Cpu) // --device cpu
        .painter()?;
    if let Some(adjustment) = painter.tile_adjustment() {
        println!("{}", adjustment.describe());
    }
    let out = Path::new("01_synth.png");
    painter.write_image(
        out,
        OutputFormat::Png { bits: 8 },
        [512, 512],
        DEFAULT_BAND_PIXELS,
        |_| {},
    )?;
    println!("wrote {}", out.display());
    Ok(())
}
