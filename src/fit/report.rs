//! How well a fitted tile matches its photo and how seamlessly it tiles: one computation for
//! `ipfn fit`'s closing line and for `ipfn eval` of a tile.

use serde::Serialize;

use super::{FitConfig, TilePainter};
use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::input_error;
use crate::maps::MapSet;
use crate::metrics::{ScoreSpread, SeamScore};

/// A fitted tile against its photo, as `ipfn eval --json` prints it.
#[derive(Debug, Clone, Serialize)]
pub struct TileReport {
    /// PSNR in dB of the tile painted at the photo's size against the photo (masked-out pixels
    /// left out).
    pub psnr: f64,
    /// The same outside the seam band, where the fit need not bend the photo.
    pub psnr_interior: f64,
    /// Seam score of one period laid 2x2 (about 1 is seamless).
    pub seam_tile: SeamScore,
    /// Seam score of the photo itself laid 2x2, for comparison.
    pub seam_photo: SeamScore,
    /// The spread of the photo's own lines' scores: a seam within it shows no more than a line
    /// of the photo does.
    pub seam_photo_lines: Option<ScoreSpread>,
    /// A map set's maps, each measured alone (empty for a photo).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub maps: Vec<MapTileReport>,
}

/// One map of a fitted map set against that map of the scan.
#[derive(Debug, Clone, Serialize)]
pub struct MapTileReport {
    pub name: String,
    pub psnr: f64,
    pub psnr_interior: f64,
    pub seam_tile: SeamScore,
    pub seam_photo_lines: Option<ScoreSpread>,
}

/// The channels `range` of every pixel of `values` (`[.., channels]`).
fn pick(values: &[f32], channels: usize, range: &std::ops::Range<usize>) -> Vec<f32> {
    values
        .chunks_exact(channels)
        .flat_map(|p| p[range.clone()].iter().copied())
        .collect()
}

impl TileReport {
    /// Paints the tile at the photo's size and one period, and compares. `mask` (the photo's
    /// pixels, above 0.5 kept) leaves pixels out of the PSNR; `config` gives the seam band.
    pub fn of(
        painter: &TilePainter,
        photo: &Exemplar,
        mask: Option<&[f32]>,
        config: &FitConfig,
        set: Option<&MapSet>,
    ) -> Result<Self> {
        let period = painter.net.shape.period;
        let (h, w, c) = (photo.height, photo.width, painter.net.shape.channels);
        if photo.channels != c || h < period[0] || w < period[1] {
            return Err(input_error!(
                "{w}x{h} with {} channels, but the tile has a {}x{} period and {c} channels: give the photo it was fitted to",
                photo.channels,
                period[1],
                period[0]
            ));
        }
        let clamped = |v: Vec<f32>| -> Vec<f32> { v.iter().map(|v| v.clamp(-1.0, 1.0)).collect() };
        let tile = clamped(painter.render([0, 0], [h, w]));
        let one = match period == [h, w] {
            true => tile.clone(),
            false => clamped(painter.render([0, 0], period)),
        };
        let band = super::target::seam_mask(h, w, config.seam_band_for([h, w]));
        let kept = |i: usize| mask.is_none_or(|m| m[i] > 0.5);
        let maps = match set {
            None => Vec::new(),
            Some(set) => set
                .maps
                .iter()
                .zip(set.ranges())
                .map(|(map, r)| {
                    let (t, o, p) = (
                        pick(&tile, c, &r),
                        pick(&one, c, &r),
                        pick(&photo.values, c, &r),
                    );
                    let mc = r.len();
                    Ok(MapTileReport {
                        name: map.name.clone(),
                        psnr: super::psnr(&t, &p, mc, kept),
                        psnr_interior: super::psnr(&t, &p, mc, |i| kept(i) && band[i] == 0.0),
                        seam_tile: crate::metrics::seam_score(&o, period[0], period[1], mc)?,
                        seam_photo_lines: crate::metrics::line_score_spread(&p, h, w, mc),
                    })
                })
                .collect::<Result<_>>()?,
        };
        Ok(Self {
            psnr: super::psnr(&tile, &photo.values, c, kept),
            psnr_interior: super::psnr(&tile, &photo.values, c, |i| kept(i) && band[i] == 0.0),
            seam_tile: crate::metrics::seam_score(&one, period[0], period[1], c)?,
            seam_photo: crate::metrics::seam_score(&photo.values, h, w, c)?,
            seam_photo_lines: crate::metrics::line_score_spread(&photo.values, h, w, c),
            maps,
        })
    }
}
