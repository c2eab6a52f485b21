//! The guide's "Volumes: porous solids from a signed-distance volume"
//! (docs/guide/solid-and-volumes.md), as library calls.
//!
//! `cargo run --release --example 06_volume` draws a gyroid SDF volume, trains a 3D model on
//! cubic crops for 10 iterations in `runs/06_volume/`, then paints a 48³ volume with its mesh:
//! `06_volume.npy` and `06_volume.obj`.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use burn::prelude::Device;
use ipfn::mesh::MeshBuilder;
use ipfn::synth::{DEFAULT_BAND_PIXELS, Synth};
use ipfn::train::{TrainConfig, Trainer};

fn main() -> ipfn::Result<()> {
    // `ipfn draw gyroid --size 48 --period 16 -o 06_gyroid.npy`
    let exemplar = Path::new("06_gyroid.npy");
    let sdf = ipfn::procedural::gyroid_sdf(48, 16.0, 0.4);
    let mut writer = ipfn::io::VolumeWriter::create(exemplar, 48, 48, 48, 1)?;
    writer.write_slab(&sdf)?;
    writer.finish()?;

    // `ipfn train 06_gyroid.npy --crop 16 --iterations 10`: a `.npy` exemplar is a volume run.
    let config = TrainConfig {
        iterations: 10,
        crop: 16,
        batch: 2,
        hidden_layers: 4,
        width: 32,
        critic_widths: vec![16, 32, 64, 64],
        ..TrainConfig::default()
    };
    let run = Path::new("runs/06_volume");
    let mut trainer = Trainer::new(config, exemplar, run, &Device::flex())?;
    println!("run kind: {:?}", trainer.kind());
    trainer.run(&AtomicBool::new(false), |_, s| println!("{}", s.summary()))?;

    // `ipfn synth --size 48x48x48 --out 06_volume.npy --mesh 06_volume.obj`
    let (config, weights) = trainer.model();
    let painter = Synth::new(config, weights).seed(1).painter()?;
    let shape = [48, 48, 48];
    let mut mesh = MeshBuilder::new(48, 48);
    painter.write_volume(
        Path::new("06_volume.npy"),
        shape,
        DEFAULT_BAND_PIXELS,
        Some(&mut mesh),
    )?;
    let mesh = mesh.finish();
    ipfn::mesh::write_mesh(&mesh, Path::new("06_volume.obj"))?;
    println!(
        "wrote 06_volume.npy and 06_volume.obj ({} triangles)",
        mesh.triangles.len()
    );
    Ok(())
}
