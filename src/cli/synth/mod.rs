//! `ipfn synth`: the flags, mapped onto [`crate::paint::SynthRequest`], which decides
//! what they paint; this file parses and prints.

mod zarr;

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::error::Result;
use crate::model::load_model;
pub use crate::paint::Size;
use crate::paint::{SynthRequest, ZarrOptions};

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Model file (.ipfn). Default: the most recently written *.ipfn or runs/*/latest.ipfn in the
    /// working folder, else the shipped honeycomb model.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    /// Output size: N (square), WxH, or WxHxD for a volume (as --depth D). Default 512.
    #[arg(long, value_name = "N|WxH|WxHxD", value_parser = parse_size)]
    pub size: Option<Size>,
    /// Output width in pixels (overrides --size).
    #[arg(long, value_name = "W")]
    pub width: Option<usize>,
    /// Output height in pixels (overrides --size).
    #[arg(long, value_name = "H")]
    pub height: Option<usize>,
    /// Depth in voxels: paint a volume (`[D, H, W, C]`, .npy or .raw) with a 3D model.
    #[arg(long, value_name = "D")]
    pub depth: Option<usize>,
    /// With a volume: also write the zero level set of the volume's first channel as a mesh
    /// (.obj or .ply), extracted slab by slab and welded.
    #[arg(long, value_name = "PATH")]
    pub mesh: Option<PathBuf>,
    /// The model is a solid texture (trained with `train --solid`): paint its volume
    /// (`--size WxHxD` or `--depth`, .npy) or, with --slice, one plane of it as an image.
    #[arg(long)]
    pub solid: bool,
    /// With a 3D model: write only the plane AXIS=INDEX of the WxHxD volume as an image, e.g.
    /// z=0 (an HxW plane), y=10 (DxW) or x=255 (DxH).
    #[arg(long, value_name = "AXIS=INDEX", value_parser = parse_slice)]
    pub slice: Option<(char, usize)>,
    /// For a volume model trained with --density: the density (mean |sdf| of the truncated
    /// SDF, e.g. 0.3) to paint, or A,B for a ramp from A at the first column to B at the last.
    #[arg(long, value_name = "D|A,B", value_parser = parse_density)]
    pub density: Option<(f32, f32)>,
    /// Seed of the latent field: each seed paints a different sample.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Magnification: 1 paints one output pixel per exemplar pixel seen in training; 2 paints
    /// the pattern twice as large.
    #[arg(long, default_value_t = 1.0)]
    pub zoom: f64,
    /// Top-left pixel of the output in the infinite plane, as X,Y. Adjacent offsets paint
    /// adjacent pieces of one larger image.
    #[arg(long, value_name = "X,Y", value_parser = parse_offset, allow_hyphen_values = true)]
    pub offset: Option<(i64, i64)>,
    /// Make the output tile seamlessly: K is snapped so the image spans whole periods, and the
    /// latent lattice wraps. Prints how far K moved.
    #[arg(long)]
    pub tile: bool,
    /// Make a mirror-symmetric tile: the top-left quarter is painted and reflected about the
    /// image's centre lines, so the output is symmetric and tiles by plain repetition.
    #[arg(long, conflicts_with = "tile")]
    pub mirror: bool,
    /// Size of the latent noise's cells relative to the pattern, as a multiple of training's:
    /// above 1, structure varies over larger regions; below 1, over smaller ones.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub noise_scale: f64,
    /// Guidance for a guided model: x, y, -x, -y, a line a,b,c (g = a·x + b·y + c over the
    /// output, x and y in [-1, 1]), or a grayscale image of the output's size (g = 2v - 1).
    #[arg(long, value_name = "LINE|IMAGE", allow_hyphen_values = true)]
    pub guide: Option<String>,
    /// Output file: .png (8 or 16 bit), .exr (float) or .npy (raw floats in [-1, 1], [H, W, C]);
    /// a volume: .npy ([D, H, W, C] float32) or .raw (bare little-endian float32). Either as
    /// .zarr: a chunked Zarr v3 store (see --chunk and --shard). Default synth.png, or synth.npy
    /// for a volume.
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out_path: Option<PathBuf>,
    /// A map set's material lit as a plane (colour, normal or height, roughness, AO, metalness;
    /// one light at a grazing angle, GGX shading), as an 8-bit PNG of the painted image (its
    /// top-left 1024² when larger).
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    /// Bits per channel for PNG output: 8 or 16. Default 8; a map set's maps keep their
    /// inputs' depth. For .zarr: 8 or 16 store unsigned integers, as PNG; default float32.
    #[arg(long)]
    pub bits: Option<u8>,
    /// For .zarr output: the side of a chunk on every axis (default 512 for images, 64 for
    /// volumes). Chunks are the unit of work of --shard.
    #[arg(long, value_name = "N")]
    pub chunk: Option<usize>,
    /// For .zarr output: render only the K-th of N disjoint sets of chunks (K from 0 to N-1),
    /// so N workers, on one machine or many, fill one store. Rerunning a shard skips the
    /// chunks it finished.
    #[arg(long, value_name = "K/N", conflicts_with = "shard_from_env")]
    pub shard: Option<crate::io::shard::Shard>,
    /// For .zarr output: take K of --shard from the environment: VAR, else
    /// JOB_COMPLETION_INDEX (Kubernetes Indexed Job), else SLURM_ARRAY_TASK_ID (less
    /// SLURM_ARRAY_TASK_MIN). N is --shards, else SLURM_ARRAY_TASK_COUNT.
    #[arg(long, value_name = "VAR", num_args = 0..=1, default_missing_value = "")]
    pub shard_from_env: Option<String>,
    /// With --shard-from-env: the number of shards N.
    #[arg(long, value_name = "N", requires = "shard_from_env")]
    pub shards: Option<usize>,
    /// Where to run: cpu (fused CPU evaluator), flex (burn CPU backend), wgpu (GPU), auto (the
    /// best present, as on every command) or cuda
    /// (NVIDIA GPU; a build with --features cuda).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// For a tile from `ipfn fit`: the level of detail, in stages (0 to the tile's stage
    /// count, fractions blend): the stages above it are faded out, an anti-aliased rendering
    /// for a smaller size. Default: every stage.
    #[arg(long, value_name = "T")]
    pub lod: Option<f32>,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

fn parse_size(s: &str) -> std::result::Result<Size, String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let number = |p: &str| {
        p.trim()
            .parse::<usize>()
            .map_err(|_| format!("'{s}': expected N, WxH or WxHxD, e.g. 512 or 256x256x256"))
    };
    match parts.as_slice() {
        [n] => Ok(Size {
            width: number(n)?,
            height: number(n)?,
            depth: None,
        }),
        [w, h] => Ok(Size {
            width: number(w)?,
            height: number(h)?,
            depth: None,
        }),
        [w, h, d] => Ok(Size {
            width: number(w)?,
            height: number(h)?,
            depth: Some(number(d)?),
        }),
        _ => Err(format!(
            "'{s}': expected N, WxH or WxHxD, e.g. 512 or 256x256x256"
        )),
    }
}

fn parse_density(s: &str) -> std::result::Result<(f32, f32), String> {
    let err = || format!("'{s}': expected a density D or a ramp A,B, e.g. 0.3 or 0.35,0.2");
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|_| err()))
        .collect::<std::result::Result<_, _>>()?;
    match values[..] {
        [d] if d.is_finite() => Ok((d, d)),
        [a, b] if a.is_finite() && b.is_finite() => Ok((a, b)),
        _ => Err(err()),
    }
}

fn parse_slice(s: &str) -> std::result::Result<(char, usize), String> {
    let err = || format!("'{s}': expected AXIS=INDEX with AXIS x, y or z, e.g. z=0");
    let (axis, index) = s.split_once('=').ok_or_else(err)?;
    let axis = match axis.trim().to_ascii_lowercase().as_str() {
        "x" => 'x',
        "y" => 'y',
        "z" => 'z',
        _ => return Err(err()),
    };
    Ok((axis, index.trim().parse().map_err(|_| err())?))
}

fn parse_offset(s: &str) -> std::result::Result<(i64, i64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("'{s}': expected X,Y (e.g. 512,-256)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<i64>()
            .map_err(|_| format!("'{s}': expected two integers X,Y"))
    };
    Ok((parse(x)?, parse(y)?))
}

impl SynthArgs {
    /// The library request these flags ask for.
    pub fn request(&self) -> Result<SynthRequest> {
        Ok(SynthRequest {
            size: self.size,
            width: self.width,
            height: self.height,
            depth: self.depth,
            slice: self.slice,
            solid: self.solid,
            mesh: self.mesh.clone(),
            density: self.density,
            seed: self.seed,
            zoom: self.zoom,
            offset: self.offset,
            tile: self.tile,
            mirror: self.mirror,
            noise_scale: self.noise_scale,
            guide: self.guide.clone(),
            out: self.out_path.clone(),
            preview: self.preview.clone(),
            bits: self.bits,
            zarr: ZarrOptions {
                chunk: self.chunk,
                shard: self.shard,
                shard_from_env: self.shard_from_env.clone(),
                shards: self.shards,
            },
            device: crate::device::DeviceChoice::resolve(&self.device)?,
            lod: self.lod,
            gpu_kernel: gpu_kernel_from_env(),
        })
    }
}

/// `IPFN_GPU_KERNEL=0` paints on a GPU with burn's generator instead of ipfn's kernel (to
/// compare the two, as `benches/gpu.sh` does).
fn gpu_kernel_from_env() -> bool {
    std::env::var("IPFN_GPU_KERNEL").map_or(true, |v| v != "0")
}

pub(super) fn synth(args: SynthArgs) -> Result<()> {
    let request = args.request()?;
    let model = load_model(args.model.as_deref(), Path::new("."))?;
    if request.is_zarr() {
        return zarr::synth_zarr(&args, &request, &model);
    }
    let plan = request.plan(&model)?;
    plan.check_destinations()?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    plan.header().into_iter().for_each(say);
    let start = Instant::now();
    let bar = crate::cli::progress_bar(
        !args.quiet && plan.pixels() >= 1 << 22 && plan.rows() > 0,
        plan.rows() as u64,
        "{bar:40} {pos}/{len} rows  {elapsed} (eta {eta})",
    );
    let wrote = plan.write(|rows| {
        if let Some(bar) = &bar {
            bar.set_position(rows as u64);
        }
    })?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    say(format!("{wrote} in {:.2} s", start.elapsed().as_secs_f64()));
    Ok(())
}
