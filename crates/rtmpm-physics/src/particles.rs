//! Particle state, stored as a struct of arrays so that the CPU loops and the GPU buffers
//! share one layout.

use crate::math::{Mat3, Real, Vec3};

/// All particles of a simulation. Every array has the same length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Particles {
    /// Position (m).
    pub x: Vec<Vec3>,
    /// Velocity (m/s).
    pub v: Vec<Vec3>,
    /// APIC affine velocity matrix `C` (approximates the velocity gradient), 1/s.
    pub c: Vec<Mat3>,
    /// Elastic deformation gradient `F` (for fluids `J^(1/3) I`).
    pub f: Vec<Mat3>,
    /// One scalar of plastic state whose meaning depends on the material: snow `Jp`, sand
    /// hardening `q` / von Mises equivalent plastic strain; unused (0) for purely elastic models and fluid.
    pub plastic: Vec<Real>,
    /// Mass (kg).
    pub mass: Vec<Real>,
    /// Initial volume (m^3).
    pub vol0: Vec<Real>,
    /// Index into the scene's material list.
    pub material: Vec<u32>,
}

impl Particles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Append one particle at rest and undeformed.
    #[allow(clippy::too_many_arguments)]
    pub fn push(&mut self, x: Vec3, v: Vec3, mass: Real, vol0: Real, material: u32, plastic: Real) {
        self.x.push(x);
        self.v.push(v);
        self.c.push(Mat3::ZERO);
        self.f.push(Mat3::IDENTITY);
        self.plastic.push(plastic);
        self.mass.push(mass);
        self.vol0.push(vol0);
        self.material.push(material);
    }

    /// Append all particles of `other`.
    pub fn extend(&mut self, other: &Particles) {
        self.x.extend_from_slice(&other.x);
        self.v.extend_from_slice(&other.v);
        self.c.extend_from_slice(&other.c);
        self.f.extend_from_slice(&other.f);
        self.plastic.extend_from_slice(&other.plastic);
        self.mass.extend_from_slice(&other.mass);
        self.vol0.extend_from_slice(&other.vol0);
        self.material.extend_from_slice(&other.material);
    }

    /// Total mass.
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().map(|&m| m as f64).sum()
    }

    /// Total linear momentum.
    pub fn momentum(&self) -> [f64; 3] {
        let mut p = [0.0f64; 3];
        for (m, v) in self.mass.iter().zip(&self.v) {
            p[0] += (*m * v.x) as f64;
            p[1] += (*m * v.y) as f64;
            p[2] += (*m * v.z) as f64;
        }
        p
    }

    /// Centre of mass.
    pub fn center_of_mass(&self) -> [f64; 3] {
        let mut c = [0.0f64; 3];
        for (m, x) in self.mass.iter().zip(&self.x) {
            c[0] += (*m * x.x) as f64;
            c[1] += (*m * x.y) as f64;
            c[2] += (*m * x.z) as f64;
        }
        let mt = self.total_mass().max(f64::MIN_POSITIVE);
        [c[0] / mt, c[1] / mt, c[2] / mt]
    }

    /// Kinetic energy `sum m |v|^2 / 2`.
    pub fn kinetic_energy(&self) -> f64 {
        self.mass
            .iter()
            .zip(&self.v)
            .map(|(m, v)| 0.5 * (*m as f64) * (v.length_squared() as f64))
            .sum()
    }

    /// Axis-aligned bounding box `(min, max)` of the positions.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(Real::INFINITY);
        let mut hi = Vec3::splat(Real::NEG_INFINITY);
        for x in &self.x {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
        (lo, hi)
    }

    /// How far `other` is from these particles in aggregate, the quantities the backend
    /// agreement tests compare (CPU vs GPU, one GPU vs several).
    pub fn aggregate_difference(&self, other: &Particles) -> AggregateDifference {
        let (ca, cb) = (self.center_of_mass(), other.center_of_mass());
        let com =
            ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2) + (ca[2] - cb[2]).powi(2)).sqrt();
        let (ka, kb) = (self.kinetic_energy(), other.kinetic_energy());
        let ((la, ha), (lb, hb)) = (self.bounding_box(), other.bounding_box());
        let bbox = (la - lb)
            .abs()
            .max_element()
            .max((ha - hb).abs().max_element());
        AggregateDifference {
            com,
            kinetic: (ka - kb).abs() / ka.max(1e-12),
            bbox: bbox as f64,
        }
    }
}

/// See [`Particles::aggregate_difference`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AggregateDifference {
    /// Distance between the centres of mass (m).
    pub com: f64,
    /// Kinetic-energy difference relative to the first set's.
    pub kinetic: f64,
    /// Largest difference of a bounding-box corner coordinate (m).
    pub bbox: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aggregate_difference_of_a_shifted_faster_copy() {
        let mut a = Particles::default();
        a.push(Vec3::new(0.0, 0.0, 0.0), Vec3::X, 1.0, 1.0, 0, 0.0);
        a.push(Vec3::new(1.0, 0.0, 0.0), Vec3::X, 3.0, 1.0, 0, 0.0);
        let mut b = a.clone();
        for x in &mut b.x {
            *x += Vec3::new(0.0, 0.5, 0.0);
        }
        b.v[1] = Vec3::new(2.0, 0.0, 0.0);
        let d = a.aggregate_difference(&b);
        assert!((d.com - 0.5).abs() < 1e-6, "{d:?}");
        assert!((d.bbox - 0.5).abs() < 1e-6, "{d:?}");
        // KE 0.5 + 1.5 = 2 against 0.5 + 6 = 6.5.
        assert!((d.kinetic - 2.25).abs() < 1e-9, "{d:?}");
        assert_eq!(a.aggregate_difference(&a).com, 0.0);
    }
}
