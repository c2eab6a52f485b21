//! `ipfn synth --out NAME.zarr`: a chunked Zarr v3 store, whole or one shard of it.

use std::time::Instant;

use super::SynthArgs;
use crate::error::Result;
use crate::io::zarr::{ZarrType, ZarrWriter};
use crate::model::ModelFile;
use crate::paint::SynthRequest;

/// The flags that make one worker differ from another of the same render; they are left out of
/// the command stored with the array, so every shard writes the same metadata.
const WORKER_FLAGS: [&str; 5] = ["--shard", "--shard-from-env", "--shards", "--quiet", "-q"];

pub(super) fn synth_zarr(
    args: &SynthArgs,
    request: &SynthRequest,
    model: &ModelFile,
) -> Result<()> {
    let out = request.out_path();
    let (painter, shape, chunk) = request.zarr_painter(model)?;
    let shard = request.zarr.shard(|name| std::env::var(name).ok())?;
    let kind = ZarrType::from_bits(args.bits)?;
    let attributes = attributes(args, model.description(), kind);
    let writer = ZarrWriter::create(&out, &shape, painter.channels(), chunk, kind, attributes)?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    say(format!("model: {}", model.description()));
    if let Some(t) = painter.tile_adjustment() {
        say(t.describe());
    }
    let removed = writer.remove_stale_temporaries(|n| shard.owns(n));
    if removed > 0 {
        say(format!(
            "removed {removed} temporary chunk files left by a stopped run of this shard"
        ));
    }
    let start = Instant::now();
    let report = write_with_progress(&painter, &writer, shard, !args.quiet)?;
    say(format!(
        "wrote {} ({}): {}, seed {}, {:?}, in {:.2} s",
        out.display(),
        writer.describe(),
        report.describe(shard),
        args.seed,
        request.device,
        start.elapsed().as_secs_f64()
    ));
    Ok(())
}

/// Paints the shard's chunks into `writer`, with a progress bar over them when `show`.
fn write_with_progress(
    painter: &crate::synth::Painter,
    writer: &ZarrWriter,
    shard: crate::io::shard::Shard,
    show: bool,
) -> Result<crate::io::zarr::ZarrReport> {
    let bar = crate::cli::progress_bar(
        show,
        0,
        "{bar:40} {pos}/{len} chunks  {elapsed} (eta {eta})",
    );
    let report = painter.write_zarr(writer, shard, |done, owned| {
        if let Some(bar) = &bar {
            bar.set_length(owned as u64);
            bar.set_position(done as u64);
        }
    })?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(report)
}

/// What the store records of the render: the model, the synth settings, what the values mean,
/// and the command without the flags that differ between workers.
fn attributes(
    args: &SynthArgs,
    model: &str,
    kind: ZarrType,
) -> serde_json::Map<String, serde_json::Value> {
    let values = match kind {
        ZarrType::Float32 => "generator values in [-1, 1]",
        ZarrType::Uint8 => "round((v + 1) / 2 * 255) of generator values v in [-1, 1]",
        ZarrType::Uint16 => "round((v + 1) / 2 * 65535) of generator values v in [-1, 1]",
    };
    let (x, y) = args.offset.unwrap_or((0, 0));
    let ipfn = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "model": model,
        "seed": args.seed,
        "zoom": args.zoom,
        "offset": [x, y],
        "noise_scale": args.noise_scale,
        "tile": args.tile,
        "mirror": args.mirror,
        "guide": args.guide,
        "density": args.density.map(|(a, b)| [a, b]),
        "device": args.device,
        "values": values,
        "command": worker_independent_command(
            std::env::args_os().map(|a| a.to_string_lossy().into_owned()),
        ),
    });
    let mut map = serde_json::Map::new();
    map.insert("ipfn".to_string(), ipfn);
    map
}

/// The command line with the worker flags (and their values) removed.
fn worker_independent_command(argv: impl Iterator<Item = String>) -> String {
    let mut kept = Vec::new();
    let mut argv = argv.peekable();
    if argv.peek().is_some() {
        argv.next();
        kept.push("ipfn".to_string());
    }
    while let Some(arg) = argv.next() {
        let name = arg.split('=').next().unwrap_or_default();
        if !WORKER_FLAGS.contains(&name) {
            kept.push(arg);
            continue;
        }
        // A value follows the flags that take one, unless it was given with `=`.
        let takes_value = matches!(name, "--shard" | "--shards" | "--shard-from-env");
        let next_is_value = argv.peek().is_some_and(|v| !v.starts_with('-'));
        if takes_value && !arg.contains('=') && next_is_value {
            argv.next();
        }
    }
    kept.join(" ")
}

#[cfg(test)]
mod tests {
    use super::worker_independent_command;

    #[test]
    fn worker_flags_leave_the_command() {
        let argv = |s: &str| {
            s.split(' ')
                .map(String::from)
                .collect::<Vec<_>>()
                .into_iter()
        };
        let a = worker_independent_command(argv(
            "/bin/ipfn synth --size 64 --out a.zarr --shard 1/4 -q",
        ));
        let b = worker_independent_command(argv(
            "ipfn synth --shard-from-env --shards 4 --size 64 --out a.zarr",
        ));
        let c = worker_independent_command(argv(
            "ipfn synth --shard=3/4 --size 64 --shard-from-env I --out a.zarr",
        ));
        assert_eq!(a, "ipfn synth --size 64 --out a.zarr");
        assert_eq!(a, b);
        assert_eq!(a, c);
    }
}
