//! The particles of sampled bodies, written once and in parallel straight into the columns of
//! [`Particles`] (no per-particle pushes, no copy of a body's particles into the scene's).

use rayon::iter::repeat_n;
use rayon::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// The particles of a body of a shape before they are written: positions in walk order (the
/// chunks concatenated) and what every particle of the body shares.
#[derive(Clone, Debug)]
pub struct BodyPositions {
    /// The positions, in chunks (concatenated: the walk's order).
    pub chunks: Vec<Vec<Vec3>>,
    /// Their number.
    pub count: usize,
    /// Initial volume of each particle (m^3).
    pub vol0: f32,
    /// Mass of each particle (kg): density x `vol0`.
    pub mass: f32,
    /// Initial plastic state of the material.
    pub plastic: f32,
    /// Material index.
    pub material: u32,
    /// The body's `velocity`, `angular_velocity` and the centroid of its particles (summed in
    /// order, in f32, as the one-thread sampler always did; zero where it cannot matter).
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    pub centre: Vec3,
    /// APIC `C` of every particle: the spin matrix of `angular_velocity`.
    pub c: Mat3,
}

impl BodyPositions {
    /// The initial velocity of the particle at `x`: `v0 + w x (x - c)`.
    #[inline]
    pub fn velocity_at(&self, x: Vec3) -> Vec3 {
        self.velocity + self.angular_velocity.cross(x - self.centre)
    }

    /// The centroid for `velocity_at`: the f32 sum of the positions in order over their count,
    /// or zero when the velocity is the same for every `x` (see [`velocity_is_uniform`]).
    pub(crate) fn centroid(chunks: &[Vec<Vec3>], count: usize, v0: Vec3, w: Vec3) -> Vec3 {
        if velocity_is_uniform(v0, w) {
            Vec3::ZERO
        } else {
            chunks.iter().flatten().fold(Vec3::ZERO, |a, b| a + *b) / count.max(1) as f32
        }
    }
}

/// One body's sampling: the positions of a shape, or the particles of a points file.
#[derive(Debug)]
pub enum SampledBody {
    Shape(BodyPositions),
    Points(Particles),
    /// Counted, its positions left to the backend ([`super::deferred`]).
    Deferred(super::deferred::DeferredBody),
}

impl SampledBody {
    /// Particles of the body.
    pub fn len(&self) -> usize {
        match self {
            SampledBody::Shape(b) => b.count,
            SampledBody::Points(p) => p.len(),
            SampledBody::Deferred(d) => d.shared.count,
        }
    }

    /// True when the body has no particle.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Room for `n` more particles in every column of `out` (address space only: pages are touched
/// when the particles are written).
pub(crate) fn reserve(out: &mut Particles, n: usize) {
    out.x.reserve_exact(n);
    out.v.reserve_exact(n);
    out.c.reserve_exact(n);
    out.f.reserve_exact(n);
    out.plastic.reserve_exact(n);
    out.mass.reserve_exact(n);
    out.vol0.reserve_exact(n);
    out.material.reserve_exact(n);
}

/// True when `v0 + w x (x - c)` equals `v0` bit for bit for every finite `x` and `c`: `w` is
/// zero (so the cross product is a signed zero) and no component of `v0` is -0 (which +0 would
/// turn into +0).
pub(crate) fn velocity_is_uniform(v0: Vec3, w: Vec3) -> bool {
    w == Vec3::ZERO
        && !v0
            .to_array()
            .iter()
            .any(|c| *c == 0.0 && c.is_sign_negative())
}

/// Append the particles of a sampled body to `out`: positions in walk order, velocity
/// [`BodyPositions::velocity_at`], C the spin matrix, F the identity.
pub(crate) fn append(out: &mut Particles, sampled: SampledBody) {
    let b = match sampled {
        SampledBody::Shape(b) => b,
        // Walked here, on the host.
        SampledBody::Deferred(d) => d.positions(),
        SampledBody::Points(p) => {
            out.x.par_extend(p.x.into_par_iter());
            out.v.par_extend(p.v.into_par_iter());
            out.c.par_extend(p.c.into_par_iter());
            out.f.par_extend(p.f.into_par_iter());
            out.plastic.par_extend(p.plastic.into_par_iter());
            out.mass.par_extend(p.mass.into_par_iter());
            out.vol0.par_extend(p.vol0.into_par_iter());
            out.material.par_extend(p.material.into_par_iter());
            return;
        }
    };
    let n = b.count;
    let start = out.x.len();
    // The positions, chunk by chunk into their places.
    out.x.par_extend(repeat_n(Vec3::ZERO, n));
    let mut rest = &mut out.x[start..];
    let mut places = Vec::with_capacity(b.chunks.len());
    for c in &b.chunks {
        let (place, tail) = rest.split_at_mut(c.len());
        places.push(place);
        rest = tail;
    }
    places
        .into_par_iter()
        .zip(b.chunks.par_iter())
        .for_each(|(place, chunk)| place.copy_from_slice(chunk));
    let xs = &out.x[start..];
    out.v.par_extend(xs.par_iter().map(|&x| b.velocity_at(x)));
    out.c.par_extend(repeat_n(b.c, n));
    out.f.par_extend(repeat_n(Mat3::IDENTITY, n));
    out.plastic.par_extend(repeat_n(b.plastic, n));
    out.mass.par_extend(repeat_n(b.mass, n));
    out.vol0.par_extend(repeat_n(b.vol0, n));
    out.material.par_extend(repeat_n(b.material, n));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_uniform_velocity_needs_no_centroid() {
        let any = [Vec3::new(0.3, -2.0, 1e3), Vec3::new(-5.0, 0.0, -0.0)];
        for v0 in [
            Vec3::ZERO,
            Vec3::new(1.0, -2.0, 0.0),
            Vec3::new(-3.5, 0.0, 7.0),
        ] {
            assert!(velocity_is_uniform(v0, Vec3::ZERO));
            for d in any {
                let v = v0 + Vec3::ZERO.cross(d);
                assert_eq!(
                    v.to_array().map(f32::to_bits),
                    v0.to_array().map(f32::to_bits)
                );
                let v = v0 + Vec3::new(-0.0, 0.0, -0.0).cross(d);
                assert_eq!(
                    v.to_array().map(f32::to_bits),
                    v0.to_array().map(f32::to_bits)
                );
            }
        }
        // -0 in the velocity: +0 + -0 is +0, so the centroid's sign may matter.
        assert!(!velocity_is_uniform(Vec3::new(-0.0, 1.0, 0.0), Vec3::ZERO));
        assert!(!velocity_is_uniform(Vec3::ONE, Vec3::new(0.0, 1.0, 0.0)));
    }
}
