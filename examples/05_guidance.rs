//! The guide's "Directional guidance" (docs/guide/train.md), as library calls.
//!
//! `cargo run --release --example 05_guidance` draws stripes that brighten from left to right,
//! trains a guided model (`--guide x`) for 20 iterations in `runs/05_guidance/`, and paints it
//! with the ramp reversed (`--guide=-x`): `05_guidance.png`.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use burn::prelude::Device;
use ipfn::condition::Guide;
use ipfn::synth::Synth;
use ipfn::train::{TrainConfig, Trainer};

fn main() -> ipfn::Result<()> {
    // `ipfn draw graded -o 05_graded.png --size 128`
    let exemplar = Path::new("05_graded.png");
    let unit = ipfn::procedural::graded_stripes(128, 128, 16.0, 0.15, 0.85);
    let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
    ipfn::io::write_png(exemplar, 128, 128, 3, &values)?;

    // `ipfn train 05_graded.png --guide x --iterations 20 --crop 32`
    let config = TrainConfig {
        iterations: 20,
        crop: 32,
        hidden_layers: 4,
        width: 32,
        critic_widths: vec![16, 32, 64, 64],
        guide: Some("x".into()),
        ..TrainConfig::default()
    };
    let run = Path::new("runs/05_guidance");
    let mut trainer = Trainer::new(config, exemplar, run, &Device::flex())?;
    println!("run kind: {:?}", trainer.kind());
    trainer.run(&AtomicBool::new(false), |_, _| {})?;

    // `ipfn synth --guide=-x --size 128`: the guidance runs over the output's frame.
    let (config, weights) = trainer.model();
    let reversed: Guide = "-x".parse()?;
    let pixels = Synth::new(config, weights)
        .guide(reversed, [128, 128])
        .painter()?
        .render(&[0, 0], &[128, 128]);
    ipfn::io::write_png(Path::new("05_guidance.png"), 128, 128, 3, &pixels)?;
    println!("wrote 05_guidance.png");
    Ok(())
}
