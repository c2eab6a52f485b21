//! Material map sets: several aligned maps (albedo, normal, roughness, height, ...) learned as one
//! exemplar with their channels stacked, and painted back as one file per map.
//!
//! Alignment is exact by construction: one generator paints all channels of a pixel in one
//! evaluation, and the maps are cut from that evaluation.

mod files;
pub mod preview;
mod role;

use std::ops::Range;
use std::path::{Path, PathBuf};

pub use files::{MapFiles, MapSetRequest};
pub use role::MapRole;

use serde::{Deserialize, Serialize};

use crate::checkpoint::Checkpoint;
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::io::OutputFormat;

/// Checkpoint metadata key holding the [`MapSet`] (JSON) of a map-set model.
pub const MAPS_KEY: &str = "maps";

/// One map of a set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapInfo {
    /// The input file's stem (`normal` for `normal.png`): outputs are named after it.
    pub name: String,
    pub channels: usize,
    /// Bits per channel of the input: 8 or 16 (PNG, JPEG) or 32 (EXR, float).
    pub bits: u8,
    /// A normal map: its first three channels are a vector, renormalised to unit length on output.
    pub normal: bool,
    /// What the map is, from its file's name (colour, normal, height, ...); none if unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub role: Option<MapRole>,
    /// A normal map in DirectX's convention (green points down): read into OpenGL's, which
    /// the model learns, and written back in DirectX's.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub directx: bool,
    /// The channels of the file where it held more than the map has: a gray map stored as RGB
    /// (or RGBA), an alpha channel that held nothing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stored_channels: Option<usize>,
}

/// The maps of a set, in channel order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSet {
    pub maps: Vec<MapInfo>,
}

impl MapSet {
    /// The maps for messages: `albedo (3 ch, 16-bit), normal (3 ch, 16-bit, normal), ...`.
    pub fn describe(&self) -> String {
        let names: Vec<String> = self
            .maps
            .iter()
            .map(|m| {
                let normal = match (m.normal, m.directx) {
                    (true, true) => ", normal, DirectX",
                    (true, false) => ", normal",
                    _ => "",
                };
                let stored = match m.stored_channels {
                    Some(c) => format!(", read from {c}"),
                    None => String::new(),
                };
                format!(
                    "{} ({} ch{stored}, {}-bit{normal})",
                    m.name, m.channels, m.bits
                )
            })
            .collect();
        names.join(", ")
    }

    /// Total channels.
    pub fn channels(&self) -> usize {
        self.maps.iter().map(|m| m.channels).sum()
    }

    /// Each map's channels within the stacked pixel.
    pub fn ranges(&self) -> Vec<Range<usize>> {
        let mut start = 0;
        self.maps
            .iter()
            .map(|m| {
                start += m.channels;
                start - m.channels..start
            })
            .collect()
    }

    /// The map that stands for the set where one picture is needed (the recipe's measures,
    /// SIFID): its colour map, else its first map of three or more channels, else its first.
    pub fn colour_map(&self) -> usize {
        let colour = self
            .maps
            .iter()
            .position(|m| m.role == Some(MapRole::Color));
        let rgb = self.maps.iter().position(|m| m.channels >= 3 && !m.normal);
        colour.or(rgb).unwrap_or(0)
    }

    /// The set stored in a model file, if it is a map-set model.
    pub fn read_from(checkpoint: &Checkpoint, path: &Path) -> Result<Option<Self>> {
        let Some(json) = checkpoint.metadata.get(MAPS_KEY) else {
            return Ok(None);
        };
        serde_json::from_str(json)
            .map(Some)
            .map_err(|e| crate::file_error!(&path, "unreadable map list ({e})"))
    }

    pub fn write_to(&self, checkpoint: &mut Checkpoint) {
        checkpoint.metadata.insert(
            MAPS_KEY.into(),
            serde_json::to_string(self).expect("the map list serialises"),
        );
    }

    /// One output per map: `<out stem>-<map name>.<ext>`. With a `.png` `out`, each map keeps its
    /// input's precision: 8- or 16-bit PNG (`bits` overrides), and float maps go to `.exr`.
    pub fn outputs(&self, out: &Path, bits: Option<u8>) -> Result<Vec<MapOutput>> {
        let stem = out
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "synth".into());
        let dir = out.parent().unwrap_or(Path::new(""));
        let format = OutputFormat::from_path(out, bits.unwrap_or(8))?;
        self.maps
            .iter()
            .zip(self.ranges())
            .map(|(map, range)| {
                let (format, ext) = match format {
                    OutputFormat::Png { .. } if map.bits > 16 => (OutputFormat::Exr, "exr"),
                    OutputFormat::Png { .. } => (
                        OutputFormat::Png {
                            bits: bits.unwrap_or(map.bits),
                        },
                        "png",
                    ),
                    OutputFormat::Exr => (OutputFormat::Exr, "exr"),
                    OutputFormat::Npy => (OutputFormat::Npy, "npy"),
                };
                Ok(MapOutput {
                    path: dir.join(format!("{stem}-{}.{ext}", map.name)),
                    format,
                    channels: range,
                    normal: map.normal,
                    directx: map.normal && map.directx,
                })
            })
            .collect()
    }
}

/// Where one map of a synthesis goes.
#[derive(Debug, Clone, PartialEq)]
pub struct MapOutput {
    pub path: PathBuf,
    pub format: OutputFormat,
    /// The map's channels within the stacked pixel.
    pub channels: Range<usize>,
    pub normal: bool,
    /// Written in DirectX's normal convention (green negated).
    pub directx: bool,
}

/// Negates every pixel's second channel (values in [-1, 1]): a normal map between OpenGL's
/// convention (green up) and DirectX's (green down).
pub fn flip_green(values: &mut [f32], channels: usize) {
    if channels >= 2 {
        values
            .chunks_exact_mut(channels)
            .for_each(|px| px[1] = -px[1]);
    }
}

/// Rescales the first three channels of every pixel (`[.., channels]`, values in [-1, 1]) to unit
/// length; a zero vector becomes (0, 0, 1).
pub fn renormalise(values: &mut [f32], channels: usize) {
    if channels < 3 {
        return;
    }
    for px in values.chunks_exact_mut(channels) {
        let len = (px[0] * px[0] + px[1] * px[1] + px[2] * px[2]).sqrt();
        if len > 1e-12 {
            px[..3].iter_mut().for_each(|v| *v /= len);
        } else {
            px[..3].copy_from_slice(&[0.0, 0.0, 1.0]);
        }
    }
}

/// Stacks same-size images channel-wise: pixel by pixel, the first image's channels, then the
/// second's, ...
pub fn stack(images: &[Exemplar]) -> Exemplar {
    let (w, h) = (images[0].width, images[0].height);
    let channels: usize = images.iter().map(|i| i.channels).sum();
    let mut values = Vec::with_capacity(w * h * channels);
    for p in 0..w * h {
        for image in images {
            let c = image.channels;
            values.extend_from_slice(&image.values[p * c..(p + 1) * c]);
        }
    }
    Exemplar {
        width: w,
        height: h,
        depth: 1,
        channels,
        values,
    }
}

/// Checks every output's folder and size before any work.
pub fn check_outputs(outputs: &[MapOutput], width: usize, height: usize) -> Result<()> {
    for o in outputs {
        crate::io::check_destination(&o.path)?;
        o.format
            .check_size(&o.path, width, height, o.channels.len())?;
    }
    Ok(())
}

/// A `[height, width]` image painted in row bands of about `band_pixels` pixels, each band's
/// stacked pixels (`channels` values each) split among `outputs`: clamped to [-1, 1] when
/// `clamp`, normal maps renormalised, DirectX maps' green flipped. Files and arrays are filled
/// by this one loop, so they hold the same values.
pub struct Bands<'a> {
    pub outputs: &'a [MapOutput],
    pub channels: usize,
    pub size: [usize; 2],
    pub band_pixels: usize,
    pub clamp: bool,
}

impl Bands<'_> {
    /// Renders every band in order (`render(row, rows)` gives its stacked pixels) and hands
    /// each output its part (`sink(output, values)`); `progress(rows_done)` follows each band.
    pub fn for_each(
        &self,
        render: impl Fn(usize, usize) -> Vec<f32>,
        mut sink: impl FnMut(usize, Vec<f32>) -> Result<()>,
        mut progress: impl FnMut(usize),
    ) -> Result<()> {
        let [height, width] = self.size;
        let channels = self.channels;
        let band_rows = (self.band_pixels / width.max(1)).clamp(1, height.max(1));
        let mut row = 0;
        while row < height {
            let rows = band_rows.min(height - row);
            let band = render(row, rows);
            for (i, o) in self.outputs.iter().enumerate() {
                let mut map: Vec<f32> = if o.channels == (0..channels) && !self.clamp {
                    band.clone()
                } else {
                    band.chunks_exact(channels)
                        .flat_map(|px| px[o.channels.clone()].iter())
                        .map(|&v| if self.clamp { v.clamp(-1.0, 1.0) } else { v })
                        .collect()
                };
                if o.normal {
                    renormalise(&mut map, o.channels.len());
                }
                if o.directx {
                    flip_green(&mut map, o.channels.len());
                }
                sink(i, map)?;
            }
            row += rows;
            progress(row);
        }
        Ok(())
    }

    /// Writes one file per output, each finished only once every band is written.
    pub fn write(
        &self,
        render: impl Fn(usize, usize) -> Vec<f32>,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        let [height, width] = self.size;
        let mut writers = (self.outputs.iter())
            .map(|o| {
                crate::io::ImageWriter::create(&o.path, o.format, width, height, o.channels.len())
            })
            .collect::<Result<Vec<_>>>()?;
        self.for_each(render, |i, map| writers[i].write_rows(&map), progress)?;
        writers.into_iter().try_for_each(|w| w.finish())
    }
}
