//! A map set's files: which maps, read how (each at its own depth; gray maps stored as RGB read
//! as gray; an alpha channel that holds nothing dropped; DirectX normals turned to OpenGL's),
//! from a list or a folder.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{MapInfo, MapRole, MapSet, flip_green, stack};
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::input_error;

/// The files of a map set, which of them are normal maps, and in which convention.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapFiles {
    pub files: Vec<PathBuf>,
    pub normal: Vec<bool>,
    /// Resample maps to the first map's size instead of refusing them.
    pub resample: bool,
    /// The normal maps in DirectX's convention (green down), by index; empty: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub directx: Vec<bool>,
}

/// A map set as a request names it: the files (or one folder of them) and how to read them,
/// one field per flag that `ipfn train` and `ipfn fit` share.
#[derive(Debug, Clone, Default)]
pub struct MapSetRequest {
    /// The maps, or one folder of maps named by role.
    pub files: Vec<PathBuf>,
    /// Which maps are normal maps, by file stem; `None`: the maps named as normal maps.
    pub normal_maps: Option<Vec<String>>,
    /// Resample maps of another size to the first map's size instead of refusing them.
    pub resize_maps: bool,
    /// The normal maps' convention: `Some(true)` DirectX's, `Some(false)` OpenGL's, `None` as
    /// each map's name says (`NormalDX`, `nor_dx`: DirectX).
    pub directx_normals: Option<bool>,
}

impl MapSetRequest {
    /// These files (or this folder), read as their names say.
    pub fn files(files: Vec<PathBuf>) -> Self {
        Self {
            files,
            ..Self::default()
        }
    }

    /// The checked files ([`MapFiles::new`]), in the convention asked for.
    pub fn open(&self) -> Result<MapFiles> {
        let files = MapFiles::new(
            self.files.clone(),
            self.normal_maps.as_deref(),
            self.resize_maps,
        )?;
        Ok(match self.directx_normals {
            Some(directx) => files.with_directx(directx),
            None => files,
        })
    }
}

/// Image files a folder of maps may hold.
const MAP_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "exr"];

impl MapFiles {
    /// The maps in `files`, or in the folder `files` names alone (each image whose name says
    /// what it is: `color`, `normal`, `height`, `roughness`, `ao`, `metalness` and their usual
    /// spellings, in that order). `normal_names`: the stems of the normal maps; `None` picks
    /// those named as normal maps (`normal`, `nor_gl`, `NormalGL`, `NormalDX`, ...). A normal
    /// map named for DirectX (`NormalDX`, `nor_dx`) is read in DirectX's convention.
    pub fn new(
        files: Vec<PathBuf>,
        normal_names: Option<&[String]>,
        resample: bool,
    ) -> Result<Self> {
        let files = match files.as_slice() {
            [dir] if dir.is_dir() => maps_in_folder(dir)?,
            _ => files,
        };
        if files.len() < 2 {
            return Err(input_error!(
                "--maps needs at least two files (a single image trains as a plain exemplar)"
            ));
        }
        let stems: Vec<String> = files.iter().map(|f| stem(f)).collect();
        for (i, s) in stems.iter().enumerate() {
            if stems[..i].contains(s) {
                return Err(input_error!(
                    "--maps: two maps are named '{s}'; outputs are named after the files, so give each a different name"
                ));
            }
        }
        if let Some(names) = normal_names {
            for n in names.iter().filter(|n| !n.is_empty()) {
                if !stems.contains(n) {
                    return Err(input_error!(
                        "--normal-maps {n}: no map of that name; the maps are {}",
                        stems.join(", ")
                    ));
                }
            }
        }
        let roles: Vec<_> = stems.iter().map(|s| MapRole::from_name(s)).collect();
        let normal = stems
            .iter()
            .zip(&roles)
            .map(|(s, role)| match normal_names {
                Some(names) => names.contains(s),
                None => {
                    matches!(role, Some((MapRole::Normal, _)))
                        || s.to_ascii_lowercase().contains("normal")
                }
            })
            .collect::<Vec<bool>>();
        let directx = roles
            .iter()
            .zip(&normal)
            .map(|(role, &n)| n && matches!(role, Some((_, true))))
            .collect();
        Ok(Self {
            files,
            normal,
            resample,
            directx,
        })
    }

    /// Every normal map read in DirectX's convention (`--normal-convention dx`), or in
    /// OpenGL's (`gl`) whatever its name says.
    pub fn with_directx(mut self, directx: bool) -> Self {
        self.directx = self.normal.iter().map(|&n| n && directx).collect();
        self
    }

    fn is_directx(&self, index: usize) -> bool {
        self.directx.get(index).copied().unwrap_or(false)
    }

    /// Reads the maps, each at its own bit depth, checks that they agree in size (or resamples
    /// them to the first map's size when `resample` is set), and stacks their channels.
    pub fn load(&self) -> Result<(Exemplar, MapSet)> {
        let mut maps = Vec::new();
        let mut images: Vec<Exemplar> = Vec::new();
        for (index, (file, &normal)) in self.files.iter().zip(&self.normal).enumerate() {
            let (image, bits) = crate::exemplar::read_exemplar_with_bits(file)?;
            let stored = image.channels;
            let directx = normal && self.is_directx(index);
            let mut image = as_read(image, bits, normal, directx);
            if let Some(first) = images.first() {
                // Each map keeps its own bit depth (a published set mixes 8-bit colour with
                // 16-bit normals and heights), and is painted back at it.
                let (w, h) = (first.width, first.height);
                if (image.width, image.height) != (w, h) {
                    if !self.resample {
                        return Err(crate::file_error!(
                            &file,
                            "{}x{}, but {} is {w}x{h}; maps must be the same size (or pass --resize-maps to resample them)",
                            image.width,
                            image.height,
                            self.files[0].display(),
                        ));
                    }
                    image = image.resized(w, h);
                }
            }
            if normal && image.channels < 3 {
                return Err(crate::file_error!(
                    &file,
                    "a normal map needs 3 channels, this one has {}",
                    image.channels,
                ));
            }
            maps.push(MapInfo {
                name: stem(file),
                channels: image.channels,
                bits,
                normal,
                role: MapRole::from_name(&stem(file)).map(|(role, _)| role),
                directx,
                stored_channels: (image.channels != stored).then_some(stored),
            });
            images.push(image);
        }
        Ok((stack(&images), MapSet { maps }))
    }

    /// A short name for messages: the first file and how many more.
    pub fn describe(&self) -> String {
        format!(
            "{} (+{} maps)",
            self.files[0].display(),
            self.files.len() - 1
        )
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "map".into())
}

/// A map as it is learned: a gray map stored as RGB or RGBA as gray (its channels equal to
/// within one step of its depth), an alpha channel that is opaque everywhere dropped, a
/// DirectX normal map turned to OpenGL's convention.
fn as_read(image: Exemplar, bits: u8, normal: bool, directx: bool) -> Exemplar {
    let step = match bits {
        8 => 2.0 / 255.0,
        16 => 2.0 / 65535.0,
        _ => 1e-6,
    } * 1.01;
    let c = image.channels;
    let gray = !normal
        && c >= 3
        && image
            .values
            .chunks_exact(c)
            .all(|p| (p[0] - p[1]).abs() <= step && (p[0] - p[2]).abs() <= step);
    let mut image = if gray { image.to_gray() } else { image };
    let c = image.channels;
    let opaque = matches!(c, 2 | 4) && image.values.chunks_exact(c).all(|p| p[c - 1] >= 1.0 - step);
    if opaque {
        image = Exemplar {
            channels: c - 1,
            values: image
                .values
                .chunks_exact(c)
                .flat_map(|p| p[..c - 1].iter().copied())
                .collect(),
            ..image
        };
    }
    if directx {
        flip_green(&mut image.values, image.channels);
    }
    image
}

/// The maps in `dir`: each image whose name says what it is, in the order of [`MapRole`]
/// (colour, normal, height, roughness, ambient occlusion, metalness).
fn maps_in_folder(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| crate::file_error!(&dir, "cannot read the folder: {e}"))?;
    let mut maps: Vec<(MapRole, bool, PathBuf)> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let ext = crate::io::extension(p);
            p.is_file() && MAP_EXTENSIONS.contains(&ext.as_str())
        })
        .filter_map(|p| MapRole::from_name(&stem(&p)).map(|(role, dx)| (role, dx, p)))
        .collect();
    // One map a role: OpenGL's normal map before DirectX's (ambientCG ships both), then by name.
    maps.sort();
    maps.dedup_by_key(|(role, _, _)| *role);
    if maps.len() < 2 {
        return Err(crate::file_error!(
            &dir,
            "found {} map named by its role (color, normal, height, roughness, ao, metalness); a map set needs two or more, or give the files as --maps A.png,B.png,...",
            maps.len(),
        ));
    }
    Ok(maps.into_iter().map(|(_, _, p)| p).collect())
}
