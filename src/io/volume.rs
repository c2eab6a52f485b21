//! Volumes out: `.npy` (`[D, H, W, C]` float32 with its shape) or `.raw` (bare little-endian
//! float32), streamed in slabs of depth slices and written atomically.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use npyz::WriterBuilder;

use super::{AtomicFile, extension};
use crate::error::{Error, Result};

/// How a volume file stores its values, chosen by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VolumeFormat {
    /// `.npy`: float32 `[D, H, W, C]` with its shape in the header.
    Npy,
    /// `.raw`: bare little-endian float32 in the same order, no header (the size is printed;
    /// volume viewers such as ParaView ask for it when opening the file).
    Raw,
}

impl VolumeFormat {
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = extension(path);
        match ext.as_str() {
            "npy" => Ok(Self::Npy),
            "raw" => Ok(Self::Raw),
            _ => Err(crate::file_error!(
                &path,
                "volumes are written as .npy (float32 [D, H, W, C] with its shape) or .raw (bare little-endian float32, same order)",
            )),
        }
    }
}

/// The most voxels in one depth slice of a painted volume: volumes are painted and written a
/// slab of whole slices at a time, so one slice (per channel, 4 bytes a voxel) must fit in
/// memory: 2^28 voxels is 1 GiB, 16384 x 16384.
pub const MAX_SLICE_VOXELS: usize = 1 << 28;

/// Checks a volume's size before any work: every side at least 1, the voxel count
/// representable, and one depth slice at most [`MAX_SLICE_VOXELS`].
pub fn check_volume_size(
    path: &Path,
    depth: usize,
    height: usize,
    width: usize,
    channels: usize,
) -> Result<()> {
    if depth == 0 || height == 0 || width == 0 {
        return Err(crate::file_error!(
            &path,
            "size {width}x{height}x{depth}: every side must be at least 1",
        ));
    }
    let slice = height.checked_mul(width);
    let total = slice
        .and_then(|s| s.checked_mul(depth))
        .and_then(|t| t.checked_mul(channels.max(1)))
        .and_then(|t| t.checked_mul(4));
    match (slice, total) {
        (Some(slice), Some(_)) if slice <= MAX_SLICE_VOXELS => Ok(()),
        _ => Err(crate::file_error!(
            &path,
            "size {width}x{height}x{depth}: one depth slice of {width}x{height} voxels is too large to paint in memory (at most {MAX_SLICE_VOXELS} voxels, e.g. 16384x16384); paint a smaller volume",
        )),
    }
}

/// Where a [`VolumeWriter`] puts values.
enum VolumeSink {
    Npy(npyz::NpyWriter<f32, BufWriter<File>>),
    Raw(BufWriter<File>),
}

/// Streams a volume `[depth, height, width, channels]` to `.npy` or `.raw` (see
/// [`VolumeFormat`]) in slabs of whole depth slices, under a temporary name renamed into place
/// by [`VolumeWriter::finish`].
pub struct VolumeWriter {
    sink: VolumeSink,
    file: AtomicFile,
    path: PathBuf,
    slice: usize,
    expected: usize,
    written: usize,
}

impl VolumeWriter {
    pub fn create(
        path: &Path,
        depth: usize,
        height: usize,
        width: usize,
        channels: usize,
    ) -> Result<Self> {
        let format = VolumeFormat::from_path(path)?;
        let mut file = AtomicFile::create(path)?;
        let io_err =
            |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", path.display()));
        let handle = BufWriter::new(file.file().try_clone().map_err(io_err)?);
        let sink = match format {
            VolumeFormat::Npy => VolumeSink::Npy(
                npyz::WriteOptions::new()
                    .default_dtype()
                    .shape(&[depth as u64, height as u64, width as u64, channels as u64])
                    .writer(handle)
                    .begin_nd()
                    .map_err(io_err)?,
            ),
            VolumeFormat::Raw => VolumeSink::Raw(handle),
        };
        Ok(Self {
            sink,
            file,
            path: path.to_path_buf(),
            slice: height * width * channels,
            expected: depth * height * width * channels,
            written: 0,
        })
    }

    /// Appends whole depth slices.
    pub fn write_slab(&mut self, values: &[f32]) -> Result<()> {
        assert!(values.len().is_multiple_of(self.slice), "whole slices only");
        match &mut self.sink {
            VolumeSink::Npy(writer) => writer.extend(values.iter().copied()),
            VolumeSink::Raw(writer) => values.chunks(1 << 16).try_for_each(|chunk| {
                let bytes: Vec<u8> = chunk.iter().flat_map(|v| v.to_le_bytes()).collect();
                writer.write_all(&bytes)
            }),
        }
        .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", self.path.display())))?;
        self.written += values.len();
        Ok(())
    }

    pub fn finish(self) -> Result<()> {
        assert_eq!(self.written, self.expected, "every slice written");
        match self.sink {
            VolumeSink::Npy(writer) => writer.finish(),
            VolumeSink::Raw(mut writer) => writer.flush(),
        }
        .map_err(|e| Error::Runtime(format!("{}: cannot write: {e}", self.path.display())))?;
        self.file.commit()
    }
}
