//! `ipfn synth` of a tile fitted by `ipfn fit`: the period at any resolution (`--size`),
//! repeated over `--width`/`--height`, with stages faded out by `--lod`.

use std::path::Path;
use std::time::Instant;

use super::SynthArgs;
use crate::checkpoint::Checkpoint;
use crate::device::DeviceChoice;
use crate::error::Result;
use crate::fit::{PeriodicNet, TilePainter};
use crate::input_error;
use crate::io::OutputFormat;
use crate::maps::{MapOutput, MapSet};

/// Paints the fitted tile in `checkpoint` as `synth` asks.
pub(super) fn synth_tile(
    args: &SynthArgs,
    device: DeviceChoice,
    checkpoint: &Checkpoint,
    description: &str,
) -> Result<()> {
    let refused = [
        (args.mirror, "--mirror"),
        (args.guide.is_some(), "--guide"),
        (
            args.zoom != 1.0,
            "--zoom (give --size: the pixels of one period)",
        ),
        (args.noise_scale != 1.0, "--noise-scale"),
        (
            args.depth.is_some() || args.slice.is_some() || args.solid,
            "volumes",
        ),
        (args.mesh.is_some() || args.density.is_some(), "volumes"),
    ];
    if let Some((_, what)) = refused.iter().find(|(given, _)| *given) {
        return Err(input_error!(
            "{description}: a tile fitted by `ipfn fit` takes no {what}"
        ));
    }
    let net = PeriodicNet::read_from(checkpoint)?;
    let period = net.shape.period;
    let resolution = args.size.map(|s| [s.height, s.width]).unwrap_or(period);
    let extent = [
        args.height.unwrap_or(resolution[0]),
        args.width.unwrap_or(resolution[1]),
    ];
    if resolution.contains(&0) || extent.contains(&0) {
        return Err(input_error!(
            "size {}x{}: width and height must be at least 1",
            extent[1],
            extent[0]
        ));
    }
    let stages = net.stages() as f32;
    let lod = args.lod.unwrap_or(stages);
    if !(0.0..=stages).contains(&lod) {
        return Err(input_error!(
            "--lod {lod}: this tile has {stages} stages; give 0 to {stages}"
        ));
    }
    let maps = MapSet::read_from(checkpoint, Path::new(description))?;
    let c = net.shape.channels;
    let format = OutputFormat::from_path(&args.out, args.bits.unwrap_or(8))?;
    crate::io::check_destination(&args.out)?;
    let outputs = match &maps {
        Some(set) => set.outputs(&args.out, args.bits)?,
        None => vec![MapOutput {
            path: args.out.clone(),
            format,
            channels: 0..c,
            normal: false,
        }],
    };
    crate::maps::check_outputs(&outputs, extent[1], extent[0])?;
    let painter = TilePainter {
        net,
        resolution,
        lod,
        device: device.burn_device()?,
    };
    let (x, y) = args.offset.unwrap_or((0, 0));
    let start = Instant::now();
    painter.write(&outputs, [y, x], extent, crate::synth::DEFAULT_BAND_PIXELS)?;
    if !args.quiet {
        let written: Vec<String> = outputs
            .iter()
            .map(|o| o.path.display().to_string())
            .collect();
        eprintln!(
            "model: {description} (a periodic tile, {}x{} per period, level of detail {lod})",
            resolution[1], resolution[0]
        );
        eprintln!(
            "wrote {} ({}x{}, {device:?}) in {:.2} s",
            written.join(", "),
            extent[1],
            extent[0],
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
