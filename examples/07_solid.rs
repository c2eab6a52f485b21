//! The guide's "Solid textures from a 2D exemplar"
//! (docs/guide/solid-and-volumes.md), as library calls.
//!
//! `cargo run --release --example 07_solid` trains a solid texture (`train --solid`: a 3D
//! generator whose random axis-aligned slices the 2D critic compares with crops of the bricks
//! image) for 10 iterations in `runs/07_solid/`, and writes three orthogonal slices of its
//! volume: `07_solid-z.png`, `07_solid-y.png`, `07_solid-x.png`.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use burn::prelude::Device;
use ipfn::synth::Synth;
use ipfn::train::{TrainConfig, Trainer};

fn main() -> ipfn::Result<()> {
    let exemplar = Path::new("07_bricks.png");
    let unit = ipfn::procedural::bricks(128, 128, 32, 16);
    let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
    ipfn::io::write_png(exemplar, 128, 128, 3, &values)?;

    // `ipfn train 07_bricks.png --solid --iterations 10 --crop 32`
    let config = TrainConfig {
        iterations: 10,
        crop: 32,
        hidden_layers: 4,
        width: 32,
        critic_widths: vec![16, 32, 64, 64],
        solid: true,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new(
        config,
        exemplar,
        Path::new("runs/07_solid"),
        &Device::flex(),
    )?;
    trainer.run(&AtomicBool::new(false), |_, _| {})?;

    // `ipfn synth --solid --size 96x96x96 --slice z=0` (and y=0, x=0): one voxel thick boxes.
    let (config, weights) = trainer.model();
    let painter = Synth::new(config, weights).seed(1).painter()?;
    for (axis, shape) in [("z", [1, 96, 96]), ("y", [96, 1, 96]), ("x", [96, 96, 1])] {
        let pixels = painter.render(&[0, 0, 0], &shape);
        let path = format!("07_solid-{axis}.png");
        ipfn::io::write_png(Path::new(&path), 96, 96, 3, &pixels)?;
        println!("wrote {path}");
    }
    Ok(())
}
