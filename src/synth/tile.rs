//! Tiling (paper §4.4): exactly periodic output. The latent lattice is wrapped and K is snapped
//! so that the tile spans a whole number of periods of every octave; the latent lattice scale is
//! snapped likewise so the tile spans a whole number of lattice cells. The generator is then
//! exactly periodic with the tile's size, on every axis (images and volumes alike).

use crate::error::Result;
use crate::input_error;

/// How K and the latent lattice were adjusted to make a tile.
#[derive(Debug, Clone, PartialEq)]
pub struct TileAdjustment {
    pub k_trained: Vec<f32>,
    pub k_used: Vec<f32>,
    pub latent_scale_trained: f32,
    pub latent_scale_used: Vec<f32>,
    /// Lattice period (cells) per axis.
    pub lattice_period: Vec<i64>,
}

impl TileAdjustment {
    /// One line for the user: how far K moved on each axis.
    pub fn describe(&self) -> String {
        let moved: Vec<String> = self
            .k_trained
            .iter()
            .zip(&self.k_used)
            .map(|(a, b)| format!("{a:.4} -> {b:.4} ({:+.2}%)", 100.0 * (b / a - 1.0)))
            .collect();
        let lat: Vec<String> = self
            .latent_scale_used
            .iter()
            .map(|s| format!("{:+.2}%", 100.0 * (s / self.latent_scale_trained - 1.0)))
            .collect();
        let axes = if self.k_used.len() == 3 {
            "depth, rows, cols"
        } else {
            "rows, cols"
        };
        format!(
            "tile: K snapped {} ({axes}); latent lattice {:?} cells, scale moved {}",
            moved.join(", "),
            self.lattice_period,
            lat.join(", ")
        )
    }
}

/// Makes the generator exactly periodic with `period` pixels (or voxels) per axis: snaps K so
/// the tile spans a whole number of periods of every octave, and the latent lattice scale so it
/// spans whole lattice cells. Returns what moved; the caller wraps the lattice with
/// `lattice_period`.
pub(crate) fn snap_to_tile(
    period: &[usize],
    spacing: f64,
    k: &mut [f32],
    latent_scale_trained: f32,
    latent_scale: &mut [f32],
) -> Result<TileAdjustment> {
    if period.contains(&0) {
        return Err(input_error!("--tile: tile size must be at least 1 pixel"));
    }
    let k_trained = k.to_vec();
    let mut lattice_period = Vec::new();
    for axis in 0..period.len() {
        let span = period[axis] as f64 * spacing;
        let ka = k_trained[axis] as f64;
        let cycles = (span / (2.0 * ka.abs())).round().max(1.0);
        k[axis] = (span / (2.0 * cycles)).copysign(ka) as f32;
        let cells = (span * latent_scale_trained as f64).round().max(1.0);
        latent_scale[axis] = (cells / span) as f32;
        lattice_period.push(cells as i64);
    }
    Ok(TileAdjustment {
        k_trained,
        k_used: k.to_vec(),
        latent_scale_trained,
        latent_scale_used: latent_scale.to_vec(),
        lattice_period,
    })
}
