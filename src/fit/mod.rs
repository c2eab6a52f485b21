//! `ipfn fit`: a photograph turned into an exactly periodic, seamless tile by a periodic
//! sinusoidal network (Paz, Novello and Velho, "Implicit Neural Representation of Tileable
//! Material Textures"; their code is MR-Net, visgraf/mrnet). Not an IPFN: one network is one
//! texture, with no random samples, so it is its own command and its own model kind.
//!
//! - [`network`]: the network (integer first-layer frequencies, SIREN hidden layers, stages).
//! - [`fused`]: its CPU forward with exact tangents and hand-written backward (`gemm`).
//! - [`reference`]: the same with burn tensors and autodiff, on any device.
//! - [`target`]: the Poisson seam loss's targets (colours, gradients, λ, masks), batches.
//! - [`run`]: the fitting loop, run folder, checkpoints and resume.
//! - [`render`]: painting the tile at any size and level of detail.
//! - [`report`]: how well a tile matches its photo and how seamlessly it tiles.
//! - [`crossfade`]: the classic "make seamless" filter, for comparison.

pub mod crossfade;
pub mod fused;
pub mod network;
pub mod reference;
pub mod render;
pub mod report;
pub mod request;
pub mod run;
pub mod target;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::exemplar::Exemplar;
use crate::input_error;
use crate::maps::MapFiles;
pub use network::{NetworkShape, PeriodicNet, StageShape};
pub use render::TilePainter;
pub use report::{MapTileReport, TileReport};
pub use run::{FitEnd, Fitter};

/// The settings of a fit. Every field has a default; `ipfn fit`'s flags set them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FitConfig {
    /// The photo (or, with `maps`, none).
    pub photo: Option<PathBuf>,
    /// A material map set fitted by one network.
    pub maps: Option<MapFiles>,
    /// A mask of the photo's size: pixels at or below half gray are left out of the loss.
    pub mask: Option<PathBuf>,
    /// The tile's period in photo pixels `[rows, cols]`; `None` takes the photo's size. A
    /// photo holding several periods of a pattern fits one period from all of them.
    pub period: Option<[usize; 2]>,
    pub seed: u64,
    /// The highest frequency (cycles per period, per axis) of the first layer's last stage; 0
    /// picks a sixteenth of the shorter side (32 for 512 pixels: the hidden sine layers add
    /// harmonics above it). At most half the shorter side (Nyquist).
    pub band_limit: usize,
    /// Stages from low to high frequencies (levels of detail, as a mip-map's): stage `s` of
    /// `S` holds first-layer frequencies up to `band_limit / 2^(S-1-s)` and fits what the
    /// stages below left of the photo filtered for `1 / 2^(S-1-s)` of its resolution.
    pub stages: usize,
    /// First-layer frequencies of the last stage (lower stages: a quarter, at least 16); 0
    /// sizes them with the hidden layers ([`FitConfig::widths`]).
    pub frequencies: usize,
    /// Hidden sine layers of the last stage (lower stages: a quarter of each width); empty
    /// sizes them for the tile ([`FitConfig::widths`]).
    pub hidden: Vec<usize>,
    /// SIREN's ω0 of the hidden layers.
    pub omega0: f32,
    /// Adam's learning rate, decayed along a cosine to 1% by each stage's end.
    pub lr: f64,
    /// Pixels per step.
    pub batch: usize,
    /// The outer part of the distance from the centre to the border where the seam term
    /// weighs in (0 turns it off: the tile then keeps the photo's own seam). `None` takes 0.1,
    /// or more on a small photo so the band is at least 12 pixels deep.
    pub seam_band: Option<f32>,
    /// Steps per stage (the last stage's `N`, lower stages `N / 4`); empty until planned
    /// from `time`.
    pub iterations: Vec<u64>,
    /// A time budget (`15m`) the steps are planned from.
    pub time: Option<String>,
    /// Steps between checkpoints.
    pub checkpoint_every: u64,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            photo: None,
            maps: None,
            mask: None,
            period: None,
            seed: 0,
            band_limit: 0,
            stages: 3,
            frequencies: 0,
            hidden: Vec::new(),
            omega0: 30.0,
            lr: 5e-4,
            batch: 8192,
            seam_band: None,
            iterations: Vec::new(),
            time: None,
            checkpoint_every: 250,
        }
    }
}

impl FitConfig {
    /// Steps per stage for `last` steps of the last stage: a quarter of them for each lower
    /// stage, whose blurred targets converge fast.
    pub fn stage_steps(last: u64, stages: usize) -> Vec<u64> {
        let mut steps = vec![(last / 4).max(1); stages.saturating_sub(1)];
        steps.push(last);
        steps
    }

    /// The band limit used for a tile of `[rows, cols]` pixels.
    pub fn band(&self, period: [usize; 2]) -> usize {
        match self.band_limit {
            0 => (period[0].min(period[1]) / 16).max(1),
            b => b,
        }
    }

    /// The seam band for a photo of `[rows, cols]` pixels (see `seam_band`).
    pub fn seam_band_for(&self, photo: [usize; 2]) -> f32 {
        let half = photo[0].min(photo[1]) as f32 / 2.0;
        self.seam_band
            .unwrap_or((12.0 / half.max(1.0)).clamp(0.1, 1.0))
    }

    /// The tile's period for a photo of `[rows, cols]` pixels.
    pub fn period_for(&self, photo: [usize; 2]) -> [usize; 2] {
        self.period.unwrap_or(photo)
    }

    /// Checks the settings against a photo of `[rows, cols]` pixels.
    pub fn validate(&self, photo: [usize; 2], source: &str) -> Result<()> {
        let period = self.period_for(photo);
        let nyquist = period[0].min(period[1]) / 2;
        if period.contains(&0) {
            return Err(input_error!(
                "{source}: a period of {}x{} pixels: a tile needs at least one pixel a side",
                period[1],
                period[0]
            ));
        }
        if period[0] > photo[0] || period[1] > photo[1] {
            return Err(input_error!(
                "--period {}x{}: larger than the {}x{} photo; give at most its size",
                period[1],
                period[0],
                photo[1],
                photo[0]
            ));
        }
        if self.band(period) > nyquist {
            return Err(crate::setting_error!(
                "--band-limit",
                self.band_limit,
                "above what a {}x{} tile's pixels can hold (Nyquist: at most {nyquist} cycles per period)",
                period[1],
                period[0]
            ));
        }
        let bad = |what: String| Err(input_error!("{what}"));
        if !(1..=8).contains(&self.stages) {
            return bad(format!("--stages {}: expected 1 to 8", self.stages));
        }
        if self.frequencies > 4096 {
            return bad(format!(
                "--frequencies {}: expected 1 to 4096",
                self.frequencies
            ));
        }
        if self.hidden.len() > 16 || self.hidden.iter().any(|&w| !(1..=4096).contains(&w)) {
            return bad(format!(
                "--hidden {:?}: expected 1 to 16 layer widths of 1 to 4096",
                self.hidden
            ));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(positive(self.lr) && positive(self.omega0 as f64)) {
            return bad("--lr and omega0 must be positive and finite".into());
        }
        if !(1..=1 << 22).contains(&self.batch) {
            return bad(format!("--batch {}: expected 1 to 4194304", self.batch));
        }
        if let Some(band) = self.seam_band.filter(|b| !(0.0..=1.0).contains(b)) {
            return bad(format!("--seam-band {band}: expected 0 to 1"));
        }
        if self.checkpoint_every == 0 {
            return bad("checkpoint_every must be at least 1".into());
        }
        Ok(())
    }

    /// The last stage's first-layer frequencies and hidden widths for a tile of `period`:
    /// as given, else two hidden layers of 288 and 256 frequencies (measured best on 512²
    /// photos), narrowed in steps of 16 until the whole network holds at most 3/4 of a
    /// parameter per pixel (fewer parameters than pixels), and at least 32 wide.
    pub fn widths(&self, period: [usize; 2], channels: usize) -> (usize, Vec<usize>) {
        let pixels = period[0] * period[1];
        let frequencies = |w: usize| match self.frequencies {
            0 => (w * 8 / 9).max(16),
            f => f,
        };
        if !self.hidden.is_empty() {
            return (frequencies(self.hidden[0]), self.hidden.clone());
        }
        let mut width = 288;
        while width > 32 {
            let mut trial = self.clone();
            trial.frequencies = frequencies(width);
            trial.hidden = vec![width, width];
            if trial
                .shape_with(period, channels, trial.frequencies, &trial.hidden)
                .parameters()
                * 4
                <= pixels * 3
            {
                break;
            }
            width -= 16;
        }
        (frequencies(width), vec![width, width])
    }

    /// The network's shape for a tile of `[rows, cols]` pixels with `channels`.
    pub fn shape(&self, period: [usize; 2], channels: usize) -> NetworkShape {
        let (frequencies, hidden) = self.widths(period, channels);
        self.shape_with(period, channels, frequencies, &hidden)
    }

    fn shape_with(
        &self,
        period: [usize; 2],
        channels: usize,
        frequencies: usize,
        hidden: &[usize],
    ) -> NetworkShape {
        let band = self.band(period).max(1);
        let s = self.stages;
        let stages = (0..s)
            .map(|i| {
                let upper = (band >> (s - 1 - i)).max(1);
                let last = i + 1 == s;
                let quarter = |w: usize| if last { w } else { (w / 4).max(16) };
                let count = quarter(frequencies);
                StageShape {
                    frequencies: network::half_band(
                        0,
                        upper,
                        count,
                        crate::latent::derive_seed(self.seed, &[0xF0, i as u64]),
                    ),
                    hidden: hidden.iter().map(|&w| quarter(w)).collect(),
                }
            })
            .collect();
        NetworkShape {
            period,
            channels,
            omega0: self.omega0,
            stages,
        }
    }

    /// Stage `stage`'s level of the photo, as a mip-map's: the last stage's is the photo, the
    /// one below it the photo filtered for half the resolution, then a quarter, and so on
    /// (a Gaussian of `0.38 * 2^j` pixels for `j` halvings, which halves the response at the
    /// halved resolution's Nyquist frequency).
    pub fn level(&self, photo: &Exemplar, stage: usize) -> Exemplar {
        let halvings = self.stages.saturating_sub(stage + 1) as i32;
        if halvings == 0 {
            return photo.clone();
        }
        let sigma = 0.38 * 2f32.powi(halvings);
        target::blur(photo, [sigma, sigma])
    }
}

/// Peak signal-to-noise ratio in dB of `a` against `b` (values in [-1, 1], so the peak is 2),
/// over the pixels where `keep` holds.
pub fn psnr(a: &[f32], b: &[f32], channels: usize, keep: impl Fn(usize) -> bool) -> f64 {
    let (mut sum, mut count) = (0f64, 0usize);
    for (i, (pa, pb)) in a
        .chunks_exact(channels)
        .zip(b.chunks_exact(channels))
        .enumerate()
    {
        if keep(i) {
            for (x, y) in pa.iter().zip(pb) {
                let e = (x.clamp(-1.0, 1.0) - y) as f64;
                sum += e * e;
            }
            count += channels;
        }
    }
    let mse = sum / count.max(1) as f64;
    10.0 * (4.0 / mse.max(1e-20)).log10()
}

#[cfg(test)]
mod tests;
