//! Directional guidance (conditional IPFN, paper eq. 5): one more input channel `g` tells the
//! generator how the pattern changes across the surface.
//!
//! In training, `g = a·X + b·Y + c` over the whole exemplar, with `X` and `Y` its normalised
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
    input_error!(
        "--guide {s}: expected x, y, -x, -y, a line a,b,c (g = a·x + b·y + c), or a grayscale image"
    )
}

impl Guide {
    /// Reads a guidance image: its first channel, `g = 2v - 1`.
    pub fn from_image(path: &std::path::Path) -> Result<Self> {
        let image = crate::io::read_exemplar(path)?;
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
