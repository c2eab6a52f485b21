//! Meshes of a volume's zero level set, extracted slab by slab with Naive Surface Nets (the
//! `fast-surface-nets` crate) and welded into one watertight mesh.
//!
//! Chunking: `fast-surface-nets` makes no faces on a chunk's positive boundary, so chunks that
//! share two sample slices (`[s_k, e_k]`, then `[e_k - 1, ...]`) produce, between them, exactly
//! the faces of the whole volume. The cubes in the shared layer give each chunk its own copy of a
//! vertex; vertices are welded by their cube's global position, so the union is one mesh with no
//! seams (tested against the single-chunk mesh).

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};

use crate::error::{Error, Result};
use crate::input_error;
use crate::io::AtomicFile;

/// A triangle mesh in voxel units: `x` along columns, `y` along rows, `z` along depth.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// The cube (its minimal corner `[x, y, z]`) each vertex belongs to.
    pub cells: Vec<[u32; 3]>,
}

/// Builds the mesh of a `depth x height x width` volume from chunks of whole depth slices.
pub struct MeshBuilder {
    height: usize,
    width: usize,
    mesh: Mesh,
    /// Global cube (x, y, z) of each welded vertex -> its index.
    welded: HashMap<[u32; 3], u32>,
    buffer: SurfaceNetsBuffer,
}

impl MeshBuilder {
    pub fn new(height: usize, width: usize) -> Self {
        Self {
            height,
            width,
            mesh: Mesh::default(),
            welded: HashMap::new(),
            buffer: SurfaceNetsBuffer::default(),
        }
    }

    /// Adds the chunk of signed distances `values` (`[slices, height, width]`, negative inside)
    /// whose first slice is `z_start`. Consecutive chunks must share their last two slices with
    /// the next chunk's first two (see [`chunk_starts`]).
    pub fn add_chunk(&mut self, values: &[f32], z_start: usize) {
        let (h, w) = (self.height, self.width);
        let slices = values.len() / (h * w);
        if slices < 2 || h < 2 || w < 2 {
            return; // no cubes
        }
        // Our layout is [z][y][x] with x fastest, which is ndshape's [x, y, z] linearisation.
        let shape = RuntimeShape::<u32, 3>::new([w as u32, h as u32, slices as u32]);
        debug_assert_eq!(shape.size() as usize, values.len());
        surface_nets(
            values,
            &shape,
            [0, 0, 0],
            [w as u32 - 1, h as u32 - 1, slices as u32 - 1],
            &mut self.buffer,
        );
        let z0 = z_start as u32;
        // Local vertex index -> welded index.
        let remap: Vec<u32> = self
            .buffer
            .surface_points
            .iter()
            .zip(&self.buffer.positions)
            .map(|(&[x, y, z], p)| {
                let key = [x, y, z + z0];
                *self.welded.entry(key).or_insert_with(|| {
                    self.mesh.positions.push([p[0], p[1], p[2] + z0 as f32]);
                    self.mesh.cells.push(key);
                    self.mesh.positions.len() as u32 - 1
                })
            })
            .collect();
        for t in self.buffer.indices.chunks_exact(3) {
            self.mesh.triangles.push([
                remap[t[0] as usize],
                remap[t[1] as usize],
                remap[t[2] as usize],
            ]);
        }
    }

    pub fn finish(self) -> Mesh {
        self.mesh
    }
}

/// First slices of the chunks of a `depth`-slice volume, about `slices` per chunk, each chunk
/// running to the next start + 1 (the last to `depth - 1`): `(start, end inclusive)` pairs.
pub fn chunk_starts(depth: usize, slices: usize) -> Vec<(usize, usize)> {
    let step = slices.max(1);
    let mut chunks = Vec::new();
    let mut start = 0;
    while start + 1 < depth {
        let end = (start + step + 1).min(depth - 1);
        chunks.push((start, end));
        if end == depth - 1 {
            break;
        }
        start = end - 1;
    }
    chunks
}

/// Edges used by exactly one triangle (a watertight mesh has none, except where the surface
/// meets the volume's outer box).
pub fn boundary_edges(mesh: &Mesh) -> Vec<[u32; 2]> {
    let mut count: HashMap<[u32; 2], u32> = HashMap::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry([a.min(b), a.max(b)]).or_insert(0) += 1;
        }
    }
    count
        .into_iter()
        .filter(|&(_, n)| n == 1)
        .map(|(e, _)| e)
        .collect()
}

/// A mesh file format, chosen by the extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    Obj,
    Ply,
}

impl MeshFormat {
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "obj" => Ok(Self::Obj),
            "ply" => Ok(Self::Ply),
            _ => Err(input_error!(
                "{}: meshes are written as .obj or .ply",
                path.display()
            )),
        }
    }
}

/// Writes `.obj` or `.ply` (ASCII), chosen by the extension, atomically.
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<()> {
    let format = MeshFormat::from_path(path)?;
    let mut file = AtomicFile::create(path)?;
    let err = |e: std::io::Error| Error::Runtime(format!("{}: cannot write: {e}", path.display()));
    {
        let mut out = std::io::BufWriter::new(file.file());
        if format == MeshFormat::Obj {
            writeln!(out, "# ipfn: zero level set, voxel units").map_err(err)?;
            for p in &mesh.positions {
                writeln!(out, "v {} {} {}", p[0], p[1], p[2]).map_err(err)?;
            }
            for t in &mesh.triangles {
                writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).map_err(err)?;
            }
        } else {
            writeln!(
                out,
                "ply\nformat ascii 1.0\ncomment ipfn: zero level set, voxel units\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header",
                mesh.positions.len(),
                mesh.triangles.len()
            )
            .map_err(err)?;
            for p in &mesh.positions {
                writeln!(out, "{} {} {}", p[0], p[1], p[2]).map_err(err)?;
            }
            for t in &mesh.triangles {
                writeln!(out, "3 {} {} {}", t[0], t[1], t[2]).map_err(err)?;
            }
        }
        out.flush().map_err(err)?;
    }
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh_in_chunks(sdf: &[f32], n: usize, slices: usize) -> Mesh {
        let mut builder = MeshBuilder::new(n, n);
        for (start, end) in chunk_starts(n, slices) {
            builder.add_chunk(&sdf[start * n * n..(end + 1) * n * n], start);
        }
        builder.finish()
    }

    /// Triangles as sets of their vertices' cubes, order-free.
    fn by_cells(mesh: &Mesh) -> Vec<[[u32; 3]; 3]> {
        let mut v: Vec<[[u32; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let mut c = t.map(|i| mesh.cells[i as usize]);
                c.sort();
                c
            })
            .collect();
        v.sort();
        v
    }

    #[test]
    fn chunks_share_two_slices_and_cover_the_volume() {
        assert_eq!(chunk_starts(10, 4), [(0, 5), (4, 9)]);
        assert_eq!(chunk_starts(10, 100), [(0, 9)]);
        assert_eq!(chunk_starts(5, 1), [(0, 2), (1, 3), (2, 4)]);
        assert!(chunk_starts(1, 4).is_empty());
    }

    #[test]
    fn chunked_meshes_equal_the_whole_and_have_no_seams() {
        let n = 24;
        let sdf = crate::procedural::gyroid_sdf(n, 16.0, 0.4);
        let whole = mesh_in_chunks(&sdf, n, n);
        assert!(whole.triangles.len() > 1000, "{}", whole.triangles.len());
        for slices in [1, 3, 7] {
            let chunked = mesh_in_chunks(&sdf, n, slices);
            assert_eq!(
                chunked.positions.len(),
                whole.positions.len(),
                "welded vertices, slabs of {slices}"
            );
            assert_eq!(by_cells(&chunked), by_cells(&whole), "slabs of {slices}");
            // Open edges only where the surface leaves the volume's box, never at a seam.
            let outer = |c: [u32; 3]| c.contains(&0) || c.contains(&((n - 2) as u32));
            let open = boundary_edges(&chunked);
            assert!(!open.is_empty(), "the gyroid is cut by the box");
            for [a, b] in open {
                let (ca, cb) = (chunked.cells[a as usize], chunked.cells[b as usize]);
                assert!(outer(ca) && outer(cb), "open edge inside: {ca:?}-{cb:?}");
            }
        }
    }
}
