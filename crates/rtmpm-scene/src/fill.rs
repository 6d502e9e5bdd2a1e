//! The particles of sampled bodies, written once and in parallel straight into the columns of
//! [`Particles`] (no per-particle pushes, no copy of a body's particles into the scene's).

use crate::body::SampledBody;
use rayon::iter::repeat_n;
use rayon::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

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
