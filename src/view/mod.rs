//! `ipfn view`: a local web page that pans and zooms a model's infinite plane and follows a
//! training run live.
//!
//! - this file: what a view is ([`View`], parsed and range-checked from a request's query), the
//!   model it paints ([`ViewModel`], reloaded when a run writes a newer checkpoint) and the
//!   tiles ([`ViewModel::tile_png`]), painted by the same [`crate::synth::Painter`] as
//!   `ipfn synth`, so that a tile holds exactly the pixels of the `ipfn synth` command
//!   [`View::synth_args`] names;
//! - [`crate::report`]: a run folder's metrics, previews, config and state, and `report.html`;
//! - [`server`]: the HTTP server, its routes, render queue and tile cache.

pub mod server;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::condition::{DensityRamp, Guide};
use crate::device::DeviceChoice;
use crate::error::{Error, Result};
use crate::generator::{GeneratorConfig, GeneratorWeights};
use crate::input_error;
use crate::maps::MapSet;
use crate::synth::Synth;

pub use crate::report::{PAGE_HTML, PAGE_JS};

/// Tiles are served within this many pixels of the origin on each axis (beyond, coordinates
/// lose precision in f32 and a request is refused).
pub const MAX_POSITION: i64 = 1_000_000;
/// A tile's side is between these, in pixels.
pub const TILE_SIDES: std::ops::RangeInclusive<usize> = 16..=1024;
/// Zoom and noise scale lie in [1/MAX_SCALE, MAX_SCALE].
pub const MAX_SCALE: f64 = 64.0;
/// A guide frame or an export is at most this many pixels on a side.
pub const MAX_FRAME: usize = 16384;
/// Tile mode's period: sides from MIN_PERIOD (so a screen holds a few hundred tiles at most) to
/// MAX_PERIOD pixels (one render).
pub const MIN_PERIOD: usize = 64;
pub const MAX_PERIOD: usize = 2048;
/// An export paints at most this many pixels (a 4096x4096 image), a 3D model's plane at most
/// MAX_EXPORT_PLANE (one render, in memory).
pub const MAX_EXPORT_PIXELS: usize = 1 << 24;
pub const MAX_EXPORT_PLANE: usize = 1 << 22;

/// What the page shows: every `ipfn synth` option that a view can set, range-checked.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    pub seed: u64,
    pub zoom: f64,
    pub noise_scale: f64,
    /// Tile mode: the period `[rows, cols]` (`synth --tile --width cols --height rows`).
    pub period: Option<[usize; 2]>,
    /// A guided model's line guide (`x`, `-y`, `a,b,c`) over a frame `[rows, cols]` whose
    /// top-left pixel is the origin.
    pub guide: Option<(String, [usize; 2])>,
    /// A density-controlled volume model's density.
    pub density: Option<f32>,
    /// Which map of a map set (0 for other models); one past the last map: the material lit
    /// ([`crate::maps::preview`]).
    pub map: usize,
    /// A 3D model's plane: the axis across it (`x`, `y` or `z`) and its index.
    pub slice: (char, i64),
}

/// A request's query string as name-value pairs (percent-decoded). Repeated names are refused.
pub fn parse_query(query: &str) -> Result<HashMap<String, String>> {
    if query.len() > 2048 {
        return Err(input_error!("query too long"));
    }
    let mut pairs = HashMap::new();
    for (name, value) in form_urlencoded::parse(query.as_bytes()) {
        if pairs.insert(name.to_string(), value.to_string()).is_some() {
            return Err(input_error!("parameter '{name}' given twice"));
        }
    }
    Ok(pairs)
}

/// One named parameter, parsed; `None` when absent.
pub fn param<T: std::str::FromStr>(q: &HashMap<String, String>, name: &str) -> Result<Option<T>> {
    match q.get(name) {
        None => Ok(None),
        Some(text) if text.len() > 64 => Err(input_error!("{name}: value too long")),
        Some(text) => text
            .trim()
            .parse()
            .map(Some)
            .map_err(|_| input_error!("{name} '{text}': not a valid value")),
    }
}

/// A positive finite number in [1/MAX_SCALE, MAX_SCALE].
fn scale(q: &HashMap<String, String>, name: &str) -> Result<f64> {
    let v: f64 = param(q, name)?.unwrap_or(1.0);
    if !(v.is_finite() && (1.0 / MAX_SCALE..=MAX_SCALE).contains(&v)) {
        return Err(input_error!(
            "{name} {v}: must be between 1/{MAX_SCALE} and {MAX_SCALE}"
        ));
    }
    Ok(v)
}

/// `WxH` as `[rows, cols]`, each side in 1..=MAX_FRAME.
pub fn frame(q: &HashMap<String, String>, name: &str) -> Result<Option<[usize; 2]>> {
    let Some(text) = q.get(name) else {
        return Ok(None);
    };
    let bad = || input_error!("{name} '{text}': expected WxH, sides 1 to {MAX_FRAME}");
    let (w, h) = text.split_once('x').ok_or_else(bad)?;
    let side = |s: &str| {
        s.parse::<usize>()
            .ok()
            .filter(|v| (1..=MAX_FRAME).contains(v))
    };
    match (side(w), side(h)) {
        (Some(w), Some(h)) if text.len() <= 16 => Ok(Some([h, w])),
        _ => Err(bad()),
    }
}

/// A position on one axis, within [`MAX_POSITION`].
pub fn position(q: &HashMap<String, String>, name: &str) -> Result<i64> {
    let v: i64 = param(q, name)?.unwrap_or(0);
    if !(-MAX_POSITION..=MAX_POSITION).contains(&v) {
        return Err(input_error!(
            "{name} {v}: the plane is served within {MAX_POSITION} pixels of the origin"
        ));
    }
    Ok(v)
}

/// A guided model's line and frame (`x` over 1024x1024 by default; in tile mode the frame is
/// the tile, as `synth --tile --guide` has it). Lines only: a request never names a file.
fn guide(
    q: &HashMap<String, String>,
    config: &GeneratorConfig,
    period: Option<[usize; 2]>,
) -> Result<Option<(String, [usize; 2])>> {
    let guided = config.guidance > 0 && config.dims == 2;
    let line = match (q.get("guide"), guided) {
        (Some(_), false) => return Err(input_error!("guide: this model is not guided")),
        (None, false) => return Ok(None),
        (Some(g), true) if g.len() > 64 => return Err(input_error!("guide: value too long")),
        (Some(g), true) => g
            .parse::<Guide>()
            .map_err(|_| input_error!("guide '{g}': expected x, y, -x, -y or a,b,c"))?,
        (None, true) => Guide::Line {
            a: 1.0,
            b: 0.0,
            c: 0.0,
        },
    };
    let frame = match period {
        Some(period) => period,
        None => frame(q, "frame")?.unwrap_or([1024, 1024]),
    };
    Ok(line.to_config().map(|text| (text, frame)))
}

/// A density-controlled volume model's density (0.3 by default), a mean |sdf| in [0, 4].
fn density(q: &HashMap<String, String>, config: &GeneratorConfig) -> Result<Option<f32>> {
    match (
        param::<f32>(q, "density")?,
        config.guidance > 0 && config.dims == 3,
    ) {
        (Some(d), true) if d.is_finite() && (0.0..=4.0).contains(&d) => Ok(Some(d)),
        (Some(d), true) => Err(input_error!("density {d}: must be in [0, 4]")),
        (None, true) => Ok(Some(0.3)),
        (Some(_), false) => Err(input_error!("density: this model has no density control")),
        (None, false) => Ok(None),
    }
}

/// A 3D model's plane: the axis across it and its index (from 0, as `synth --slice`).
fn slice(q: &HashMap<String, String>, config: &GeneratorConfig) -> Result<(char, i64)> {
    let axis = match (q.get("axis").map(String::as_str), config.dims) {
        (None, _) | (Some("z"), 3) => 'z',
        (Some("x"), 3) => 'x',
        (Some("y"), 3) => 'y',
        (Some(_), 3) => return Err(input_error!("axis: expected x, y or z")),
        (Some(_), _) => return Err(input_error!("axis: only 3D models have slices")),
    };
    let depth = position(q, "depth")?;
    if depth < 0 || (depth > 0 && config.dims != 3) {
        return Err(input_error!(
            "depth {depth}: a slice's index is 0 or more, for 3D models"
        ));
    }
    Ok((axis, depth))
}

impl View {
    /// The view in a query, checked against the model: options a model cannot take are refused.
    pub fn from_query(q: &HashMap<String, String>, model: &ViewModel) -> Result<Self> {
        let config = &model.config;
        let period = frame(q, "tile")?;
        if period.is_some() && config.dims != 2 {
            return Err(input_error!("tile: tile mode is for 2D models"));
        }
        if period.is_some_and(|[h, w]| h.max(w) > MAX_PERIOD || h.min(w) < MIN_PERIOD) {
            return Err(input_error!(
                "tile: a period's sides are {MIN_PERIOD} to {MAX_PERIOD} pixels"
            ));
        }
        let maps = model.maps.as_ref().map_or(1, |m| m.ranges().len());
        let map: usize = param(q, "map")?.unwrap_or(0);
        // A map set's views are its maps and, after them, the material lit.
        let views = if model.maps.is_some() { maps + 1 } else { 1 };
        if map >= views {
            return Err(input_error!(
                "map {map}: the model has {maps} map(s){}",
                if model.maps.is_some() {
                    " and the lit material after them"
                } else {
                    ""
                }
            ));
        }
        Ok(Self {
            seed: param(q, "seed")?.unwrap_or(0),
            zoom: scale(q, "zoom")?,
            noise_scale: scale(q, "noise")?,
            period,
            guide: guide(q, config, period)?,
            density: density(q, config)?,
            map,
            slice: slice(q, config)?,
        })
    }

    /// The `ipfn synth` arguments (after `ipfn synth`) that paint this view's `[rows, cols]`
    /// frame whose top-left pixel is `(x, y)`, into `out`. In tile mode the frame is one period
    /// (the tile); a 3D model's plane starts at the volume's origin.
    pub fn synth_args(
        &self,
        model: &ViewModel,
        [x, y]: [i64; 2],
        size: [usize; 2],
        out: &Path,
    ) -> Vec<String> {
        let mut args: Vec<String> = Vec::new();
        let push = |args: &mut Vec<String>, a: &str, b: String| {
            args.push(a.to_string());
            args.push(b);
        };
        if let Some(file) = &model.command_file {
            push(&mut args, "--model", file.display().to_string());
        }
        push(&mut args, "--seed", self.seed.to_string());
        push(&mut args, "--zoom", self.zoom.to_string());
        push(&mut args, "--noise-scale", self.noise_scale.to_string());
        let [rows, cols] = self.period.unwrap_or(size);
        if model.config.dims == 3 {
            let (axis, index) = self.slice;
            let index = index as usize; // from_query: 0 or more
            // The volume holds the plane: the slice's axis reaches its index.
            let (w, h, d) = match axis {
                'z' => (cols, rows, index + 1),
                'y' => (cols, index + 1, rows),
                _ => (index + 1, cols, rows),
            };
            push(&mut args, "--size", format!("{w}x{h}x{d}"));
            push(&mut args, "--slice", format!("{axis}={index}"));
        } else {
            push(&mut args, "--width", cols.to_string());
            push(&mut args, "--height", rows.to_string());
        }
        if self.period.is_some() {
            args.push("--tile".into());
        } else if model.config.dims == 2 && (x, y) != (0, 0) && self.guide.is_none() {
            push(&mut args, "--offset", format!("{x},{y}"));
        }
        if let Some((g, _)) = &self.guide {
            push(&mut args, "--guide", g.clone());
        }
        if let Some(d) = self.density {
            push(&mut args, "--density", d.to_string());
        }
        if model.maps.is_some() {
            push(&mut args, "--bits", "8".into()); // as the tiles show them
        }
        if self.lit(model) {
            push(&mut args, "--preview", lit_path(out).display().to_string());
        }
        if model.device != DeviceChoice::Cpu {
            push(
                &mut args,
                "--device",
                format!("{:?}", model.device).to_lowercase(),
            );
        }
        push(&mut args, "--out", out.display().to_string());
        args
    }
}

impl View {
    /// Whether the view shows a map set's material lit rather than one of its maps.
    pub fn lit(&self, model: &ViewModel) -> bool {
        model
            .maps
            .as_ref()
            .is_some_and(|set| self.map == set.maps.len())
    }
}

/// Where an export to `out` writes the lit material: beside it, `-lit` added to its stem.
pub fn lit_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("view");
    out.with_file_name(format!("{stem}-lit.png"))
}

/// A shell-ready rendering of `ipfn synth ARGS`.
pub fn command_line(args: &[String]) -> String {
    let quote = |a: &String| {
        if !a.is_empty()
            && a.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.,=/:+".contains(c))
        {
            a.clone()
        } else {
            format!("'{}'", a.replace('\'', r"'\''"))
        }
    };
    let mut words = vec!["ipfn".to_string(), "synth".to_string()];
    words.extend(args.iter().map(quote));
    words.join(" ")
}

/// The model a view paints: a model file, or a run folder's newest checkpoint (`latest.ipfn`),
/// reloaded when the run writes a newer one.
pub struct ViewModel {
    pub config: GeneratorConfig,
    pub weights: GeneratorWeights,
    pub maps: Option<MapSet>,
    /// The file it was read from (`None`: the shipped honeycomb).
    pub file: Option<PathBuf>,
    /// The file that commands name: for a run's `latest.ipfn`, the run's unchanging
    /// `checkpoints/iter-N.ipfn` of the same iteration (same generator), when it is there.
    pub command_file: Option<PathBuf>,
    /// Changes whenever the file does (its modification time and length).
    pub version: String,
    pub description: String,
    pub device: DeviceChoice,
}

/// The file's version: modification time (ns) and length.
pub fn file_version(path: &Path) -> Option<String> {
    let meta = std::fs::metadata(path).ok()?;
    let modified = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some(format!("{}-{}", modified.as_nanos(), meta.len()))
}

impl ViewModel {
    /// Loads `file` (or the shipped honeycomb).
    pub fn load(file: Option<&Path>, device: DeviceChoice) -> Result<Self> {
        let version = match file {
            Some(f) => file_version(f).ok_or_else(|| crate::file_error!(&f, "cannot read"))?,
            None => "shipped".to_string(),
        };
        let chosen = match file {
            Some(f) => crate::model::choose_model(Some(f), Path::new("."))?,
            None => crate::model::load_shipped()?,
        };
        Ok(Self {
            config: chosen.config,
            weights: chosen.weights,
            maps: chosen.maps,
            command_file: file.map(checkpoint_of),
            file: file.map(Path::to_path_buf),
            version,
            description: chosen.description,
            device,
        })
    }

    /// The model's facts for the page (`/api/info`).
    pub fn info(&self) -> serde_json::Value {
        let maps: Vec<serde_json::Value> = self.maps.as_ref().map_or_else(Vec::new, |set| {
            set.maps
                .iter()
                .map(|m| serde_json::json!({"name": m.name, "normal": m.normal}))
                .collect()
        });
        serde_json::json!({
            "description": self.description,
            "version": self.version,
            "dims": self.config.dims,
            "channels": self.config.channels,
            "guided": self.config.guidance > 0 && self.config.dims == 2,
            "density": self.config.guidance > 0 && self.config.dims == 3,
            "maps": maps,
            "k": self.weights.k,
            "device": format!("{:?}", self.device).to_lowercase(),
        })
    }

    /// The painter of `view`, whose plane starts at the origin.
    fn painter(&self, view: &View, width: usize) -> Result<crate::synth::Painter> {
        let mut synth = Synth::new(self.config.clone(), self.weights.clone())
            .seed(view.seed)
            .zoom(view.zoom)
            .noise_scale(view.noise_scale)
            .device(self.device);
        if let Some(period) = view.period {
            synth = synth.tile(&period);
        }
        if let Some((g, frame)) = &view.guide {
            synth = synth.guide(g.parse()?, *frame);
        }
        if let Some(d) = view.density {
            synth = synth.density(DensityRamp {
                from: d,
                to: d,
                width,
            });
        }
        synth.painter()
    }

    /// The `[rows, cols]` pixels at `(x, y)` of the view's plane as an 8-bit PNG: the chosen map
    /// (normal maps renormalised), as `ipfn synth` writes it, or the material lit as
    /// `ipfn synth --preview` renders it. In tile mode the tile is one whole
    /// period at the origin, whatever `(x, y)`.
    pub fn tile_png(
        &self,
        view: &View,
        [x, y]: [i64; 2],
        [rows, cols]: [usize; 2],
    ) -> Result<Vec<u8>> {
        let [rows, cols] = view.period.unwrap_or([rows, cols]);
        let [x, y] = if view.period.is_some() {
            [0, 0]
        } else {
            [x, y]
        };
        let painter = self.painter(view, cols)?;
        let values = if self.config.dims == 3 {
            let (axis, index) = view.slice;
            let (origin, shape) = match axis {
                'z' => ([index, y, x], [1, rows, cols]),
                'y' => ([y, index, x], [rows, 1, cols]),
                _ => ([y, x, index], [rows, cols, 1]),
            };
            painter.render(&origin, &shape)
        } else {
            painter.render(&[y, x], &[rows, cols])
        };
        let c = self.config.channels;
        let (channels, normal) = match &self.maps {
            Some(set) if view.map == set.maps.len() => {
                let lit = crate::maps::preview::render(set, &values, [rows, cols]);
                return encode_png(cols, rows, 3, &lit);
            }
            Some(set) => (set.ranges()[view.map].clone(), set.maps[view.map].normal),
            None => (0..c, false),
        };
        let mut map: Vec<f32> = values
            .chunks_exact(c)
            .flat_map(|px| px[channels.clone()].iter().copied())
            .collect();
        if normal {
            crate::maps::renormalise(&mut map, channels.len());
        }
        encode_png(cols, rows, channels.len(), &map)
    }
}

/// For a run's `latest.ipfn`, its `checkpoints/iter-N.ipfn` (the generator of the same iteration,
/// which the run never rewrites); else the file itself.
fn checkpoint_of(file: &Path) -> PathBuf {
    let iteration = (file.file_name() == Some("latest.ipfn".as_ref()))
        .then(|| crate::checkpoint::Checkpoint::load(file).ok())
        .flatten()
        .and_then(|c| c.metadata.get("iteration")?.parse::<u64>().ok());
    let dir = file.parent().unwrap_or(Path::new("."));
    iteration
        .map(|it| dir.join("checkpoints").join(format!("iter-{it:06}.ipfn")))
        .filter(|p| p.is_file())
        .unwrap_or_else(|| file.to_path_buf())
}

/// `[rows, cols, channels]` values in [-1, 1] as an 8-bit PNG in memory, with the levels of
/// [`crate::io::write_png`].
pub fn encode_png(width: usize, height: usize, channels: usize, values: &[f32]) -> Result<Vec<u8>> {
    let color = match channels {
        1 => png::ColorType::Grayscale,
        2 => png::ColorType::GrayscaleAlpha,
        3 => png::ColorType::Rgb,
        4 => png::ColorType::Rgba,
        c => return Err(input_error!("a map of {c} channels cannot be shown as PNG")),
    };
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width as u32, height as u32);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let levels: Vec<u8> = values.iter().map(|&v| crate::io::to_unit_u8(v)).collect();
    let mut writer = encoder
        .write_header()
        .map_err(|e| Error::Runtime(format!("PNG encoding: {e}")))?;
    writer
        .write_image_data(&levels)
        .map_err(|e| Error::Runtime(format!("PNG encoding: {e}")))?;
    writer
        .finish()
        .map_err(|e| Error::Runtime(format!("PNG encoding: {e}")))?;
    Ok(bytes)
}

/// The model of a view, shared by the server's threads: a model file, or a run folder whose
/// `latest.ipfn` is followed.
pub struct ModelSource {
    /// The file read (None: the shipped honeycomb).
    file: Option<PathBuf>,
    device: DeviceChoice,
    current: Mutex<Option<Arc<ViewModel>>>,
}

impl ModelSource {
    pub fn new(file: Option<PathBuf>, device: DeviceChoice) -> Self {
        Self {
            file,
            device,
            current: Mutex::new(None),
        }
    }

    /// The model as the file is now: reloaded when the file changed; `None` while a run has no
    /// checkpoint yet.
    pub fn current(&self) -> Result<Option<Arc<ViewModel>>> {
        let version = match &self.file {
            Some(f) => match file_version(f) {
                Some(v) => v,
                None => return Ok(None),
            },
            None => "shipped".to_string(),
        };
        let current = || self.current.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(model) = current().as_ref().filter(|m| m.version == version) {
            return Ok(Some(model.clone()));
        }
        // Loaded outside the lock: a slow load does not hold up requests that need no model.
        let model = Arc::new(ViewModel::load(self.file.as_deref(), self.device)?);
        *current() = Some(model.clone());
        Ok(Some(model))
    }
}
