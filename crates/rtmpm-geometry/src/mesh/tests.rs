use super::*;
use crate::shape::box_distance;
use std::path::Path;

fn cube_obj() -> String {
    // Unit cube [0,1]^3, outward-facing quads (triangulated by tobj).
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
     f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
        .to_string()
}

fn shipped_mesh() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/blob.obj")
}

#[test]
fn closest_point_regions() {
    let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
    let p = closest_point_on_triangle(Vec3::new(0.2, 0.2, 1.0), a, b, c);
    assert!((p - Vec3::new(0.2, 0.2, 0.0)).length() < 1e-6);
    assert_eq!(
        closest_point_on_triangle(Vec3::new(-1.0, -1.0, 0.0), a, b, c),
        a
    );
    assert_eq!(
        closest_point_on_triangle(Vec3::new(2.0, -0.5, 0.0), a, b, c),
        b
    );
    let p = closest_point_on_triangle(Vec3::new(1.0, 1.0, 0.0), a, b, c);
    assert!((p - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6);
    let p = closest_point_on_triangle(Vec3::new(0.5, -1.0, 3.0), a, b, c);
    assert!((p - Vec3::new(0.5, 0.0, 0.0)).length() < 1e-6);
}

#[test]
fn cube_mesh_matches_box_sdf() {
    // Scale/translate so the faces do not coincide with grid planes.
    let scale = Vec3::splat(0.6);
    let tr = Vec3::new(0.13, 0.21, 0.17);
    let mesh = TriMesh::parse_obj(cube_obj().as_bytes(), "cube", scale, tr).unwrap();
    assert_eq!(mesh.triangles.len(), 12);
    let sdf = MeshSdf::build(&mesh, 0.02, 4);
    let center = tr + 0.5 * scale;
    let half = 0.5 * scale;
    let mut max_err: f32 = 0.0;
    let mut rng_state = 12345u32;
    let mut rnd = || {
        rng_state = rng_state.wrapping_mul(1664525).wrapping_add(1013904223);
        (rng_state >> 8) as f32 / (1u32 << 24) as f32
    };
    for _ in 0..2000 {
        let x = center + (Vec3::new(rnd(), rnd(), rnd()) - 0.5) * 0.9;
        let exact = box_distance(x, center, half);
        let d = sdf.distance(x);
        // Trilinear interpolation is exact up to O(h) near edges/corners.
        max_err = max_err.max((d - exact).abs());
        if exact.abs() > 0.03 {
            assert_eq!(d < 0.0, exact < 0.0, "sign at {x}: {d} vs {exact}");
        }
    }
    // Errors of O(h) (h = 0.02) are expected only next to edges and corners.
    assert!(max_err < 0.03, "max error {max_err}");
    assert!((sdf.distance(center) + 0.3).abs() < 1e-3);
    let n = sdf.normal(center + Vec3::new(0.0, 0.29, 0.0));
    assert!((n - Vec3::Y).length() < 0.05, "{n}");
    let n = sdf.normal(center - Vec3::new(0.35, 0.0, 0.0));
    assert!((n + Vec3::X).length() < 0.05, "{n}");
    // Outside the grid: positive and growing.
    let far = center + Vec3::new(5.0, 0.0, 0.0);
    assert!(sdf.distance(far) > 4.0);
    let v = sdf.volume();
    assert!((v - 0.216).abs() < 0.02, "volume {v}");
}

#[test]
fn shipped_mesh_sign() {
    let text = std::fs::read(shipped_mesh()).unwrap();
    let mesh = TriMesh::parse_obj(&text, "blob.obj", Vec3::ONE, Vec3::ZERO).unwrap();
    let sdf = MeshSdf::build(&mesh, 0.05, 3);
    let c = 0.5 * (sdf.mesh_min + sdf.mesh_max);
    assert!(sdf.distance(c) < 0.0);
    assert!(sdf.distance(c + Vec3::splat(10.0)) > 0.0);
    // Every grid point far from the surface has the sign of the inside test at the corners.
    assert!(sdf.values[0] > 0.0);
    assert!(*sdf.values.last().unwrap() > 0.0);
}

#[test]
fn empty_mesh() {
    let e = TriMesh::parse_obj(b"# nothing\n", "e.obj", Vec3::ONE, Vec3::ZERO).unwrap_err();
    assert!(matches!(e, MeshError::Empty { .. }), "{e}");
}

/// Build time of a ~5000-triangle sphere at 64^3 (run with `--ignored --nocapture`).
#[test]
fn build_time_sphere() {
    let mut mesh = TriMesh::default();
    let (nu, nv) = (72usize, 36usize);
    for j in 0..=nv {
        let th = std::f32::consts::PI * j as f32 / nv as f32;
        for i in 0..nu {
            let ph = 2.0 * std::f32::consts::PI * i as f32 / nu as f32;
            mesh.vertices.push(Vec3::new(
                th.sin() * ph.cos(),
                th.cos(),
                th.sin() * ph.sin(),
            ));
        }
    }
    for j in 0..nv {
        for i in 0..nu {
            let a = (j * nu + i) as u32;
            let b = (j * nu + (i + 1) % nu) as u32;
            let c = a + nu as u32;
            let d = b + nu as u32;
            mesh.triangles.push([a, b, d]);
            mesh.triangles.push([a, d, c]);
        }
    }
    let t0 = std::time::Instant::now();
    let sdf = MeshSdf::build(&mesh, 2.0 / 58.0, 3);
    let el = t0.elapsed();
    eprintln!(
        "mesh sdf build: {} triangles, grid {:?}: {:.1} ms",
        mesh.triangles.len(),
        sdf.dims,
        el.as_secs_f64() * 1e3
    );
    assert!(sdf.distance(Vec3::ZERO) < -0.95);
    assert!((sdf.distance(Vec3::new(0.0, 0.0, 1.5)) - 0.5).abs() < 0.02);
}
