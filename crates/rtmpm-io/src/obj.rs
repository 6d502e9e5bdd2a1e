//! Triangle meshes in: OBJ files (colliders, bodies and rigid bodies of `shape = "mesh"`), read
//! with the size bound of [`crate::limits`] and parsed by `rtmpm_geometry::mesh::TriMesh::parse_obj`.

use rtmpm_geometry::mesh::{MeshError, TriMesh};
use std::path::Path;

/// Read the OBJ file `path` (all objects, faces triangulated), then scale about the origin and
/// translate: `x' = x * scale + translate`.
pub fn read_obj(
    path: &Path,
    scale: glam::Vec3,
    translate: glam::Vec3,
) -> Result<TriMesh, MeshError> {
    let name = path.display().to_string();
    let bytes = crate::limits::read_bounded(path, crate::limits::MESH_MAX_BYTES, "mesh file")
        .map_err(|source| MeshError::Io {
            path: name.clone(),
            source,
        })?;
    TriMesh::parse_obj(&bytes, &name, scale, translate)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_is_an_io_error() {
        let e = read_obj(
            Path::new("/nonexistent/x.obj"),
            glam::Vec3::ONE,
            glam::Vec3::ZERO,
        )
        .unwrap_err();
        assert!(matches!(e, MeshError::Io { .. }), "{e}");
    }
}
