//! The map-set flags that `ipfn train` and `ipfn fit` share.

use std::path::PathBuf;

use clap::Args;

use crate::maps::MapSetRequest;

#[derive(Debug, Args)]
pub struct MapSetArgs {
    /// A material map set instead of one image, trained or fitted as one so the maps stay
    /// aligned (synth writes one file per map): the files
    /// (albedo.png,normal.png,roughness.png,height.png), or a folder of maps named by role
    /// (color, normal, height, roughness, ao, metalness and their usual spellings), each read
    /// and written back at its own bit depth (a gray map stored as RGB is read as gray, an
    /// opaque alpha dropped).
    #[arg(long, value_delimiter = ',', value_name = "FILES")]
    pub maps: Option<Vec<PathBuf>>,
    /// Which maps are normal maps (renormalised to unit length on output), by file stem.
    /// Default: the maps named as normal maps (normal, nor_gl, NormalGL, NormalDX, ...); pass
    /// "" for none.
    #[arg(long, value_delimiter = ',', value_name = "NAMES", requires = "maps")]
    pub normal_maps: Option<Vec<String>>,
    /// Resample maps of another size to the first map's size (maps of mixed bit depths are
    /// read as they are, without it).
    #[arg(long, requires = "maps")]
    pub resize_maps: bool,
    /// The normal maps' convention: gl (OpenGL, green up) or dx (DirectX, green down; read
    /// and written back as DirectX). Default: as each map's name says (NormalDX, nor_dx: dx).
    #[arg(long, value_name = "gl|dx", value_parser = ["gl", "dx"], requires = "maps")]
    pub normal_convention: Option<String>,
}

impl MapSetArgs {
    /// The map set these flags name, if any.
    pub fn request(&self) -> Option<MapSetRequest> {
        self.maps.as_ref().map(|files| MapSetRequest {
            files: files.clone(),
            normal_maps: self.normal_maps.clone(),
            resize_maps: self.resize_maps,
            directx_normals: self.normal_convention.as_deref().map(|c| c == "dx"),
        })
    }
}
