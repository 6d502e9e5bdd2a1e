//! Stage 4: grid to particle (APIC, Jiang et al. 2015; MLS-MPM), deformation gradient update,
//! plastic return mapping, advection and health check.

use super::CpuBackend;
use crate::math::{Mat3, Real, Vec3, outer};
use crate::shape::{Stencil, inv_d};
use crate::sim::{BadParticle, check_particle};
use rayon::prelude::*;

/// Gather velocities back to the particles and advance them. Returns the largest particle speed
/// and the lowest-index bad particle, if any.
pub fn g2p(b: &mut CpuBackend, dt: Real) -> (Real, Option<BadParticle>) {
    let c = &b.consts;
    let (layout, grid, bases) = (&b.layout, &b.grid, &b.bases);
    let inv_d = inv_d(c.dx);
    let p = &mut b.particles;
    let materials = &p.material;
    p.x.par_iter_mut()
        .zip(p.v.par_iter_mut())
        .zip(p.c.par_iter_mut())
        .zip(p.f.par_iter_mut())
        .zip(p.plastic.par_iter_mut())
        .enumerate()
        .map(|(pi, ((((x, v), cp), f), plastic))| {
            let s = Stencil::with_base((*x - c.origin) * c.inv_dx, bases[pi]);
            let nodes = layout.stencil_nodes(layout.gblock_of(pi), s.base);
            // v = sum w v_i and B = sum w v_i (i, j, k)^T, accumulated axis by axis; then
            // C = D^-1 dx (B - v fx^T) = D^-1 sum w v_i (x_i - x_p)^T (APIC, Jiang et al. 2015).
            let mut new_v = Vec3::ZERO;
            let (mut b0, mut b1, mut b2) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
            for i in 0..3 {
                let (mut sum_i, mut b1_i, mut b2_i) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
                for j in 0..3 {
                    let wij = s.w[0][i] * s.w[1][j];
                    let mut sum_j = Vec3::ZERO;
                    let mut b2_j = Vec3::ZERO;
                    for k in 0..3 {
                        let n = grid[nodes[i * 9 + j * 3 + k] as usize];
                        let wv = (wij * s.w[2][k]) * Vec3::new(n[1], n[2], n[3]);
                        sum_j += wv;
                        b2_j += k as Real * wv;
                    }
                    sum_i += sum_j;
                    b1_i += j as Real * sum_j;
                    b2_i += b2_j;
                }
                new_v += sum_i;
                b0 += i as Real * sum_i;
                b1 += b1_i;
                b2 += b2_i;
            }
            let mut new_c = (Mat3::from_cols(b0, b1, b2) - outer(new_v, s.fx)) * c.dx;
            new_c *= inv_d;
            *v = new_v;
            *cp = new_c;
            *x = (*x + dt * new_v).clamp(c.domain_min, c.domain_max);
            // F^{n+1} = (I + dt C) F^n, then the plastic return mapping.
            let model = &c.materials[materials[pi] as usize].model;
            *f = model.project((Mat3::IDENTITY + new_c * dt) * *f, plastic);
            let bad =
                check_particle(*x, new_v, dt, c.dx).map(|reason| BadParticle { index: pi, reason });
            let speed = if new_v.is_finite() {
                new_v.length()
            } else {
                0.0
            };
            (speed, bad)
        })
        .reduce(
            || (0.0, None),
            |(s1, b1), (s2, b2)| {
                let bad = match (b1, b2) {
                    (Some(a), Some(b)) => Some(if a.index <= b.index { a } else { b }),
                    (a, b) => a.or(b),
                };
                (s1.max(s2), bad)
            },
        )
}
