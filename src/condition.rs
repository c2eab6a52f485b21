//! Conditioning (conditional IPFN, paper eq. 5): one more input `g` after the latent tells the
//! generator how the pattern changes across the surface, and the critic sees it as one more
//! channel. Two kinds of condition share that input:
//!
//! - **Guidance** ([`Guide`]), for images: a direction over the exemplar.
//! - **Density** ([`DensityRamp`], [`density_input`]), for volumes: the mean |sdf| of a crop
//!   (the paper's Fig. 7), so `synth --density` sets the porosity.
//!
//! [`Condition`] is the value a synthesis paints with, at any pixel of its frame.
//!
//! Guidance: in training, `g = a·X + b·Y + c` over the whole exemplar, with `X` and `Y` its normalised
//! column and row coordinates in [-1, 1]; each crop carries its own slice of `g`, as one more
//! channel for the critic and one more input for the generator. In synthesis, `g` comes from
//! a line over the output frame or from a grayscale image, which lets the user paint how the
//! pattern varies (for example a ramp the exemplar never had).

use std::str::FromStr;

use crate::error::{Error, Result};
use crate::input_error;

/// A guidance field over a frame of pixels.
#[derive(Debug, Clone, PartialEq)]
pub enum Guide {
    /// `g = a·X + b·Y + c`, with `X`, `Y` the frame's normalised column and row in [-1, 1].
    Line { a: f32, b: f32, c: f32 },
    /// One value per pixel of the frame (a grayscale image: `g = 2v - 1` for `v` in [0, 1]),
    /// row-major.
    Map {
        width: usize,
        height: usize,
        values: Vec<f32>,
    },
}

impl FromStr for Guide {
    type Err = Error;
    /// `x`, `y`, `-x`, `-y`, or `a,b,c`.
    fn from_str(s: &str) -> Result<Self> {
        let line = |a, b, c| Ok(Self::Line { a, b, c });
        match s.trim() {
            "x" => line(1.0, 0.0, 0.0),
            "-x" => line(-1.0, 0.0, 0.0),
            "y" => line(0.0, 1.0, 0.0),
            "-y" => line(0.0, -1.0, 0.0),
            other => {
                let parts: Vec<f32> = other
                    .split(',')
                    .map(|p| p.trim().parse::<f32>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|_| bad(other))?;
                match parts[..] {
                    [a, b, c] if parts.iter().all(|v| v.is_finite()) => line(a, b, c),
                    _ => Err(bad(other)),
                }
            }
        }
    }
}

fn bad(s: &str) -> Error {
    crate::setting_error!(
        "--guide",
        s,
        "expected x, y, -x, -y, a line a,b,c (g = a·x + b·y + c), or a grayscale image"
    )
}

impl Guide {
    /// Reads a guidance image: its first channel, `g = 2v - 1`.
    pub fn from_image(path: &std::path::Path) -> Result<Self> {
        let image = crate::exemplar::read_exemplar(path)?;
        let c = image.channels;
        Ok(Self::Map {
            width: image.width,
            height: image.height,
            values: image.values.chunks_exact(c).map(|p| p[0]).collect(),
        })
    }

    /// `--guide VALUE`: a line, or else an image file.
    pub fn parse_flag(value: &str) -> Result<Self> {
        match value.parse() {
            Ok(line) => Ok(line),
            Err(e) => {
                let path = std::path::Path::new(value);
                if path.extension().is_some() {
                    Self::from_image(path)
                } else {
                    Err(e)
                }
            }
        }
    }

    /// g at pixel `(row, col)` of a `width x height` frame (pixel centres).
    pub fn at(&self, row: i64, col: i64, width: usize, height: usize) -> f32 {
        match self {
            Self::Line { a, b, c } => {
                let x = ((col as f64 + 0.5) / width as f64 * 2.0 - 1.0) as f32;
                let y = ((row as f64 + 0.5) / height as f64 * 2.0 - 1.0) as f32;
                a * x + b * y + c
            }
            Self::Map {
                width: w,
                height: h,
                values,
            } => {
                let r = row.clamp(0, *h as i64 - 1) as usize;
                let c = col.clamp(0, *w as i64 - 1) as usize;
                values[r * w + c]
            }
        }
    }

    /// Checks that a map guide fits the output frame.
    pub fn check_frame(&self, width: usize, height: usize) -> Result<()> {
        match self {
            Self::Map {
                width: w,
                height: h,
                ..
            } if (*w, *h) != (width, height) => Err(input_error!(
                "--guide: the guidance image is {w}x{h} but the output is {width}x{height}; give an image of the output's size"
            )),
            _ => Ok(()),
        }
    }

    /// The line as the config stores it (`a,b,c`); `None` for a map.
    pub fn to_config(&self) -> Option<String> {
        match self {
            Self::Line { a, b, c } => Some(format!("{a},{b},{c}")),
            Self::Map { .. } => None,
        }
    }
}

/// Densities typical of truncated SDFs (mean |sdf| 0.1 to 0.4) are spread over about ±1 before
/// they reach the generator and the critic: fed raw, their small spread left a 300-iteration
/// model ignoring them (measured on the graded gyroid; with this scaling it followed a ramp).
pub const DENSITY_CENTER: f32 = 0.25;
pub const DENSITY_GAIN: f32 = 6.0;

/// The generator's input for density `d` (the mean |sdf| of a truncated SDF).
pub fn density_input(d: f32) -> f32 {
    (d - DENSITY_CENTER) * DENSITY_GAIN
}

/// The density a density-controlled volume model paints (the mean |sdf| of its truncated SDF):
/// `from` at column 0 of the volume, `to` at its last column, linear in between (constant when
/// they are equal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DensityRamp {
    pub from: f32,
    pub to: f32,
    /// The volume's width in voxels (the ramp's frame).
    pub width: usize,
}

impl DensityRamp {
    /// The generator's density input at column `x` (clamped to the frame).
    pub fn at(&self, x: i64) -> f32 {
        density_input(self.density(x))
    }

    /// The density at column `x` (clamped to the frame).
    pub fn density(&self, x: i64) -> f32 {
        let t = if self.width > 1 {
            (x as f32 / (self.width - 1) as f32).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.from + (self.to - self.from) * t
    }
}

/// What a synthesis of a conditioned model paints with.
#[derive(Debug, Clone, PartialEq)]
pub enum Condition {
    /// A guided image model's guidance over a `[height, width]` frame whose top-left pixel is
    /// the synthesis' offset.
    Guide { guide: Guide, frame: [usize; 2] },
    /// A density-controlled volume model's density, a ramp along the columns.
    Density(DensityRamp),
}

impl Condition {
    /// The generator's condition input at `(row, col)` relative to the frame's top-left pixel.
    pub fn at(&self, row: i64, col: i64) -> f32 {
        match self {
            Self::Guide {
                guide,
                frame: [h, w],
            } => guide.at(row, col, *w, *h),
            Self::Density(ramp) => ramp.at(col),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_parse_and_evaluate_over_the_frame() {
        let x: Guide = "x".parse().unwrap();
        assert_eq!(
            x,
            Guide::Line {
                a: 1.0,
                b: 0.0,
                c: 0.0
            }
        );
        assert_eq!(
            "0.5,-1,0.25".parse::<Guide>().unwrap(),
            Guide::Line {
                a: 0.5,
                b: -1.0,
                c: 0.25
            }
        );
        assert!("z".parse::<Guide>().is_err());
        assert!("1,2".parse::<Guide>().is_err());
        // Left edge -1 + half a pixel, right edge +1 - half a pixel.
        assert!((x.at(0, 0, 100, 10) + 0.99).abs() < 1e-6);
        assert!((x.at(5, 99, 100, 10) - 0.99).abs() < 1e-6);
        let back: Guide = x.to_config().unwrap().parse().unwrap();
        assert_eq!(back, x);
    }
}
