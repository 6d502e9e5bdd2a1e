//! Fluid surfaces: a triangle mesh per frame around the particles of chosen materials (fluids
//! by default), for rendering here and for Houdini, Blender and ParaView.
//!
//! [`reconstruct`] (cargo feature `surface`, on in the `rtmpm` command) runs `splashsurf_lib`
//! (Löschner, Longva, Jeske, Kugelstadt and Bender, "Weighted Laplacian smoothing for surface
//! reconstruction of particle-based fluids", VMV 2023): an SPH density field of the particles
//! (cubic spline kernel) on a sparse marching-cubes grid, split into subdomains processed in
//! parallel, then Laplacian smoothing of the vertices and area-weighted vertex normals,
//! themselves smoothed. Without the feature, [`TriMesh`] and the writers still exist (the
//! renderer draws meshes either way) and [`AVAILABLE`] is false.

#[cfg(feature = "surface")]
mod reconstruct;
#[cfg(feature = "surface")]
pub use reconstruct::reconstruct;

use glam::Vec3;

/// True when this build can reconstruct surfaces (cargo feature `surface`).
pub const AVAILABLE: bool = cfg!(feature = "surface");

/// A triangle mesh with one unit normal per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (m).
    pub vertices: Vec<Vec3>,
    /// Unit normal per vertex, pointing out of the fluid (empty: none computed).
    pub normals: Vec<Vec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// True when the mesh has no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Append `other` (its indices shifted).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.normals.extend_from_slice(&other.normals);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// Check that every index is in range and normals are absent or one per vertex.
    pub fn check(&self) -> Result<(), String> {
        let n = self.vertices.len();
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(format!("{} normals for {n} vertices", self.normals.len()));
        }
        if let Some(t) = self
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(format!("triangle {t:?} indexes past the {n} vertices"));
        }
        Ok(())
    }

    /// Enclosed volume (m^3) by the divergence theorem; positive when the triangles are
    /// oriented outwards and the mesh is closed.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }
}

/// Parameters of the reconstruction; lengths relative to the particle radius as in
/// splashsurf's command line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceParams {
    /// Particle radius (m): the radius of a sphere of the particle's volume,
    /// `(3 V / 4 pi)^(1/3)`.
    pub particle_radius: f32,
    /// SPH smoothing length in particle radii (the kernel's support is twice this).
    pub smoothing_length: f32,
    /// Marching-cubes cell edge in particle radii.
    pub cube_size: f32,
    /// Iso-surface at this fraction of the rest density.
    pub threshold: f32,
    /// Laplacian smoothing iterations of the vertices (0: none).
    pub smoothing_iters: u32,
    /// Smoothing iterations of the vertex normals (0: none).
    pub normal_smoothing_iters: u32,
}

impl SurfaceParams {
    /// splashsurf's recommended settings (smoothing length 2, cube size 0.5, threshold 0.6)
    /// with 10 smoothing iterations of the vertices and 5 of the normals, for particles of
    /// volume `volume` (m^3).
    pub fn for_volume(volume: f32) -> SurfaceParams {
        SurfaceParams {
            particle_radius: radius_of_volume(volume),
            smoothing_length: 2.0,
            cube_size: 0.5,
            threshold: 0.6,
            smoothing_iters: 10,
            normal_smoothing_iters: 5,
        }
    }

    /// Check the values: positive finite lengths, threshold in (0, 1).
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [
            ("particle radius", self.particle_radius),
            ("smoothing length", self.smoothing_length),
            ("cube size", self.cube_size),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("the {name} must be positive, got {v}"));
            }
        }
        if !(self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(format!(
                "the surface threshold must be in (0, 1), got {}",
                self.threshold
            ));
        }
        Ok(())
    }
}

/// Radius of the sphere of volume `v`.
pub fn radius_of_volume(v: f32) -> f32 {
    (3.0 * v.max(0.0) / (4.0 * std::f32::consts::PI)).cbrt()
}
