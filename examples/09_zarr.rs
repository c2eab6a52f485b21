//! The guide's "Sharded output: Zarr stores for many workers"
//! (docs/guide/synth.md), as library calls.
//!
//! `cargo run --release --example 09_zarr` writes `09_zarr.zarr`, a 2048x2048 float32 Zarr v3
//! store, as 4 shards (one after another here; `ipfn synth --shard K/4` runs each as its own
//! process, on this machine or another). Every shard writes the same metadata and its own
//! chunks, so the order and the overlap of the workers do not matter.

use std::path::Path;

use ipfn::checkpoint::Checkpoint;
use ipfn::generator::GeneratorWeights;
use ipfn::io::shard::Shard;
use ipfn::io::zarr::{DEFAULT_IMAGE_CHUNK, ZarrType, ZarrWriter};
use ipfn::synth::Synth;

fn main() -> ipfn::Result<()> {
    let model =
        Checkpoint::from_bytes(ipfn::model::SHIPPED_HONEYCOMB, Path::new("honeycomb.ipfn"))?;
    let (config, weights) = GeneratorWeights::read_from(&model)?;
    let painter = Synth::new(config, weights).seed(7).painter()?;
    let out = Path::new("09_zarr.zarr");
    let mut attributes = serde_json::Map::new();
    attributes.insert("note".into(), "09_zarr example, seed 7".into());
    for index in 0..4 {
        // What `ipfn synth --size 2048 --seed 7 --out 09_zarr.zarr --shard {index}/4` does.
        let writer = ZarrWriter::create(
            out,
            &[2048, 2048],
            painter.channels(),
            DEFAULT_IMAGE_CHUNK,
            ZarrType::Float32,
            attributes.clone(),
        )?;
        let shard = Shard::new(index, 4)?;
        let report = painter.write_zarr(&writer, shard, |_, _| {})?;
        println!("{} ({})", report.describe(shard), writer.describe());
    }
    Ok(())
}
