//! `ipfn draw` as a request: a drawn exemplar (one of [`crate::procedural`]'s patterns)
//! written to a file, so a user can try every command without a photo of their own.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::input_error;
use crate::io::{ImageWriter, OutputFormat, VolumeWriter};
use crate::procedural;

/// The patterns `ipfn draw` knows, as the user names them.
pub const PATTERNS: &str = "bricks, weave, stripes, graded, material or gyroid";

/// One drawing: the pattern, its size in pixels (voxels for `gyroid`) and where it goes.
#[derive(Debug, Clone)]
pub struct DrawRequest {
    pub pattern: String,
    pub size: usize,
    /// `gyroid`: the period in voxels (default 32).
    pub period: Option<usize>,
    /// `gyroid`: a sheet thickened along x (porosity graded across the volume).
    pub graded: bool,
    /// A PNG, a folder for `material`, a volume (`.npy`, `.raw`) for `gyroid`.
    pub out: PathBuf,
}

impl DrawRequest {
    /// Draws and writes; returns the line that says what was written.
    pub fn draw(&self) -> Result<String> {
        if self.size == 0 {
            return Err(crate::setting_error!("--size", 0, "must be at least 1"));
        }
        match self.pattern.as_str() {
            "gyroid" => self.gyroid(),
            "material" => self.material(),
            _ => self.picture(),
        }
    }

    fn gyroid(&self) -> Result<String> {
        let (n, period) = (self.size, self.period.unwrap_or(32));
        if period < 2 {
            return Err(crate::setting_error!(
                "--period",
                period,
                "must be at least 2 voxels"
            ));
        }
        let sdf = match self.graded {
            true => procedural::graded_gyroid_sdf(n, period as f32, 0.1, 0.9),
            false => procedural::gyroid_sdf(n, period as f32, 0.4),
        };
        let mut writer = VolumeWriter::create(&self.out, n, n, n, 1)?;
        writer.write_slab(&sdf)?;
        writer.finish()?;
        Ok(format!(
            "wrote {} ({n}x{n}x{n} gyroid sheet SDF, period {period} voxels)",
            self.out.display()
        ))
    }

    fn material(&self) -> Result<String> {
        let n = self.size;
        std::fs::create_dir_all(&self.out)
            .map_err(|e| crate::file_error!(&self.out, "cannot create folder: {e}"))?;
        let maps = procedural::material(n, n, 32);
        for ((name, channels), unit) in procedural::MATERIAL_MAPS.iter().zip(maps) {
            let path = self.out.join(format!("{name}.png"));
            write_png16(&path, n, *channels, &unit)?;
        }
        Ok(format!(
            "wrote {}/{{albedo,normal,roughness,height}}.png ({n}x{n} 16-bit material)",
            self.out.display()
        ))
    }

    fn picture(&self) -> Result<String> {
        let n = self.size;
        let unit = match self.pattern.as_str() {
            "bricks" => procedural::bricks(n, n, 32, 16),
            "weave" => procedural::weave(n, n, 8),
            "stripes" => procedural::stripes(n, n, 40.0),
            "graded" => procedural::graded_stripes(n, n, 16.0, 0.15, 0.85),
            other => return Err(input_error!("unknown pattern '{other}'; use {PATTERNS}")),
        };
        crate::io::write_png(&self.out, n, n, 3, &to_signed(&unit))?;
        Ok(format!(
            "wrote {} ({n}x{n} {})",
            self.out.display(),
            self.pattern
        ))
    }
}

/// [0, 1] values as the [-1, 1] the writers take.
fn to_signed(unit: &[f32]) -> Vec<f32> {
    unit.iter().map(|v| v * 2.0 - 1.0).collect()
}

fn write_png16(path: &Path, n: usize, channels: usize, unit: &[f32]) -> Result<()> {
    let mut writer = ImageWriter::create(path, OutputFormat::Png { bits: 16 }, n, n, channels)?;
    writer.write_rows(&to_signed(unit))?;
    writer.finish()
}
