//! Surface meshes ([`TriMesh`]) as files that Blender, Houdini and ParaView open as they are:
//!
//! * [`write_obj`]: Wavefront OBJ with `v`, `vn` and `f a//a b//b c//c` lines (Blender's
//!   OBJ importer, Houdini, meshio).
//! * [`write_mesh_ply`]: binary little-endian PLY, `vertex` (`x y z nx ny nz`, float) and
//!   `face` (`list uchar int vertex_indices`), the layout Blender's PLY importer expects.
//! * [`write_mesh_vtu`]: VTK XML UnstructuredGrid of `VTK_TRIANGLE` cells with the point array
//!   `Normals`, zlib-compressed appended data (ParaView).
//!
//! Every file is written atomically (temporary file + rename).

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use super::vtu::{CellKind, Encoding, OutArray, write_unstructured};
use rtmpm_geometry::surface::TriMesh;

fn checked(mesh: &TriMesh) -> io::Result<()> {
    mesh.check()
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, format!("bad mesh: {e}")))?;
    if mesh.vertices.len() > i32::MAX as usize {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "more vertices than PLY/VTK int indices hold",
        ));
    }
    Ok(())
}

/// Write `mesh` as a Wavefront OBJ file (1-based indices; normals when the mesh has them).
pub fn write_obj(path: &Path, mesh: &TriMesh) -> io::Result<()> {
    checked(mesh)?;
    write_atomic_with(path, |w| {
        writeln!(
            w,
            "# rtmpm fluid surface: {} vertices, {} triangles",
            mesh.vertices.len(),
            mesh.triangles.len()
        )?;
        for v in &mesh.vertices {
            writeln!(w, "v {} {} {}", v.x, v.y, v.z)?;
        }
        for n in &mesh.normals {
            writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
        }
        let with_n = !mesh.normals.is_empty();
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i + 1);
            if with_n {
                writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
            } else {
                writeln!(w, "f {a} {b} {c}")?;
            }
        }
        Ok(())
    })
}

/// Write `mesh` as a binary little-endian PLY file with vertex normals (zero when absent).
pub fn write_mesh_ply(path: &Path, mesh: &TriMesh) -> io::Result<()> {
    checked(mesh)?;
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment rtmpm fluid surface\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.triangles.len()
    );
    write_atomic_with(path, |w| {
        w.write_all(header.as_bytes())?;
        let mut buf = Vec::with_capacity(64 * 1024);
        for (i, v) in mesh.vertices.iter().enumerate() {
            let n = mesh.normals.get(i).copied().unwrap_or_default();
            for c in [v.x, v.y, v.z, n.x, n.y, n.z] {
                buf.extend_from_slice(&c.to_le_bytes());
            }
            if buf.len() > 60 * 1024 {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        for t in &mesh.triangles {
            buf.push(3);
            for i in t {
                buf.extend_from_slice(&(*i as i32).to_le_bytes());
            }
            if buf.len() > 60 * 1024 {
                w.write_all(&buf)?;
                buf.clear();
            }
        }
        w.write_all(&buf)
    })
}

/// Write `mesh` as a `.vtu` of triangles with the point array `Normals` (when present),
/// zlib-compressed when `compress`.
pub fn write_mesh_vtu(path: &Path, mesh: &TriMesh, compress: bool) -> io::Result<()> {
    checked(mesh)?;
    let points: Vec<[f32; 3]> = mesh.vertices.iter().map(|v| v.to_array()).collect();
    let mut arrays = Vec::new();
    let mut active = Vec::new();
    if !mesh.normals.is_empty() {
        arrays.push(OutArray::f32(
            "Normals",
            3,
            mesh.normals.iter().flat_map(|n| n.to_array()),
        ));
        active.push(("Normals", "Normals"));
    }
    write_unstructured(
        path,
        &points,
        CellKind::Triangles,
        &mesh.triangles,
        &arrays,
        &active,
        Encoding::appended(compress),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ply::{PlyColumn, read_ply};
    use crate::testing::TestDir;
    use crate::vtu::VtuValues;
    use crate::vtu::read_any_vtu;
    use rtmpm_physics::math::Vec3;

    /// A tetrahedron with outward triangles and per-vertex normals.
    pub(crate) fn tetra() -> TriMesh {
        let vertices = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let c = Vec3::splat(0.25);
        TriMesh {
            normals: vertices.iter().map(|v| (*v - c).normalize()).collect(),
            vertices,
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn writes_obj_ply_vtu() {
        let d = TestDir::new("trimesh");
        let m = tetra();
        assert!((m.volume() - 1.0 / 6.0).abs() < 1e-9);
        let obj = d.path("s.obj");
        write_obj(&obj, &m).unwrap();
        let text = std::fs::read_to_string(&obj).unwrap();
        assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 4);
        assert_eq!(text.lines().filter(|l| l.starts_with("vn ")).count(), 4);
        assert!(text.contains("\nf 1//1 3//3 2//2\n"), "{text}");
        // tobj (the OBJ reader the colliders use) reads it back.
        let (models, _) = tobj::load_obj(&obj, &tobj::GPU_LOAD_OPTIONS).unwrap();
        let tm = &models[0].mesh;
        // Corners in order (tobj renumbers the vertices).
        let corners: Vec<[f32; 3]> = tm
            .indices
            .iter()
            .map(|&i| {
                let i = 3 * i as usize;
                [tm.positions[i], tm.positions[i + 1], tm.positions[i + 2]]
            })
            .collect();
        let want: Vec<[f32; 3]> = m
            .triangles
            .iter()
            .flatten()
            .map(|&i| m.vertices[i as usize].to_array())
            .collect();
        assert_eq!(corners, want);
        assert_eq!(tm.normals.len(), tm.positions.len());

        let ply = d.path("s.ply");
        write_mesh_ply(&ply, &m).unwrap();
        let r = read_ply(&ply).unwrap();
        assert_eq!(r.count, 4);
        assert_eq!(r.names(), ["x", "y", "z", "nx", "ny", "nz"]);
        assert_eq!(
            r.column("y"),
            Some(&PlyColumn::Float(vec![0.0, 0.0, 1.0, 0.0]))
        );
        let bytes = std::fs::read(&ply).unwrap();
        // The faces close the file: 4 x (1 + 3 x 4) bytes.
        let tail = &bytes[bytes.len() - 52..];
        assert_eq!(tail[0], 3);
        assert_eq!(&tail[1..13], &[0, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0]);

        let vtu = d.path("s.vtu");
        write_mesh_vtu(&vtu, &m, true).unwrap();
        let r = read_any_vtu(&vtu).unwrap();
        assert_eq!((r.num_points, r.num_cells), (4, 4));
        let types = r.cells.iter().find(|a| a.name == "types").unwrap();
        assert_eq!(types.values, VtuValues::UInt8(vec![5; 4]));
        assert_eq!(r.point_array("Normals").unwrap().num_components, 3);
    }

    #[test]
    fn bad_meshes_are_refused() {
        let d = TestDir::new("trimesh-bad");
        let mut m = tetra();
        m.triangles.push([0, 1, 9]);
        assert!(write_obj(&d.path("a.obj"), &m).is_err());
        assert!(!d.path("a.obj").exists());
        let mut m = tetra();
        m.normals.pop();
        assert!(write_mesh_ply(&d.path("a.ply"), &m).is_err());
    }
}
