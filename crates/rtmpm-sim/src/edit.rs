//! New values for some columns of every particle between steps ([`ParticleEdit`]): what the
//! Python package's setters hand to a backend.

use crate::error::SimError;
use rtmpm_physics::math::{Mat3, Vec3};

/// Columns to overwrite, each with one value per particle in original order (f32, widened
/// exactly by an f64 backend); `None` keeps that column. The rest of each particle's state
/// (mass, volume, material, plastic state) is kept.
#[derive(Clone, Copy, Debug, Default)]
pub struct ParticleEdit<'a> {
    /// Positions (m).
    pub x: Option<&'a [Vec3]>,
    /// Velocities (m/s).
    pub v: Option<&'a [Vec3]>,
    /// APIC affine matrices (about the velocity gradient, 1/s).
    pub c: Option<&'a [Mat3]>,
    /// Deformation gradients.
    pub f: Option<&'a [Mat3]>,
}

impl ParticleEdit<'_> {
    /// An error when a given column does not have one value per particle (`n`).
    pub fn check_lengths(&self, n: usize) -> Result<(), SimError> {
        let lens = [
            ("positions", self.x.map(<[Vec3]>::len)),
            ("velocities", self.v.map(<[Vec3]>::len)),
            ("affine matrices (C)", self.c.map(<[Mat3]>::len)),
            ("deformation gradients (F)", self.f.map(<[Mat3]>::len)),
        ];
        for (what, len) in lens {
            if let Some(len) = len
                && len != n
            {
                return Err(SimError::Backend(format!(
                    "{len} {what} given for {n} particles"
                )));
            }
        }
        Ok(())
    }

    /// True when nothing is given.
    pub fn is_empty(&self) -> bool {
        self.x.is_none() && self.v.is_none() && self.c.is_none() && self.f.is_none()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_must_match_the_particle_count() {
        let x = [Vec3::ZERO; 3];
        let c = [Mat3::IDENTITY; 2];
        let e = ParticleEdit {
            x: Some(&x),
            ..Default::default()
        };
        assert!(e.check_lengths(3).is_ok());
        let e = ParticleEdit {
            x: Some(&x),
            c: Some(&c),
            ..Default::default()
        };
        let m = e.check_lengths(3).unwrap_err().to_string();
        assert!(
            m.contains("2 affine matrices (C) given for 3 particles"),
            "{m}"
        );
        assert!(ParticleEdit::default().is_empty());
    }
}
