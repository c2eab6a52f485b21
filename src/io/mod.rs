//! Files in and out: `.npy` arrays, images written in row bands, and atomic replacement; the
//! run folder's lock ([`lock`]).
//!
//! Every file we produce is written to a temporary file in the destination folder and renamed
//! into place when complete, so a crash or Ctrl-C never leaves a half-written output.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use npyz::WriterBuilder;

use crate::error::{Error, Result};

pub mod lock;
pub mod shard;
mod volume;
pub mod zarr;
pub use volume::{MAX_SLICE_VOXELS, VolumeFormat, VolumeWriter, check_volume_size};

/// Where the header of the `.npy` file `bytes` ends, if its preamble (magic, version, header
/// length) is whole and the header fits in the file.
fn npy_header_end(bytes: &[u8]) -> Option<usize> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return None;
    }
    let (length, preamble): (usize, usize) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return None,
    };
    let end = preamble.checked_add(length)?;
    (end <= bytes.len()).then_some(end)
}

/// Reads a float32 (or float64, converted) `.npy` array: `(shape, values)` in C order.
pub fn read_npy(path: &Path) -> Result<(Vec<usize>, Vec<f32>)> {
    let bytes = std::fs::read(path).map_err(|e| crate::file_error!(&path, "cannot read: {e}"))?;
    let corrupt = |e: std::io::Error| crate::file_error!(&path, "not a valid .npy array: {e}");
    let header_end = npy_header_end(&bytes).ok_or_else(|| {
        crate::file_error!(
            &path,
            "not a valid .npy array: its header is missing, truncated or claims more bytes than the file has",
        )
    })?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(corrupt)?;
    // The data must be in the file: a shape that claims more is refused before allocating it.
    let claimed = npy
        .shape()
        .iter()
        .try_fold(1u64, |n, &d| n.checked_mul(d))
        .and_then(|n| n.checked_mul(npy.dtype().num_bytes().unwrap_or(8) as u64));
    if claimed.is_none_or(|n| n > (bytes.len() - header_end) as u64) {
        return Err(crate::file_error!(
            &path,
            "not a valid .npy array: its shape {:?} claims more data than the file holds",
            npy.shape(),
        ));
    }
    if npy.order() != npyz::Order::C {
        return Err(crate::file_error!(
            &path,
            "Fortran-ordered .npy arrays are not supported; save it in C order",
        ));
    }
    let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let values = match npy.dtype() {
        npyz::DType::Plain(t) if t.type_char() == npyz::TypeChar::Float && t.size_field() == 4 => {
            npy.into_vec::<f32>().map_err(corrupt)?
        }
        npyz::DType::Plain(t) if t.type_char() == npyz::TypeChar::Float && t.size_field() == 8 => {
            npy.into_vec::<f64>()
                .map_err(corrupt)?
                .into_iter()
                .map(|v| v as f32)
                .collect()
        }
        other => {
            return Err(crate::file_error!(
                &path,
                "expected a float32 or float64 array, found {}",
                other.descr(),
            ));
        }
    };
    Ok((shape, values))
}

/// A file being written under a temporary name next to its destination.
///
/// Creating one checks at once that the destination folder is writable. Dropping it without
/// [`AtomicFile::commit`] removes the temporary file.
///
/// The temporary file is registered with [`crate::stop`], so a Ctrl-C or SIGTERM that ends the
/// process removes it too.
pub struct AtomicFile {
    temp: Option<tempfile::NamedTempFile>,
    path: PathBuf,
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(temp) = self.temp.take() {
            // Remove, then forget: a signal in between still finds the file listed.
            let path = temp.path().to_path_buf();
            drop(temp);
            crate::stop::forget_temporary(&path);
        }
    }
}

/// Checks that `path` can be created: its folder exists and it is not itself a folder.
pub fn check_destination(path: &Path) -> Result<&Path> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(crate::file_error!(
            &path,
            "cannot write: folder {} does not exist",
            dir.display(),
        ));
    }
    if path.is_dir() {
        return Err(crate::file_error!(&path, "cannot write: it is a folder",));
    }
    Ok(dir)
}

impl AtomicFile {
    pub fn create(path: &Path) -> Result<Self> {
        let dir = check_destination(path)?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(".tmp")
            .tempfile_in(dir)
            .map_err(|e| match e.kind() {
                // The user's to fix: a folder they cannot write to.
                std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::NotFound => {
                    crate::file_error!(&path, "cannot write: {e}")
                }
                // The machine's: a full disk, a read-only or lost mount.
                _ => Error::Runtime(format!("{}: cannot write: {e}", path.display())),
            })?;
        crate::stop::register_temporary(temp.path());
        Ok(Self {
            temp: Some(temp),
            path: path.to_path_buf(),
        })
    }

    pub fn file(&mut self) -> &mut File {
        self.temp
            .as_mut()
            .expect("present until commit")
            .as_file_mut()
    }

    /// Flushes to disk and renames the temporary file onto the destination.
    pub fn commit(mut self) -> Result<()> {
        let path = self.path.clone();
        let temp = self.temp.take().expect("present until commit");
        let temp_path = temp.path().to_path_buf();
        let committed = Self::persist(temp, &path);
        crate::stop::forget_temporary(&temp_path);
        committed
    }

    fn persist(temp: tempfile::NamedTempFile, path: &Path) -> Result<()> {
        // tempfile creates files private (0600); give outputs the usual permissions.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(path)
                .map(|m| m.permissions().mode())
                .unwrap_or(0o644);
            let _ = temp
                .as_file()
                .set_permissions(std::fs::Permissions::from_mode(mode));
        }
        temp.as_file()
            .sync_all()
            .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", path.display())))?;
        temp.persist(path).map_err(|e| {
            Error::Runtime(format!("{}: cannot write: {}", path.display(), e.error))
        })?;
        Ok(())
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    file.file()
        .write_all(bytes)
        .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", path.display())))?;
    file.commit()
}

/// Image and array formats `synth` can write, chosen by file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// PNG, 8 or 16 bits per channel; values mapped from [-1, 1] to [0, 1].
    Png { bits: u8 },
    /// OpenEXR, 32-bit float channels holding (v + 1) / 2, unclamped.
    Exr,
    /// NumPy array `[height, width, channels]` of the raw generator output in [-1, 1].
    Npy,
}

/// `path`'s extension in lower case (empty when it has none): what picks a file's format.
pub fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

impl OutputFormat {
    /// The format for `path`'s extension; `bits` applies to PNG only (8 or 16).
    pub fn from_path(path: &Path, bits: u8) -> Result<Self> {
        let ext = extension(path);
        let format = match ext.as_str() {
            "png" => OutputFormat::Png { bits },
            "exr" => OutputFormat::Exr,
            "npy" => OutputFormat::Npy,
            "" => {
                return Err(crate::file_error!(
                    &path,
                    "no file extension; use .png, .exr or .npy",
                ));
            }
            other => {
                return Err(crate::file_error!(
                    &path,
                    "unknown extension .{other}; use .png, .exr or .npy",
                ));
            }
        };
        if !matches!(bits, 8 | 16) {
            return Err(crate::setting_error!(
                "--bits",
                bits,
                "PNG holds 8 or 16 bits per channel"
            ));
        }
        if bits == 16 && format != (OutputFormat::Png { bits: 16 }) {
            return Err(crate::file_error!(&path, "--bits 16 applies to .png only",));
        }
        Ok(format)
    }

    /// Checks that an image of this size and channel count fits the format.
    pub fn check_size(
        &self,
        path: &Path,
        width: usize,
        height: usize,
        channels: usize,
    ) -> Result<()> {
        let limit: usize = match self {
            OutputFormat::Png { .. } => (1 << 31) - 1, // PNG stores dimensions as 31-bit integers
            OutputFormat::Exr => i32::MAX as usize,
            OutputFormat::Npy => usize::MAX,
        };
        if width == 0 || height == 0 {
            return Err(crate::file_error!(
                &path,
                "size {width}x{height}: width and height must be at least 1",
            ));
        }
        if width > limit || height > limit {
            return Err(crate::file_error!(
                &path,
                "size {width}x{height} is too large for this format (at most {limit} per side)",
            ));
        }
        if let OutputFormat::Png { bits } = self {
            if !(1..=4).contains(&channels) {
                return Err(crate::file_error!(
                    &path,
                    "PNG holds 1 to 4 channels, this model makes {channels}; write .exr or .npy",
                ));
            }
            // The png crate buffers one row; keep a row's bytes addressable.
            let row = width.checked_mul(channels * (*bits as usize / 8));
            if row.is_none_or(|r| r > u32::MAX as usize) {
                return Err(crate::file_error!(
                    &path,
                    "width {width} is too large for PNG rows",
                ));
            }
        }
        if *self == OutputFormat::Exr
            && width.saturating_mul(height).saturating_mul(channels) > (1usize << 32)
        {
            return Err(crate::file_error!(
                &path,
                "{width}x{height} is too large for .exr output, which is held in memory; write .png or .npy (streamed)",
            ));
        }
        Ok(())
    }
}

/// Writes an image of `height` rows band by band: PNG and NPY stream to disk, EXR is collected
/// in memory (the exr crate writes whole layers). Values are the generator's, in [-1, 1],
/// row-major `[rows, width, channels]`.
pub struct ImageWriter {
    inner: WriterKind,
    path: PathBuf,
    width: usize,
    height: usize,
    channels: usize,
    rows_written: usize,
}

enum WriterKind {
    Png {
        writer: Box<png::StreamWriter<'static, BufWriter<File>>>,
        bits: u8,
        file: AtomicFile,
    },
    Npy {
        writer: npyz::NpyWriter<f32, BufWriter<File>>,
        file: AtomicFile,
    },
    Exr {
        values: Vec<f32>,
        file: AtomicFile,
    },
}

impl ImageWriter {
    pub fn create(
        path: &Path,
        format: OutputFormat,
        width: usize,
        height: usize,
        channels: usize,
    ) -> Result<Self> {
        format.check_size(path, width, height, channels)?;
        let mut file = AtomicFile::create(path)?;
        let io_err =
            |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", path.display()));
        let inner = match format {
            OutputFormat::Png { bits } => {
                let handle = file.file().try_clone().map_err(io_err)?;
                let mut encoder =
                    png::Encoder::new(BufWriter::new(handle), width as u32, height as u32);
                encoder.set_color(match channels {
                    1 => png::ColorType::Grayscale,
                    2 => png::ColorType::GrayscaleAlpha,
                    3 => png::ColorType::Rgb,
                    _ => png::ColorType::Rgba,
                });
                encoder.set_depth(if bits == 16 {
                    png::BitDepth::Sixteen
                } else {
                    png::BitDepth::Eight
                });
                encoder.set_compression(png::Compression::Fast);
                let writer = encoder
                    .write_header()
                    .and_then(|w| w.into_stream_writer())
                    .map_err(|e| {
                        Error::Runtime(format!("{}: cannot write PNG: {e}", path.display()))
                    })?;
                WriterKind::Png {
                    writer: Box::new(writer),
                    bits,
                    file,
                }
            }
            OutputFormat::Npy => {
                let handle = file.file().try_clone().map_err(io_err)?;
                let writer = npyz::WriteOptions::new()
                    .default_dtype()
                    .shape(&[height as u64, width as u64, channels as u64])
                    .writer(BufWriter::new(handle))
                    .begin_nd()
                    .map_err(io_err)?;
                WriterKind::Npy { writer, file }
            }
            OutputFormat::Exr => WriterKind::Exr {
                values: Vec::with_capacity(width * height * channels),
                file,
            },
        };
        Ok(Self {
            inner,
            path: path.to_path_buf(),
            width,
            height,
            channels,
            rows_written: 0,
        })
    }

    /// Appends whole rows (`values.len()` a multiple of `width * channels`).
    pub fn write_rows(&mut self, values: &[f32]) -> Result<()> {
        let row = self.width * self.channels;
        assert_eq!(values.len() % row, 0, "write_rows takes whole rows");
        self.rows_written += values.len() / row;
        assert!(
            self.rows_written <= self.height,
            "more rows than the image holds"
        );
        let path = &self.path;
        let io_err =
            |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", path.display()));
        match &mut self.inner {
            WriterKind::Png { writer, bits, .. } => {
                let bytes = if *bits == 16 {
                    values
                        .iter()
                        .flat_map(|&v| to_unit_u16(v).to_be_bytes())
                        .collect::<Vec<u8>>()
                } else {
                    values.iter().map(|&v| to_unit_u8(v)).collect::<Vec<u8>>()
                };
                writer.write_all(&bytes).map_err(io_err)
            }
            WriterKind::Npy { writer, .. } => {
                for v in values {
                    writer.push(v).map_err(io_err)?;
                }
                Ok(())
            }
            WriterKind::Exr { values: all, .. } => {
                all.extend_from_slice(values);
                Ok(())
            }
        }
    }

    /// Finishes the file and moves it into place.
    pub fn finish(self) -> Result<()> {
        assert_eq!(
            self.rows_written, self.height,
            "image finished before all rows were written"
        );
        let path = self.path;
        let io_err =
            |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", path.display()));
        match self.inner {
            WriterKind::Png { writer, file, .. } => {
                writer.finish().map_err(|e| {
                    Error::Runtime(format!("{}: cannot write PNG: {e}", path.display()))
                })?;
                file.commit()
            }
            WriterKind::Npy { writer, file } => {
                writer.finish().map_err(io_err)?;
                file.commit()
            }
            WriterKind::Exr { values, mut file } => {
                write_exr(file.file(), self.width, self.height, self.channels, &values).map_err(
                    |e| Error::Runtime(format!("{}: cannot write EXR: {e}", path.display())),
                )?;
                file.commit()
            }
        }
    }
}

fn write_exr(
    file: &mut File,
    width: usize,
    height: usize,
    channels: usize,
    values: &[f32],
) -> exr::error::UnitResult {
    use exr::prelude::*;
    let names: Vec<String> = match channels {
        1 => vec!["Y".into()],
        2 => vec!["Y".into(), "A".into()],
        3 => vec!["R".into(), "G".into(), "B".into()],
        4 => vec!["R".into(), "G".into(), "B".into(), "A".into()],
        n => (0..n).map(|c| format!("c{c:02}")).collect(),
    };
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = names
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let samples: Vec<f32> = values
                .iter()
                .skip(c)
                .step_by(channels)
                .map(|&v| (v + 1.0) * 0.5)
                .collect();
            AnyChannel::new(name.as_str(), FlatSamples::F32(samples))
        })
        .collect();
    let layer = Layer::new(
        (width, height),
        LayerAttributes::named("ipfn"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list),
    );
    let mut out = BufWriter::new(file);
    Image::from_layer(layer).write().to_buffered(&mut out)?;
    out.flush()?;
    Ok(())
}

/// Maps a generator value in [-1, 1] to an 8-bit level: `round((v + 1) / 2 * 255)`, clamped.
pub fn to_unit_u8(v: f32) -> u8 {
    (((v + 1.0) * 0.5).clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Maps a generator value in [-1, 1] to a 16-bit level.
pub fn to_unit_u16(v: f32) -> u16 {
    (((v + 1.0) * 0.5).clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// Writes `[height, width, channels]` values in [-1, 1] as an 8-bit PNG, atomically.
pub fn write_png(
    path: &Path,
    width: usize,
    height: usize,
    channels: usize,
    values: &[f32],
) -> Result<()> {
    let mut writer =
        ImageWriter::create(path, OutputFormat::Png { bits: 8 }, width, height, channels)?;
    writer.write_rows(values)?;
    writer.finish()
}
