//! `ipfn voxelize`: meshes (.obj, .ply) to signed-distance volumes.

use crate::common::{assert_error, ipfn, stderr};
use ipfn::io::read_npy;
use ipfn::mesh::{Mesh, write_mesh};

const RADIUS: f32 = 1.0;

/// A UV sphere of `RADIUS` around the origin (closed, consistently wound).
fn sphere(rings: u32, segments: u32) -> Mesh {
    let mut mesh = Mesh::default();
    mesh.positions.push([0.0, 0.0, RADIUS]);
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            mesh.positions.push([
                RADIUS * theta.sin() * phi.cos(),
                RADIUS * theta.sin() * phi.sin(),
                RADIUS * theta.cos(),
            ]);
        }
    }
    mesh.positions.push([0.0, 0.0, -RADIUS]);
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let bottom = mesh.positions.len() as u32 - 1;
    for s in 0..segments {
        mesh.triangles.push([0, ring(1, s), ring(1, s + 1)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r + 1, s),
                ring(r + 1, s + 1),
                ring(r, s + 1),
            );
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
        mesh.triangles
            .push([ring(rings - 1, s), bottom, ring(rings - 1, s + 1)]);
    }
    mesh
}

#[test]
fn a_sphere_becomes_its_signed_distance_from_obj_and_ply_alike() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = sphere(32, 64);
    write_mesh(&mesh, &d.join("sphere.obj")).unwrap();
    write_mesh(&mesh, &d.join("sphere.ply")).unwrap();
    let res = 32;
    let mut volumes = Vec::new();
    for file in ["sphere.obj", "sphere.ply"] {
        let out = format!("{file}.npy");
        let o = ipfn(
            d,
            &[
                "voxelize",
                file,
                "--res",
                "32",
                "--padding",
                "0.25",
                "-o",
                &out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!stderr(&o).contains("open edges"), "{}", stderr(&o));
        let (shape, values) = read_npy(&d.join(&out)).unwrap();
        assert_eq!(shape, vec![res, res, res, 1]);
        volumes.push(values);
    }
    assert_eq!(volumes[0], volumes[1], "OBJ and PLY give the same volume");

    // The cube spans the sphere's box (side 2) widened by 25% on each side: side 3.
    let side = 2.0 * RADIUS * 1.5;
    let step = side / res as f32;
    let mut worst = 0f32;
    for (q, &v) in volumes[0].iter().enumerate() {
        let (x, y, z) = (q % res, q / res % res, q / (res * res));
        let c = |i: usize| (i as f32 + 0.5 - res as f32 * 0.5) * step;
        let exact = ((c(x).powi(2) + c(y).powi(2) + c(z).powi(2)).sqrt() - RADIUS) / side;
        assert_eq!(
            v < 0.0,
            exact < 0.0,
            "voxel ({x}, {y}, {z}): sign of {v} vs exact {exact}"
        );
        worst = worst.max((v - exact).abs());
    }
    // The 32x64 sphere departs from the true one by at most 0.5% of its radius.
    eprintln!("worst distance error: {worst:.2e} of the side");
    assert!(
        worst < 0.005 * RADIUS / side,
        "worst distance error {worst}"
    );
}

#[test]
fn an_open_mesh_is_voxelized_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut mesh = sphere(16, 32);
    mesh.triangles.truncate(mesh.triangles.len() - 5); // a hole at the bottom
    write_mesh(&mesh, &d.join("open.obj")).unwrap();
    let o = ipfn(d, &["voxelize", "open.obj", "--res", "16", "-o", "v.npy"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("open edges"), "{}", stderr(&o));
    let (_, values) = read_npy(&d.join("v.npy")).unwrap();
    let centre = (8 * 16 + 8) * 16 + 8;
    assert!(values[centre] < 0.0, "the centre is still inside");
    assert!(values[0] > 0.0, "a corner is outside");
    // The same volume as bare little-endian float32.
    let o = ipfn(d, &["voxelize", "open.obj", "--res", "16", "-o", "v.raw"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let raw: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    assert!(std::fs::read(d.join("v.raw")).unwrap() == raw);
}

#[test]
fn bad_voxelize_input_is_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("junk.obj"), "this is not a mesh\n").unwrap();
    std::fs::write(d.join("junk.ply"), "ply\nformat nonsense\n").unwrap();
    write_mesh(&sphere(8, 8), &d.join("s.obj")).unwrap();
    assert_error(
        &ipfn(d, &["voxelize", "junk.obj", "-o", "v.npy"]),
        &["junk.obj"],
    );
    assert_error(
        &ipfn(d, &["voxelize", "junk.ply", "-o", "v.npy"]),
        &["junk.ply", "not a readable mesh"],
    );
    assert_error(
        &ipfn(d, &["voxelize", "missing.obj", "-o", "v.npy"]),
        &["missing.obj", "no such file"],
    );
    assert_error(
        &ipfn(d, &["voxelize", "s.obj", "--res", "0", "-o", "v.npy"]),
        &["--res 0"],
    );
    assert_error(
        &ipfn(d, &["voxelize", "s.obj", "--res", "5000", "-o", "v.npy"]),
        &["s.obj", "--res 5000", "at most 1024"],
    );
    assert_error(
        &ipfn(d, &["voxelize", "s.obj", "-o", "v.png"]),
        &["v.png", ".npy"],
    );
    std::fs::write(d.join("s.stl"), "solid x\n").unwrap();
    assert_error(&ipfn(d, &["voxelize", "s.stl", "-o", "v.npy"]), &["s.stl"]);
}
