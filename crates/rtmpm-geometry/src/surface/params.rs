//! The parameters of a surface reconstruction.

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
