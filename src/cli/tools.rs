//! `ipfn import`, `ipfn draw` and `ipfn voxelize`: the commands that make inputs.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::checkpoint::Checkpoint;
use crate::error::Result;

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The authors' generator checkpoint (e.g. honeycomb_test_netG_Epoch101.pth).
    pub pth: PathBuf,
    /// Where to write the ipfn model.
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
    /// Octaves of the encoding the model was trained with (their code's default: 5).
    #[arg(long, default_value_t = 5)]
    pub octaves: usize,
    /// Crop size it was trained with, in pixels (their default: 128).
    #[arg(long, default_value_t = 128)]
    pub crop: usize,
}

#[derive(Debug, Args)]
pub struct VoxelizeArgs {
    /// The mesh: .obj or .ply (ASCII or binary), closed for a meaningful inside.
    pub mesh: PathBuf,
    /// Voxels per side of the cubic volume.
    #[arg(long, default_value_t = 64)]
    pub res: usize,
    /// Empty margin around the mesh's bounding box, as a fraction of its largest side.
    #[arg(long, default_value_t = 0.05)]
    pub padding: f32,
    /// Output volume: .npy `[res, res, res, 1]`, or .raw (bare little-endian float32); signed
    /// distance in units of the volume's side, negative inside.
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct DrawArgs {
    /// bricks (32x16 bricks: period 32 across, 32 down), weave (thread pitch 8: period 16),
    /// stripes (period 40 across), graded (16 px stripes whose bright part grows from 15% of
    /// the period at the left to 85% at the right: for --guide x), or material: a map set (albedo, normal, roughness,
    /// height; 16-bit PNGs, period 32) written into the folder --out, or gyroid: a signed
    /// distance volume (.npy, size^3 voxels, period 32).
    pub pattern: String,
    /// Width and height in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: usize,
    /// gyroid: the period in voxels (default 32).
    #[arg(long, value_name = "VOXELS")]
    pub period: Option<usize>,
    /// gyroid: thicken the sheet along x (half-thickness 0.1 to 0.9), so porosity grows from
    /// about 7% to 58% across the volume (an exemplar for `train --density`).
    #[arg(long)]
    pub graded: bool,
    /// Output PNG (a folder for material).
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
}

pub(super) fn import(args: ImportArgs) -> Result<()> {
    if args.out.extension().is_none_or(|e| e != "ipfn") {
        return Err(crate::file_error!(&args.out, "model files end in .ipfn",));
    }
    let (config, weights) = crate::generator::import_pytorch(&args.pth, args.octaves, args.crop)?;
    let mut ckpt = Checkpoint::new();
    ckpt.metadata.insert(
        "provenance".into(),
        format!(
            "imported by ipfn {} from {}",
            env!("CARGO_PKG_VERSION"),
            args.pth
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        ),
    );
    weights.write_to(&config, &mut ckpt);
    ckpt.save(&args.out)?;
    eprintln!(
        "wrote {}: {} hidden layers of {}, latent {}, {} channels, K = {:?}",
        args.out.display(),
        config.hidden_layers,
        config.width,
        config.latent_dim,
        config.channels,
        weights.k
    );
    Ok(())
}

pub(super) fn draw(args: DrawArgs) -> Result<()> {
    let request = crate::draw::DrawRequest {
        pattern: args.pattern,
        size: args.size,
        period: args.period,
        graded: args.graded,
        out: args.out,
    };
    eprintln!("{}", request.draw()?);
    Ok(())
}

pub(super) fn voxelize(args: VoxelizeArgs) -> Result<()> {
    if !(args.padding.is_finite() && args.padding >= 0.0) {
        return Err(crate::setting_error!(
            "--padding",
            args.padding,
            "must be a fraction of 0 or more"
        ));
    }
    crate::io::VolumeFormat::from_path(&args.out)?;
    crate::io::check_destination(&args.out)?;
    let start = Instant::now();
    let mesh = crate::mesh::read_mesh(&args.mesh)?;
    let volume = crate::mesh::voxelize(&mesh, args.res, args.padding)
        .map_err(|e| crate::file_error!(&args.mesh, "{e}"))?;
    if volume.open_edges > 0 {
        eprintln!(
            "warning: {} has {} open edges: inside and outside are decided by ray parity voted over three axes, which can leak through holes; close the mesh for a reliable sign",
            args.mesh.display(),
            volume.open_edges
        );
    }
    let n = args.res;
    let mut writer = crate::io::VolumeWriter::create(&args.out, n, n, n, 1)?;
    writer.write_slab(&volume.values)?;
    writer.finish()?;
    let inside =
        volume.values.iter().filter(|&&v| v < 0.0).count() as f64 / volume.values.len() as f64;
    eprintln!(
        "wrote {} ({n}x{n}x{n} signed distance of {}: {} triangles, {:.1}% inside) in {:.2} s",
        args.out.display(),
        args.mesh.display(),
        mesh.triangles.len(),
        100.0 * inside,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
