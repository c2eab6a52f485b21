//! Meshes in and out: a volume's zero level set, extracted slab by slab with Naive Surface Nets
//! (the `fast-surface-nets` crate) and welded into one watertight mesh; and a mesh file turned
//! into a signed-distance volume ([`voxelize`]) to train on.
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
        let ext = crate::io::extension(path);
        match ext.as_str() {
            "obj" => Ok(Self::Obj),
            "ply" => Ok(Self::Ply),
            _ => Err(crate::file_error!(
                &path,
                "meshes are written as .obj or .ply",
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

/// Reads a triangle mesh: `.obj` (the `tobj` crate; polygons are triangulated, all objects
/// merged) or `.ply` (the `ply-rs-bw` crate; ASCII or binary, faces fan-triangulated), in the
/// file's own units.
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    if !path.exists() {
        return Err(crate::file_error!(&path, "no such file"));
    }
    let bad = |why: String| {
        let why = why.split_whitespace().collect::<Vec<_>>().join(" ");
        crate::file_error!(&path, "not a readable mesh ({why})")
    };
    let mut mesh = Mesh::default();
    match MeshFormat::from_path(path)? {
        MeshFormat::Obj => {
            let options = tobj::LoadOptions {
                triangulate: true,
                single_index: false,
                ..Default::default()
            };
            let (models, _) = tobj::load_obj(path, &options).map_err(|e| bad(e.to_string()))?;
            for model in models {
                let base = mesh.positions.len() as u32;
                mesh.positions.extend(
                    model
                        .mesh
                        .positions
                        .chunks_exact(3)
                        .map(|p| [p[0], p[1], p[2]]),
                );
                mesh.triangles.extend(
                    model
                        .mesh
                        .indices
                        .chunks_exact(3)
                        .map(|t| [base + t[0], base + t[1], base + t[2]]),
                );
            }
        }
        MeshFormat::Ply => {
            use ply_rs_bw::ply::Property;
            let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
            let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
            let ply = parser
                .read_ply(&mut std::io::BufReader::new(file))
                .map_err(|e| bad(e.to_string()))?;
            let coordinate = |v: &ply_rs_bw::ply::DefaultElement, k: &str| {
                v.get(k)
                    .and_then(Property::to_f32_lossy)
                    .ok_or_else(|| bad(format!("a vertex has no numeric '{k}'")))
            };
            for v in ply.payload.get("vertex").into_iter().flatten() {
                mesh.positions.push([
                    coordinate(v, "x")?,
                    coordinate(v, "y")?,
                    coordinate(v, "z")?,
                ]);
            }
            for f in ply.payload.get("face").into_iter().flatten() {
                let list = f.get("vertex_indices").or_else(|| f.get("vertex_index"));
                let indices: Vec<i64> = match list {
                    Some(Property::ListInt(v)) => v.iter().map(|&i| i as i64).collect(),
                    Some(Property::ListUInt(v)) => v.iter().map(|&i| i as i64).collect(),
                    Some(Property::ListShort(v)) => v.iter().map(|&i| i as i64).collect(),
                    Some(Property::ListUShort(v)) => v.iter().map(|&i| i as i64).collect(),
                    Some(Property::ListChar(v)) => v.iter().map(|&i| i as i64).collect(),
                    Some(Property::ListUChar(v)) => v.iter().map(|&i| i as i64).collect(),
                    _ => return Err(bad("a face has no integer 'vertex_indices' list".into())),
                };
                let n = mesh.positions.len() as i64;
                if indices.iter().any(|&i| i < 0 || i >= n) {
                    return Err(bad("a face indexes a vertex that does not exist".into()));
                }
                for k in 1..indices.len().saturating_sub(1) {
                    mesh.triangles.push([
                        indices[0] as u32,
                        indices[k] as u32,
                        indices[k + 1] as u32,
                    ]);
                }
            }
        }
    }
    if mesh.triangles.is_empty() {
        return Err(bad("it has no faces".into()));
    }
    if mesh.positions.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad("it has NaN or infinite vertex positions".into()));
    }
    Ok(mesh)
}

/// A signed-distance volume made from a mesh by [`voxelize`].
#[derive(Debug, Clone, PartialEq)]
pub struct Voxelized {
    /// `[res, res, res]` (z, y, x), negative inside, in units of the volume's side.
    pub values: Vec<f32>,
    pub res: usize,
    /// Edges used by one triangle only (after welding equal positions): 0 for a closed mesh.
    pub open_edges: usize,
}

/// The largest `--res` of [`voxelize`]: the volume is held in memory, 4 GiB of floats at 1024³.
pub const MAX_VOXELIZE_RES: usize = 1024;

/// Samples the signed distance to `mesh` at the centres of a `res³` grid: a cube around the
/// mesh's bounding box, widened by `padding` of its side on each side, with mesh x, y, z along
/// the volume's columns, rows and depth.
///
/// - Distance: to the nearest point of the surface (`parry3d`'s BVH point query), in units of
///   the cube's side, as `ipfn draw gyroid` writes them and as the authors' `sdf_scale` expects.
/// - Sign, by ray parity: along each axis, one ray per line of voxels collects every crossing
///   of the surface, and a voxel is inside when an odd number of crossings lies before it. The
///   three axes vote, so a ray grazing an edge or a vertex, which may count a crossing twice,
///   is outvoted. For an open mesh parity is not defined: rays that pass through a hole see one
///   crossing too few, and the vote only limits the damage, so check `open_edges`.
pub fn voxelize(mesh: &Mesh, res: usize, padding: f32) -> Result<Voxelized> {
    use parry3d::math::Vector;
    use parry3d::query::PointQuery;
    use rayon::prelude::*;

    if res == 0 {
        return Err(input_error!(
            "--res 0: the volume needs at least 1 voxel per side"
        ));
    }
    if res > MAX_VOXELIZE_RES {
        return Err(crate::setting_error!(
            "--res",
            res,
            "at most {MAX_VOXELIZE_RES} (the whole {res}³ volume is held in memory)"
        ));
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0f32, f32::max);
    if extent.is_nan() || extent <= 0.0 {
        return Err(input_error!(
            "the mesh has no extent: all its vertices coincide"
        ));
    }
    let side = extent * (1.0 + 2.0 * padding.max(0.0));
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let step = side / res as f32;
    let grid = VoxelGrid {
        res,
        side,
        centre,
        step,
    };
    let at = |a: usize, i: usize| grid.at(a, i);

    let vertices: Vec<Vector> = mesh
        .positions
        .iter()
        .map(|p| Vector::new(p[0], p[1], p[2]))
        .collect();
    let trimesh = parry3d::shape::TriMesh::new(vertices, mesh.triangles.clone())
        .map_err(|e| input_error!("the mesh cannot be indexed for distance queries ({e:?})"))?;

    let n = res * res * res;
    let votes = inside_votes(&trimesh, &grid);
    let values: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|q| {
            let (x, y, z) = (q % res, q / res % res, q / (res * res));
            let p = Vector::new(at(0, x), at(1, y), at(2, z));
            let d = trimesh.distance_to_local_point(p, false) / side;
            if votes[q] >= 2 { -d } else { d }
        })
        .collect();

    Ok(Voxelized {
        values,
        res,
        open_edges: open_edges(mesh),
    })
}

/// The voxel cube of [`voxelize`]: `res` voxels per side of length `side`, centred on `centre`.
struct VoxelGrid {
    res: usize,
    side: f32,
    centre: [f32; 3],
    step: f32,
}

impl VoxelGrid {
    /// Voxel centre along an axis.
    fn at(&self, a: usize, i: usize) -> f32 {
        self.centre[a] + (i as f32 + 0.5 - self.res as f32 * 0.5) * self.step
    }
}

/// For every voxel, how many of the three axes' rays find it inside (odd crossings before it).
fn inside_votes(trimesh: &parry3d::shape::TriMesh, grid: &VoxelGrid) -> Vec<u8> {
    use parry3d::math::Vector;
    use parry3d::query::{Ray, RayCast};
    use rayon::prelude::*;
    let (res, side, centre) = (grid.res, grid.side, grid.centre);
    let at = |a: usize, i: usize| grid.at(a, i);
    let n = res * res * res;
    let index = |x: usize, y: usize, z: usize| (z * res + y) * res + x;
    let mut votes = vec![0u8; n];
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let lines: Vec<Vec<bool>> = (0..res * res)
            .into_par_iter()
            .map(|line| {
                let (i, j) = (line / res, line % res);
                let mut origin = [0f32; 3];
                origin[u] = at(u, i);
                origin[v] = at(v, j);
                origin[axis] = centre[axis] - side; // outside the cube
                let mut dir = [0f32; 3];
                dir[axis] = 1.0;
                let dir = Vector::new(dir[0], dir[1], dir[2]);
                let start = Vector::new(origin[0], origin[1], origin[2]);
                let length = 2.0 * side;
                let nudge = side * 1e-6;
                // Every crossing along the line, as a distance from `start`.
                let mut crossings = Vec::new();
                let mut travelled = 0f32;
                while let Some(t) = trimesh.cast_local_ray(
                    &Ray::new(start + dir * travelled, dir),
                    length - travelled,
                    false,
                ) {
                    crossings.push(travelled + t);
                    travelled += t + nudge;
                }
                (0..res)
                    .map(|k| {
                        let s = at(axis, k) - origin[axis];
                        crossings.iter().filter(|&&c| c < s).count() % 2 == 1
                    })
                    .collect()
            })
            .collect();
        for (line, inside) in lines.iter().enumerate() {
            let (i, j) = (line / res, line % res);
            for (k, &is_inside) in inside.iter().enumerate() {
                let mut p = [0usize; 3];
                p[axis] = k;
                p[u] = i;
                p[v] = j;
                votes[index(p[0], p[1], p[2])] += is_inside as u8;
            }
        }
    }
    votes
}

/// Edges of the mesh used by one triangle only, after welding vertices at equal positions.
fn open_edges(mesh: &Mesh) -> usize {
    let mut id: HashMap<[u32; 3], u32> = HashMap::new();
    let welded: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.map(f32::to_bits);
            let next = id.len() as u32;
            *id.entry(key).or_insert(next)
        })
        .collect();
    let closed = Mesh {
        positions: Vec::new(),
        triangles: mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| welded[i as usize]))
            .collect(),
        cells: Vec::new(),
    };
    boundary_edges(&closed).len()
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
