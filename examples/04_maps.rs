//! The guide's "Material map sets" (docs/guide/train.md), as library calls.
//!
//! `cargo run --release --example 04_maps` draws the procedural material (albedo, normal,
//! roughness, height), trains one small model on all four maps for 20 iterations in
//! `runs/04_maps/`, and paints an aligned 128x128 set `04_maps-<map>.png`.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use burn::prelude::Device;
use ipfn::io::OutputFormat;
use ipfn::maps::MapFiles;
use ipfn::synth::{DEFAULT_BAND_PIXELS, Synth};
use ipfn::train::{TrainConfig, Trainer};

fn main() -> ipfn::Result<()> {
    // `ipfn draw material -o 04_material`
    let dir = Path::new("04_material");
    std::fs::create_dir_all(dir).map_err(|e| ipfn::Error::Runtime(e.to_string()))?;
    let mut files: Vec<PathBuf> = Vec::new();
    let maps = ipfn::procedural::material(128, 128, 32);
    for ((name, channels), unit) in ipfn::procedural::MATERIAL_MAPS.iter().zip(maps) {
        let values: Vec<f32> = unit.iter().map(|v| v * 2.0 - 1.0).collect();
        let path = dir.join(format!("{name}.png"));
        ipfn::io::write_png(&path, 128, 128, *channels, &values)?;
        files.push(path);
    }
    // `ipfn train --maps albedo.png,normal.png,... --iterations 20 --crop 32`
    let config = TrainConfig {
        iterations: 20,
        crop: 32,
        hidden_layers: 4,
        width: 32,
        critic_widths: vec![16, 32, 64, 64],
        ..TrainConfig::default()
    };
    let source = MapFiles::new(files, None, false)?;
    let run = Path::new("runs/04_maps");
    let mut trainer = Trainer::new(config, source, run, &Device::flex())?;
    trainer.run(&AtomicBool::new(false), |_, _| {})?;

    // `ipfn synth --model runs/04_maps/latest.ipfn --size 128 --out 04_maps.png`
    let set = trainer.maps().expect("a map-set run").clone();
    let (config, weights) = trainer.model();
    let outputs = set.outputs(Path::new("04_maps.png"), None)?;
    Synth::new(config, weights).seed(1).painter()?.write_maps(
        &outputs,
        [128, 128],
        DEFAULT_BAND_PIXELS,
        |_| {},
    )?;
    for o in &outputs {
        let bits = match o.format {
            OutputFormat::Png { bits } => bits,
            _ => 32,
        };
        println!(
            "wrote {} ({} channels, {bits}-bit)",
            o.path.display(),
            o.channels.len()
        );
    }
    Ok(())
}
