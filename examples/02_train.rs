//! The guide's "`ipfn train`: learn a pattern" (docs/guide/train.md), as library calls.
//!
//! `cargo run --release --example 02_train` draws the bricks exemplar, trains a small model on
//! it for 100 iterations (about 1.5 minutes on 2 cores) in `runs/02_train/`, and paints a sample.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use burn::prelude::Device;
use ipfn::synth::Synth;
use ipfn::train::{TrainConfig, Trainer};

fn main() -> ipfn::Result<()> {
    let exemplar = Path::new("02_bricks.png");
    let unit = ipfn::procedural::bricks(128, 128, 32, 16);
    let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
    ipfn::io::write_png(exemplar, 128, 128, 3, &values)?;

    let config = TrainConfig {
        iterations: 100,
        crop: 32,
        batch: 8,
        lr: 2e-4,
        hidden_layers: 6,
        width: 64,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new(
        config,
        exemplar,
        Path::new("runs/02_train"),
        &Device::flex(),
    )?;
    // Prepares the run folder, appends metrics.csv, and saves checkpoints and previews on
    // schedule (and at the last iteration); raising `stop` ends the run after a checkpoint.
    let stop = AtomicBool::new(false);
    trainer.run(&stop, |_, stats| {
        if stats.iteration % 25 == 0 {
            println!("iteration {}: {}", stats.iteration, stats.summary());
        }
    })?;

    let (config, weights) = trainer.model();
    let sample = Synth::new(config, weights)
        .seed(1)
        .painter()?
        .render(&[0, 0], &[256, 256]);
    ipfn::io::write_png(Path::new("02_train.png"), 256, 256, 3, &sample)?;
    println!("wrote runs/02_train/latest.ipfn and 02_train.png");
    Ok(())
}
