//! Zarr v3 output: one chunked array (`[H, W, C]` images, `[D, H, W, C]` volumes) written chunk
//! by chunk, by one process or by many (`--shard K/N`), through the `zarrs` crate.
//!
//! Every file (the `zarr.json` metadata and each chunk) is written under a temporary name and
//! renamed into place, so a chunk that exists is complete: a shard that is stopped and run again
//! skips the chunks it finished. Any shard may create the metadata; shards of one render write
//! the same metadata, so concurrent starts agree, and a store that holds another array is
//! refused rather than mixed.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use zarrs::array::codec::GzipCodec;
use zarrs::array::{Array, ArrayBuilder, ArrayMetadataOptions, CodecOptions, data_type};
use zarrs::storage::{
    Bytes, OffsetBytesIterator, StorageError, StoreKey, StorePrefix, WritableStorageTraits,
};

use super::shard::Shard;
use super::{to_unit_u8, to_unit_u16, write_atomic};
use crate::error::{Error, Result};
use crate::input_error;

/// Default chunk side: 512 pixels for images (a 512² RGB float32 chunk is 3 MiB), 64 voxels
/// for volumes.
pub const DEFAULT_IMAGE_CHUNK: usize = 512;
pub const DEFAULT_VOLUME_CHUNK: usize = 64;
/// The most values in one chunk (all channels): 2^26, 256 MiB as float32. Memory holds one chunk.
pub const MAX_CHUNK_VALUES: usize = 1 << 26;

/// The element type of the stored array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZarrType {
    /// The generator's values in [-1, 1], as `.npy` output holds them.
    Float32,
    /// `round((v + 1) / 2 * 255)`, as 8-bit PNG output.
    Uint8,
    /// `round((v + 1) / 2 * 65535)`, as 16-bit PNG output.
    Uint16,
}

impl ZarrType {
    /// From `--bits`: none is float32; 8 and 16 are unsigned integers.
    pub fn from_bits(bits: Option<u8>) -> Result<Self> {
        match bits {
            None | Some(32) => Ok(Self::Float32),
            Some(8) => Ok(Self::Uint8),
            Some(16) => Ok(Self::Uint16),
            Some(b) => Err(crate::setting_error!(
                "--bits",
                b,
                "Zarr output is float32 (no --bits, or 32), or 8 or 16 bits per channel"
            )),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Float32 => "float32",
            Self::Uint8 => "uint8",
            Self::Uint16 => "uint16",
        }
    }
}

/// What one worker did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ZarrReport {
    /// Chunks in the whole array.
    pub chunks: usize,
    /// Chunks of this shard.
    pub owned: usize,
    /// Chunks of this shard rendered and written now.
    pub written: usize,
    /// Chunks of this shard found complete and skipped.
    pub skipped: usize,
}

impl ZarrReport {
    /// E.g. `shard 1/3: 3 of 9 chunks written, 2 already complete and skipped`.
    pub fn describe(&self, shard: Shard) -> String {
        let which = if shard.count > 1 {
            format!("shard {}/{}: ", shard.index, shard.count)
        } else {
            String::new()
        };
        let skipped = if self.skipped > 0 {
            format!(", {} already complete and skipped", self.skipped)
        } else {
            String::new()
        };
        format!(
            "{which}{} of {} chunks written{skipped}",
            self.written, self.chunks
        )
    }
}

/// A filesystem store whose writes are atomic (temporary file, then rename), which is all that
/// `zarrs` needs of a store to encode and write chunks.
struct AtomicStore {
    root: PathBuf,
}

impl AtomicStore {
    fn path(&self, key: &StoreKey) -> PathBuf {
        self.root.join(key.as_str())
    }
}

fn storage_error(e: Error) -> StorageError {
    StorageError::Other(e.to_string())
}

impl WritableStorageTraits for AtomicStore {
    fn set(&self, key: &StoreKey, value: Bytes) -> std::result::Result<(), StorageError> {
        let path = self.path(key);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        write_atomic(&path, &value).map_err(storage_error)
    }

    fn set_partial_many(
        &self,
        key: &StoreKey,
        _offset_values: OffsetBytesIterator,
    ) -> std::result::Result<(), StorageError> {
        Err(StorageError::Other(format!(
            "{}: partial writes are not atomic and not used",
            key.as_str()
        )))
    }

    fn erase(&self, key: &StoreKey) -> std::result::Result<(), StorageError> {
        match std::fs::remove_file(self.path(key)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        }
    }

    fn erase_prefix(&self, prefix: &StorePrefix) -> std::result::Result<(), StorageError> {
        match std::fs::remove_dir_all(self.root.join(prefix.as_str())) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        }
    }

    fn supports_set_partial(&self) -> bool {
        false
    }
}

/// Writes `bytes` as `file` if no `file` exists, atomically: a temporary file is hard-linked to
/// the name, which fails where another process published first. Returns whether we published.
fn publish_new(file: &Path, bytes: &[u8]) -> Result<bool> {
    use std::io::Write;
    let failed =
        |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", file.display()));
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut temp = tempfile::Builder::new()
        .prefix(".zarr.json.")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(failed)?;
    temp.write_all(bytes).map_err(failed)?;
    temp.as_file().sync_all().map_err(failed)?;
    match std::fs::hard_link(temp.path(), file) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) => Err(failed(e)),
    }
}

/// A Zarr v3 array on disk, opened for writing chunks: its shape is the painted box's shape
/// followed by the channels.
pub struct ZarrWriter {
    path: PathBuf,
    array: Array<AtomicStore>,
    kind: ZarrType,
    /// The painted box (array order, without channels) and the chunk's box.
    shape: Vec<usize>,
    chunk: Vec<usize>,
    channels: usize,
}

impl ZarrWriter {
    /// Creates the array at `path` (a folder ending in `.zarr`), or opens it when it already
    /// holds the same array (another shard of the same render, or an earlier run of this one).
    ///
    /// `shape` is the box in array order (`[H, W]` or `[D, H, W]`); `chunk` the side of a
    /// chunk on every axis; `attributes` are stored with the array.
    pub fn create(
        path: &Path,
        shape: &[usize],
        channels: usize,
        chunk: usize,
        kind: ZarrType,
        attributes: serde_json::Map<String, serde_json::Value>,
    ) -> Result<Self> {
        let shown = path.display();
        if chunk == 0 {
            return Err(input_error!(
                "{shown}: --chunk 0: a chunk side must be at least 1"
            ));
        }
        let parent = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !parent.is_dir() {
            return Err(input_error!(
                "{shown}: cannot write: folder {} does not exist",
                parent.display()
            ));
        }
        let values = (0..shape.len())
            .try_fold(channels, |n, _| n.checked_mul(chunk))
            .filter(|&n| n <= MAX_CHUNK_VALUES);
        if values.is_none() {
            return Err(input_error!(
                "{shown}: --chunk {chunk}: a chunk of {chunk}^{} x {channels} values is over {MAX_CHUNK_VALUES} (256 MiB of float32); use a smaller chunk",
                shape.len()
            ));
        }
        if shape.contains(&0) || channels == 0 {
            return Err(input_error!(
                "{shown}: every side of the array must be at least 1"
            ));
        }
        let mut full: Vec<u64> = shape.iter().map(|&s| s as u64).collect();
        full.push(channels as u64);
        let chunk_box: Vec<usize> = shape.iter().map(|&s| chunk.min(s)).collect();
        let mut chunk_shape: Vec<u64> = chunk_box.iter().map(|&c| c as u64).collect();
        chunk_shape.push(channels as u64);
        let names: Vec<&str> = match shape.len() {
            2 => vec!["y", "x", "c"],
            _ => vec!["z", "y", "x", "c"],
        };
        let (dtype, fill) = match kind {
            ZarrType::Float32 => (data_type::float32(), zarrs::array::FillValue::from(0f32)),
            ZarrType::Uint8 => (data_type::uint8(), zarrs::array::FillValue::from(0u8)),
            ZarrType::Uint16 => (data_type::uint16(), zarrs::array::FillValue::from(0u16)),
        };
        let gzip = GzipCodec::new(1).expect("gzip level 1 is valid");
        let store = Arc::new(AtomicStore {
            root: path.to_path_buf(),
        });
        let array = ArrayBuilder::new(full, chunk_shape, dtype, fill)
            .bytes_to_bytes_codecs(vec![Arc::new(gzip)])
            .dimension_names(Some(names))
            .attributes(attributes)
            .build(store, "/")
            .map_err(|e| Error::Runtime(format!("{shown}: cannot describe the array: {e}")))?;
        let writer = Self {
            path: path.to_path_buf(),
            array,
            kind,
            shape: shape.to_vec(),
            chunk: chunk_box,
            channels,
        };
        writer.create_or_check_metadata()?;
        Ok(writer)
    }

    /// Writes `zarr.json`, or checks that the one there describes this very array.
    fn create_or_check_metadata(&self) -> Result<()> {
        let shown = self.path.display();
        // Without zarrs' own version attribute: workers built with another zarrs release still
        // write the same metadata.
        let options = ArrayMetadataOptions::default().with_include_zarrs_metadata(false);
        let metadata = self.array.metadata_opt(&options);
        let ours = serde_json::to_value(&metadata)
            .map_err(|e| Error::Runtime(format!("{shown}: cannot describe the array: {e}")))?;
        let file = self.path.join("zarr.json");
        if self.path.exists() && !self.path.is_dir() {
            return Err(input_error!(
                "{shown}: exists and is not a folder; a Zarr store is a folder: remove it or choose another --out"
            ));
        }
        match std::fs::read(&file) {
            Ok(bytes) => {
                let theirs: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| {
                    crate::file_error!(
                        &file,
                        "not valid Zarr metadata ({e}); remove {shown} or choose another --out",
                    )
                })?;
                if theirs != ours {
                    return Err(input_error!(
                        "{shown}: holds another array (its zarr.json differs from this render's: shape, chunks, type or synth settings); remove it or choose another --out"
                    ));
                }
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // Another worker's `zarr.json` on its way in (`.zarr.json.*.tmp`) is ours.
                let not_empty = std::fs::read_dir(&self.path).is_ok_and(|entries| {
                    entries.flatten().any(|e| {
                        let name = e.file_name().to_string_lossy().into_owned();
                        !(name.starts_with(".zarr.json.") && name.ends_with(".tmp"))
                    })
                });
                if not_empty && file.exists() {
                    // Another worker's `zarr.json` arrived since we looked: check it.
                    return self.create_or_check_metadata();
                }
                if not_empty {
                    return Err(input_error!(
                        "{shown}: is a folder with files but no zarr.json, so not a Zarr store of ours; remove it or choose another --out"
                    ));
                }
                std::fs::create_dir_all(&self.path)
                    .map_err(|e| input_error!("{shown}: cannot create the store: {e}"))?;
                let text = serde_json::to_vec_pretty(&ours).expect("JSON values serialise");
                if publish_new(&file, &text)? {
                    Ok(())
                } else {
                    // Another worker published first: check that it is the same array.
                    self.create_or_check_metadata()
                }
            }
            Err(e) => Err(crate::file_error!(&file, "cannot read: {e}")),
        }
    }

    /// Axes of the painted box: 2 for an image, 3 for a volume.
    pub fn axes(&self) -> usize {
        self.shape.len()
    }

    /// The number of chunks along each axis of the painted box.
    pub fn grid(&self) -> Vec<usize> {
        self.shape
            .iter()
            .zip(&self.chunk)
            .map(|(s, c)| s.div_ceil(*c))
            .collect()
    }

    /// Chunk number `n` (C order): its grid indices, the origin of its box and the box's shape
    /// cut to the array's bounds.
    pub fn chunk_box(&self, n: usize) -> (Vec<u64>, Vec<i64>, Vec<usize>) {
        let grid = self.grid();
        let mut indices = vec![0u64; grid.len()];
        let mut rest = n;
        for axis in (0..grid.len()).rev() {
            indices[axis] = (rest % grid[axis]) as u64;
            rest /= grid[axis];
        }
        let origin: Vec<i64> = indices
            .iter()
            .zip(&self.chunk)
            .map(|(&i, &c)| i as i64 * c as i64)
            .collect();
        let shape: Vec<usize> = origin
            .iter()
            .zip(&self.chunk)
            .zip(&self.shape)
            .map(|((&o, &c), &s)| c.min(s - o as usize))
            .collect();
        (indices, origin, shape)
    }

    /// Whether chunk `indices` is already on disk (and so complete: chunks appear by rename).
    pub fn is_complete(&self, indices: &[u64]) -> bool {
        let mut all = indices.to_vec();
        all.push(0);
        self.path
            .join(self.array.chunk_key(&all).as_str())
            .is_file()
    }

    /// Removes temporary files that a stopped worker left for the chunks `owned` selects.
    pub fn remove_stale_temporaries(&self, owned: impl Fn(usize) -> bool) -> usize {
        let total: usize = self.grid().iter().product();
        let mut folders = std::collections::BTreeSet::new();
        let mut names = std::collections::HashSet::new();
        for n in (0..total).filter(|&n| owned(n)) {
            let (mut indices, _, _) = self.chunk_box(n);
            indices.push(0);
            let file = self.path.join(self.array.chunk_key(&indices).as_str());
            if let (Some(dir), Some(name)) = (file.parent(), file.file_name()) {
                folders.insert(dir.to_path_buf());
                names.insert((dir.to_path_buf(), name.to_string_lossy().into_owned()));
            }
        }
        let mut removed = 0;
        for dir in folders {
            let Ok(entries) = std::fs::read_dir(&dir) else {
                continue;
            };
            for entry in entries.flatten() {
                let name = entry.file_name().to_string_lossy().into_owned();
                // Temporary files are `.{name}.{random}.tmp` (see `AtomicFile`).
                let Some(inner) = name.strip_prefix('.').and_then(|n| n.strip_suffix(".tmp"))
                else {
                    continue;
                };
                let Some((chunk, _)) = inner.rsplit_once('.') else {
                    continue;
                };
                if names.contains(&(dir.clone(), chunk.to_string()))
                    && std::fs::remove_file(entry.path()).is_ok()
                {
                    removed += 1;
                }
            }
        }
        removed
    }

    /// Encodes and writes chunk `indices` from the rendered values of its box (`shape`, as
    /// [`ZarrWriter::chunk_box`] gives it; generator values in [-1, 1], channels last), padded
    /// to the chunk's full shape with the fill value at the array's edges.
    pub fn write_chunk(&self, indices: &[u64], shape: &[usize], values: &[f32]) -> Result<()> {
        let c = self.channels;
        let full: usize = self.chunk.iter().product::<usize>() * c;
        let mut padded = vec![0f32; full];
        if shape == self.chunk.as_slice() {
            padded.copy_from_slice(values);
        } else {
            // Copy row by row (the last axis) into the full chunk.
            let row = shape[shape.len() - 1] * c;
            let rows: usize = shape[..shape.len() - 1].iter().product();
            for r in 0..rows {
                // The row's position in the full chunk: unravel r over shape[..n-1].
                let mut rest = r;
                let mut at = 0;
                let mut stride = self.chunk[self.chunk.len() - 1] * c;
                for axis in (0..shape.len() - 1).rev() {
                    at += (rest % shape[axis]) * stride;
                    rest /= shape[axis];
                    stride *= self.chunk[axis];
                }
                padded[at..at + row].copy_from_slice(&values[r * row..(r + 1) * row]);
            }
        }
        let mut all = indices.to_vec();
        all.push(0);
        let options = CodecOptions::default().with_store_empty_chunks(true);
        let stored = match self.kind {
            ZarrType::Float32 => self.array.store_chunk_opt(&all, padded, &options),
            ZarrType::Uint8 => {
                let v: Vec<u8> = padded.iter().map(|&v| to_unit_u8(v)).collect();
                self.array.store_chunk_opt(&all, v, &options)
            }
            ZarrType::Uint16 => {
                let v: Vec<u16> = padded.iter().map(|&v| to_unit_u16(v)).collect();
                self.array.store_chunk_opt(&all, v, &options)
            }
        };
        stored.map_err(|e| {
            Error::Runtime(format!(
                "{}: cannot write chunk {indices:?}: {e}",
                self.path.display()
            ))
        })
    }

    /// A one-line description: shape, chunks and type.
    pub fn describe(&self) -> String {
        let mut shape = self.shape.clone();
        shape.push(self.channels);
        let mut chunk = self.chunk.clone();
        chunk.push(self.channels);
        format!(
            "Zarr v3 {} {shape:?} in chunks of {chunk:?} (gzip level 1)",
            self.kind.name()
        )
    }
}
