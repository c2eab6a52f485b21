//! What a run learns from ([`ExemplarSource`]) and the real side of the critic's input: random
//! crops over the exemplar's 2 or 3 axes, with their condition channel.

use std::path::{Path, PathBuf};

use burn::prelude::*;

use super::coarse::Scale;
use super::draws::uniform;
use super::{RunKind, TrainConfig, Trainer};
use crate::error::Result;
use crate::exemplar::{Exemplar, read_exemplar, read_sdf_volume};
use crate::maps::{MapFiles, MapSet};

/// Loads the exemplar and applies the config's resize.
pub fn load_exemplar(path: &Path, resize: f64) -> Result<Exemplar> {
    apply_resize(read_exemplar(path)?, resize)
}

fn apply_resize(exemplar: Exemplar, resize: f64) -> Result<Exemplar> {
    if resize == 1.0 {
        return Ok(exemplar);
    }
    let w = (exemplar.width as f64 * resize).round().max(1.0) as usize;
    let h = (exemplar.height as f64 * resize).round().max(1.0) as usize;
    Ok(exemplar.resized(w, h))
}

/// What a run learns from: one image, a set of aligned material maps, or an SDF volume.
#[derive(Debug, Clone, PartialEq)]
pub enum ExemplarSource {
    Image(PathBuf),
    Maps(MapFiles),
    /// A signed-distance volume (`.npy`).
    Volume(PathBuf),
}

impl From<&Path> for ExemplarSource {
    fn from(p: &Path) -> Self {
        p.to_path_buf().into()
    }
}

impl From<&PathBuf> for ExemplarSource {
    fn from(p: &PathBuf) -> Self {
        p.clone().into()
    }
}

impl From<PathBuf> for ExemplarSource {
    /// A `.npy` file is a volume; anything else an image.
    fn from(p: PathBuf) -> Self {
        let npy = crate::io::extension(&p) == "npy";
        if npy { Self::Volume(p) } else { Self::Image(p) }
    }
}

impl From<MapFiles> for ExemplarSource {
    fn from(m: MapFiles) -> Self {
        Self::Maps(m)
    }
}

impl ExemplarSource {
    /// Reads the exemplar (stacking a map set's channels; a volume as a truncated SDF) and
    /// applies the config's resize.
    pub fn load(&self, config: &TrainConfig) -> Result<(Exemplar, Option<MapSet>)> {
        let resize = config.resize;
        match self {
            Self::Image(path) => {
                let exemplar = load_exemplar(path, resize)?;
                let gray = config.gray && exemplar.channels >= 3;
                Ok((if gray { exemplar.to_gray() } else { exemplar }, None))
            }
            Self::Volume(path) => Ok((
                read_sdf_volume(path, config.sdf_scale)?.into_exemplar(),
                None,
            )),
            Self::Maps(files) => {
                let (exemplar, set) = files.load()?;
                Ok((apply_resize(exemplar, resize)?, Some(set)))
            }
        }
    }

    /// The file that names the exemplar in messages (a set's first map).
    pub fn main_path(&self) -> &Path {
        match self {
            Self::Image(path) | Self::Volume(path) => path,
            Self::Maps(files) => &files.files[0],
        }
    }

    /// For the run's checkpoint: absolute paths, so `--resume` works from any folder. A single
    /// image is its path; a map set is JSON.
    pub(super) fn to_meta(&self) -> String {
        let absolute = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        match self {
            Self::Image(path) | Self::Volume(path) => absolute(path).to_string_lossy().into_owned(),
            Self::Maps(files) => serde_json::to_string(&MapFiles {
                files: files.files.iter().map(absolute).collect(),
                ..files.clone()
            })
            .expect("the map files serialise"),
        }
    }

    pub(super) fn from_meta(meta: &str, checkpoint: &Path) -> Result<Self> {
        if meta.starts_with('{') {
            serde_json::from_str(meta)
                .map(Self::Maps)
                .map_err(|e| crate::file_error!(&checkpoint, "unreadable exemplar map list ({e})",))
        } else {
            Ok(PathBuf::from(meta).into())
        }
    }
}

impl Trainer {
    /// The first pixel (or voxel) of a random crop of the exemplar for sample `s`, drawn from
    /// stream `purpose`, in array order over the crop's axes; a crop read every `stride`-th
    /// pixel ([`Scale::Coarse`]) spans `(crop - 1) · stride + 1` pixels.
    pub(super) fn crop_origin(
        &self,
        purpose: u64,
        s: usize,
        counters: &[u64],
        stride: usize,
    ) -> Vec<usize> {
        let shape = self.exemplar.shape(self.kind.crop_axes());
        let extra = shape.len() - 2;
        let span = (self.config.crop - 1) * stride + 1;
        (0..shape.len())
            .map(|axis| {
                // Rows and columns draw as an image's crop does (0, 1); a volume's depth draws 2.
                let draw = if axis < extra { 2 + axis } else { axis - extra };
                let range = shape[axis] - span + 1;
                let mut k = vec![purpose, s as u64, draw as u64];
                k.extend_from_slice(counters);
                ((uniform(self.config.seed, &k) * range as f32) as usize).min(range - 1)
            })
            .collect()
    }

    /// The rows of the crop at `origin` read every `stride`-th pixel, in row-major order over
    /// the crop's leading axes: each the stretch of the exemplar (every channel, interleaved as
    /// it stores them) from the row's first pixel to its last, so `stride` 1 gives `crop`
    /// pixels and a coarse row is read with `chunks_exact(channels).step_by(stride)`.
    pub(super) fn crop_rows(
        &self,
        origin: &[usize],
        stride: usize,
    ) -> impl Iterator<Item = &[f32]> + '_ {
        let (s, ex, c) = (self.config.crop, &self.exemplar, self.exemplar.channels);
        let shape = ex.shape(origin.len());
        let leading = s.pow(origin.len() as u32 - 1);
        let span = (s - 1) * stride + 1;
        let origin = origin.to_vec();
        (0..leading).map(move |r| {
            // The row's index along each leading axis, last leading axis fastest.
            let mut flat = 0;
            let mut rest = r;
            let mut index = vec![0; origin.len() - 1];
            for a in (0..origin.len() - 1).rev() {
                index[a] = rest % s;
                rest /= s;
            }
            for a in 0..origin.len() - 1 {
                flat = flat * shape[a] + origin[a] + index[a] * stride;
            }
            let from = (flat * shape[origin.len() - 1] + origin[origin.len() - 1]) * c;
            &ex.values[from..from + span * c]
        })
    }

    /// The density input of the crop at `origin`: the mean |sdf| of its truncated SDF, through
    /// [`crate::condition::density_input`].
    pub(super) fn crop_density(&self, origin: &[usize]) -> f32 {
        let points = self.config.crop.pow(origin.len() as u32);
        let total: f64 = self
            .crop_rows(origin, 1)
            .map(|row| row.iter().map(|v| v.abs() as f64).sum::<f64>())
            .sum();
        crate::condition::density_input((total / points as f64) as f32)
    }

    /// Points of one crop: `crop²` pixels, or `crop³` voxels for a volume run.
    pub(super) fn crop_points(&self) -> usize {
        self.config.crop.pow(self.kind.crop_axes() as u32)
    }

    /// A crop's spatial shape as the critic takes it: `[depth, crop, crop]`, depth 1 in 2D.
    pub(super) fn crop_shape(&self) -> [usize; 3] {
        let s = self.config.crop;
        [if self.kind.crop_axes() == 3 { s } else { 1 }, s, s]
    }

    /// The critic's input channels: the exemplar's, and one for a condition.
    pub(super) fn critic_channels(&self) -> usize {
        self.exemplar.channels + self.kind.conditioned() as usize
    }

    /// The condition slice `[points]` of the crop at `origin` read every `stride`-th pixel:
    /// guidance over the exemplar, or the crop's density at every point; empty for an
    /// unconditioned run.
    pub(super) fn crop_condition(&self, origin: &[usize], stride: usize) -> Vec<f32> {
        let (crop, ex) = (self.config.crop, &self.exemplar);
        match &self.kind {
            RunKind::Volume { density: true } => {
                vec![self.crop_density(origin); self.crop_points()]
            }
            RunKind::Image { guide: Some(g) } => (0..crop * crop)
                .map(|q| {
                    let row = origin[0] + q / crop * stride;
                    let col = origin[1] + q % crop * stride;
                    g.at(row as i64, col as i64, ex.width, ex.height)
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// Random real crops for the counters' step at `scale` (a coarse crop is read every
    /// `coarse_stride`-th pixel): the exemplar's channels, then the condition.
    ///
    /// # Shapes
    /// - output: `[batch, channels (+ 1), depth, crop, crop]` (depth 1 for 2D crops)
    pub fn real_batch(&self, counters: &[u64], scale: Scale) -> Tensor<5> {
        let (b, s, c) = (self.config.batch, self.config.crop, self.exemplar.channels);
        let cg = c + self.kind.conditioned() as usize;
        let (n, stride) = (self.crop_points(), self.stride(scale));
        let mut data = vec![0f32; b * cg * n];
        for (i, sample) in data.chunks_mut(cg * n).enumerate() {
            let origin = self.crop_origin(scale.real_crop_stream(), i, counters, stride);
            for (r, row) in self.crop_rows(&origin, stride).enumerate() {
                for (x, px) in row.chunks_exact(c).step_by(stride).enumerate() {
                    for (ch, v) in px.iter().enumerate() {
                        sample[ch * n + r * s + x] = *v;
                    }
                }
            }
            let condition = self.crop_condition(&origin, stride);
            sample[c * n..].copy_from_slice(&condition);
        }
        let depth = if self.kind.crop_axes() == 3 { s } else { 1 };
        Tensor::from_data(TensorData::new(data, [b, cg, depth, s, s]), &self.device)
    }
}
