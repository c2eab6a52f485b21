//! The exemplar a run learns from: an image (PNG, JPEG, EXR) or a signed-distance volume
//! (`.npy`), as values in [-1, 1], row-major `[depth, height, width, channels]` (depth 1 for an
//! image).

use std::path::Path;

use crate::error::Result;
use crate::io::{extension, read_npy};

/// An exemplar image: values scaled to [-1, 1], row-major `[height, width, channels]`.
///
/// Channels are kept as the file has them: gray (1), gray + alpha (2), RGB (3), RGBA (4). Alpha
/// is learned as one more channel, so synthesized output carries alpha too (useful for cut-outs
/// such as foliage); flatten the image first if alpha holds nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct Exemplar {
    pub width: usize,
    pub height: usize,
    /// 1 for an image; the slices of a volume exemplar (`values` is then `[depth, height,
    /// width, channels]`).
    pub depth: usize,
    pub channels: usize,
    pub values: Vec<f32>,
}

impl Exemplar {
    /// From values in [0, 1], `[height, width, channels]`.
    pub fn from_unit(width: usize, height: usize, channels: usize, unit: &[f32]) -> Self {
        assert_eq!(unit.len(), width * height * channels);
        Self {
            width,
            height,
            depth: 1,
            channels,
            values: unit.iter().map(|v| v.clamp(0.0, 1.0) * 2.0 - 1.0).collect(),
        }
    }

    /// Resamples to `width x height` with a Lanczos-3 filter (scaled to the output's footprint
    /// when shrinking, so it anti-aliases), any number of channels (a map set's stack too), four
    /// at a time.
    pub fn resized(&self, width: usize, height: usize) -> Self {
        // The image crate's float resampling clamps to [0, 1], so resample unit values.
        let c = self.channels;
        let mut unit = vec![0f32; width * height * c];
        for first in (0..c).step_by(4) {
            let group = (c - first).min(4);
            let mut rgba = image::Rgba32FImage::new(self.width as u32, self.height as u32);
            for (i, px) in rgba.pixels_mut().enumerate() {
                let mut v = [0f32; 4];
                for (k, slot) in v.iter_mut().enumerate().take(group) {
                    *slot = (self.values[i * c + first + k] + 1.0) * 0.5;
                }
                *px = image::Rgba(v);
            }
            let out = image::imageops::resize(
                &rgba,
                width as u32,
                height as u32,
                image::imageops::FilterType::Lanczos3,
            );
            for (i, p) in out.pixels().enumerate() {
                unit[i * c + first..i * c + first + group].copy_from_slice(&p.0[..group]);
            }
        }
        Self::from_unit(width, height, c, &unit)
    }

    /// The centre `side x side` pixels (at most) of an image exemplar.
    pub fn centre(&self, side: usize) -> Self {
        let (h, w) = (self.height.min(side), self.width.min(side));
        self.window([(self.height - h) / 2, (self.width - w) / 2], [h, w])
    }

    /// The `[height, width]` window whose top-left pixel is `[top, left]` (clipped to the image).
    pub fn window(&self, [top, left]: [usize; 2], [height, width]: [usize; 2]) -> Self {
        let (h, w, c) = (self.height, self.width, self.channels);
        let (top, left) = (top.min(h), left.min(w));
        let (ch, cw) = (height.min(h - top), width.min(w - left));
        if (ch, cw) == (h, w) {
            return self.clone();
        }
        let mut values = Vec::with_capacity(ch * cw * c);
        for y in top..top + ch {
            let from = (y * w + left) * c;
            values.extend_from_slice(&self.values[from..from + cw * c]);
        }
        Self {
            width: cw,
            height: ch,
            depth: 1,
            channels: c,
            values,
        }
    }

    /// Whether every pixel's first three channels are equal (a gray image stored as RGB).
    pub fn is_gray(&self) -> bool {
        let c = self.channels;
        c >= 3
            && self
                .values
                .chunks_exact(c)
                .all(|p| (p[0] - p[1]).abs() < 1e-3 && (p[0] - p[2]).abs() < 1e-3)
    }

    /// The first channel alone, and alpha if there is one (RGBA becomes gray + alpha): for a
    /// gray image stored as RGB.
    pub fn to_gray(&self) -> Self {
        let c = self.channels;
        let keep: Vec<usize> = if c == 4 { vec![0, 3] } else { vec![0] };
        Self {
            channels: keep.len(),
            values: self
                .values
                .chunks_exact(c)
                .flat_map(|p| keep.iter().map(move |&k| p[k]))
                .collect(),
            ..*self
        }
    }

    /// The channels `range` of every pixel: one map of a map set's stacked exemplar.
    pub fn select(&self, range: std::ops::Range<usize>) -> Self {
        let c = self.channels;
        Self {
            channels: range.len(),
            values: self
                .values
                .chunks_exact(c)
                .flat_map(|p| p[range.clone()].iter().copied())
                .collect(),
            ..*self
        }
    }

    /// The exemplar's extent over its last `axes` axes, in array order: `[height, width]` or
    /// `[depth, height, width]`.
    pub fn shape(&self, axes: usize) -> Vec<usize> {
        let all = [self.depth, self.height, self.width];
        all[3 - axes..].to_vec()
    }

    /// A 64-bit fingerprint of the pixels (resume checks that the exemplar did not change).
    pub fn fingerprint(&self) -> u64 {
        let mut h = crate::latent::mix64(
            (self.width as u64) << 32 ^ self.height as u64 ^ (self.channels as u64) << 60,
        );
        if self.depth > 1 {
            h = crate::latent::mix64(h ^ self.depth as u64);
        }
        for v in &self.values {
            h = crate::latent::mix64(h ^ v.to_bits() as u64);
        }
        h
    }
}

/// Reads a PNG (8/16-bit), JPEG or EXR exemplar.
pub fn read_exemplar(path: &Path) -> Result<Exemplar> {
    read_exemplar_with_bits(path).map(|(exemplar, _)| exemplar)
}

/// Reads an exemplar and the bits per channel of its file: 8 or 16 for PNG and JPEG (values
/// keep that precision as f32), 32 for EXR (float).
pub fn read_exemplar_with_bits(path: &Path) -> Result<(Exemplar, u8)> {
    if !path.exists() {
        return Err(crate::file_error!(&path, "no such file"));
    }
    let ext = extension(path);
    if ext == "exr" {
        return read_exr_exemplar(path).map(|e| (e, 32));
    }
    let image = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| crate::file_error!(&path, "cannot read: {e}"))?
        .decode()
        .map_err(|e| crate::file_error!(&path, "not a readable PNG or JPEG image ({e})"))?;
    let (w, h) = (image.width() as usize, image.height() as usize);
    let bits = match image.color().bytes_per_pixel() / image.color().channel_count() {
        1 => 8,
        2 => 16,
        _ => 32,
    };
    use image::ColorType::*;
    let (channels, unit): (usize, Vec<f32>) = match image.color() {
        L8 | L16 => (1, image.to_luma32f().into_raw()),
        La8 | La16 => (2, image.to_luma_alpha32f().into_raw()),
        Rgb8 | Rgb16 | Rgb32F => (3, image.to_rgb32f().into_raw()),
        Rgba8 | Rgba16 | Rgba32F => (4, image.to_rgba32f().into_raw()),
        other => {
            return Err(crate::file_error!(
                &path,
                "unsupported pixel format {other:?}; use gray, RGB or RGBA",
            ));
        }
    };
    if w == 0 || h == 0 {
        return Err(crate::file_error!(&path, "the image is empty"));
    }
    Ok((Exemplar::from_unit(w, h, channels, &unit), bits))
}

/// EXR exemplars: channels Y (gray) or R, G, B, optionally A; values expected in [0, 1]
/// (outside is clipped).
/// The most bytes an EXR exemplar's layers may claim (as the `image` crate's default limit for
/// PNG and JPEG): headers are checked before any pixel is allocated.
pub const MAX_EXR_BYTES: usize = 512 << 20;

fn read_exr_exemplar(path: &Path) -> Result<Exemplar> {
    use exr::prelude::*;
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| crate::file_error!(&path, "not a readable EXR image ({e})"))?;
    for header in meta.headers.iter() {
        let size = header.layer_size;
        let bytes = size
            .0
            .checked_mul(size.1)
            .and_then(|p| p.checked_mul(header.channels.list.len().max(1)))
            .and_then(|v| v.checked_mul(4));
        if bytes.is_none_or(|b| b > MAX_EXR_BYTES) {
            return Err(crate::file_error!(
                &path,
                "its header claims a {}x{} layer of {} channels, over the {} MiB an exemplar may take",
                size.0,
                size.1,
                header.channels.list.len(),
                MAX_EXR_BYTES >> 20,
            ));
        }
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| crate::file_error!(&path, "not a readable EXR image ({e})"))?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    let find = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
    };
    let order: Vec<&str> = if find("R").is_some() && find("G").is_some() && find("B").is_some() {
        vec!["R", "G", "B", "A"]
    } else if find("Y").is_some() {
        vec!["Y", "A"]
    } else {
        return Err(crate::file_error!(
            &path,
            "EXR needs channels R, G, B (and A) or Y",
        ));
    };
    let chans: Vec<_> = order.iter().filter_map(|n| find(n)).collect();
    let c = chans.len();
    let mut unit = vec![0f32; w * h * c];
    for (k, ch) in chans.iter().enumerate() {
        for i in 0..w * h {
            unit[i * c + k] = ch.sample_data.value_by_flat_index(i).to_f32();
        }
    }
    Ok(Exemplar::from_unit(w, h, c, &unit))
}

/// A volume of values, row-major `[depth, height, width, channels]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    pub depth: usize,
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    pub values: Vec<f32>,
}

/// Reads a signed-distance volume (`.npy`, float, `D x H x W` or `D x H x W x 1`) as the authors
/// prepare one: scaled by `sdf_scale` and clamped to [-1, 1] (a truncated SDF).
pub fn read_sdf_volume(path: &Path, sdf_scale: f32) -> Result<Volume> {
    if !path.exists() {
        return Err(crate::file_error!(&path, "no such file"));
    }
    let (shape, values) = read_npy(path)?;
    let [depth, height, width] = match shape[..] {
        [d, h, w] | [d, h, w, 1] => [d, h, w],
        _ => {
            return Err(crate::file_error!(
                &path,
                "a volume must be a 3D float array (D x H x W), this one has shape {shape:?}",
            ));
        }
    };
    if depth == 0 || height == 0 || width == 0 {
        return Err(crate::file_error!(&path, "the volume is empty"));
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(crate::file_error!(
            &path,
            "the volume holds NaN or infinite values",
        ));
    }
    Ok(Volume {
        depth,
        height,
        width,
        channels: 1,
        values: values
            .iter()
            .map(|v| (v * sdf_scale).clamp(-1.0, 1.0))
            .collect(),
    })
}

impl Volume {
    /// The volume as a training exemplar (`[depth, height, width, 1]`, values in [-1, 1]).
    pub fn into_exemplar(self) -> Exemplar {
        Exemplar {
            width: self.width,
            height: self.height,
            depth: self.depth,
            channels: self.channels,
            values: self.values,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Exemplar;

    /// A `height x width` one-channel exemplar whose pixel (y, x) holds `10 y + x`.
    fn numbered(height: usize, width: usize) -> Exemplar {
        Exemplar {
            width,
            height,
            depth: 1,
            channels: 1,
            values: (0..height)
                .flat_map(|y| (0..width).map(move |x| (10 * y + x) as f32))
                .collect(),
        }
    }

    #[test]
    fn a_window_holds_the_pixels_below_and_right_of_its_corner_clipped_to_the_image() {
        let image = numbered(4, 5);
        let w = image.window([1, 2], [2, 2]);
        assert_eq!((w.height, w.width), (2, 2));
        assert_eq!(w.values, vec![12.0, 13.0, 22.0, 23.0]);
        let clipped = image.window([3, 3], [4, 4]);
        assert_eq!((clipped.height, clipped.width), (1, 2));
        assert_eq!(clipped.values, vec![33.0, 34.0]);
        let centre = image.centre(2);
        assert_eq!(centre.values, vec![11.0, 12.0, 21.0, 22.0]);
    }
}
