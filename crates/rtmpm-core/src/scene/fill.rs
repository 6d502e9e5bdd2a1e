//! The particles of sampled bodies, written once and in parallel straight into the columns of
//! [`Particles`] (no per-particle pushes, no copy of a body's particles into the scene's).

use super::Body;
use super::walk::Walked;
use crate::Particles;
use crate::material::Material;
use crate::math::{Mat3, Vec3};
use rayon::iter::repeat_n;
use rayon::prelude::*;

/// One body's sampling: the positions of a shape, or the particles of a points file.
pub(crate) enum Sampled {
    Walked { walked: Walked, vol0: f32 },
    Points(Particles),
}

impl Sampled {
    /// Particles of the body.
    pub(crate) fn len(&self) -> usize {
        match self {
            Sampled::Walked { walked, .. } => walked.count as usize,
            Sampled::Points(p) => p.len(),
        }
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
fn velocity_is_uniform(v0: Vec3, w: Vec3) -> bool {
    w == Vec3::ZERO
        && !v0
            .to_array()
            .iter()
            .any(|c| *c == 0.0 && c.is_sign_negative())
}

/// Append the particles of `body` (material `material`) to `out`: positions in walk order,
/// velocity `v0 + w x (x - c)` with `c` the centroid of the body's particles (summed in order,
/// in f32, as the one-thread sampler always did), C the spin matrix of `w`, F the identity.
pub(crate) fn append(out: &mut Particles, body: &Body, material: &Material, sampled: Sampled) {
    let (walked, vol0) = match sampled {
        Sampled::Walked { walked, vol0 } => (walked, vol0),
        Sampled::Points(p) => {
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
    let n = walked.count as usize;
    let start = out.x.len();
    // The positions, chunk by chunk into their places.
    out.x.par_extend(repeat_n(Vec3::ZERO, n));
    let mut rest = &mut out.x[start..];
    let mut places = Vec::with_capacity(walked.chunks.len());
    for c in &walked.chunks {
        let (place, tail) = rest.split_at_mut(c.len());
        places.push(place);
        rest = tail;
    }
    places
        .into_par_iter()
        .zip(walked.chunks.par_iter())
        .for_each(|(place, chunk)| place.copy_from_slice(chunk));
    drop(walked);
    let xs = &out.x[start..];
    let (v0, w) = (body.velocity, body.angular_velocity);
    let centre = if velocity_is_uniform(v0, w) {
        Vec3::ZERO
    } else {
        xs.iter().fold(Vec3::ZERO, |a, b| a + *b) / n.max(1) as f32
    };
    out.v
        .par_extend(xs.par_iter().map(|&x| v0 + w.cross(x - centre)));
    out.c
        .par_extend(repeat_n(super::sampling::spin_matrix(w), n));
    out.f.par_extend(repeat_n(Mat3::IDENTITY, n));
    out.plastic
        .par_extend(repeat_n(material.model.initial_plastic(), n));
    out.mass.par_extend(repeat_n(material.density * vol0, n));
    out.vol0.par_extend(repeat_n(vol0, n));
    out.material.par_extend(repeat_n(body.material, n));
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
