//! Stage 4: grid to particle (APIC, Jiang et al. 2015; MLS-MPM), deformation gradient update,
//! plastic return mapping, advection and health check.

use super::CpuBackend;
use crate::math::{Mat3, Vec3, outer};
use crate::shape::{Stencil, inv_d};
use crate::sim::{BadParticle, check_particle};
use rayon::prelude::*;

/// Gather velocities back to the particles and advance them. Returns the largest particle speed
/// and the lowest-index bad particle, if any.
pub fn g2p(b: &mut CpuBackend, dt: f32) -> (f32, Option<BadParticle>) {
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
            let s = Stencil::new((*x - c.origin) * c.inv_dx);
            debug_assert_eq!(s.base, bases[pi]);
            let nodes = layout.stencil_nodes(layout.gblock_of(pi), s.base);
            let mut new_v = Vec3::ZERO;
            let mut new_c = Mat3::ZERO;
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let w = s.weight(i, j, k);
                        let n = grid[nodes[i * 9 + j * 3 + k] as usize];
                        let vi = Vec3::new(n[1], n[2], n[3]);
                        new_v += w * vi;
                        // C = D^-1 sum w v_i (x_i - x_p)^T, dpos in metres.
                        new_c += outer(w * vi, s.dpos(i, j, k) * c.dx);
                    }
                }
            }
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
            || (0.0f32, None),
            |(s1, b1), (s2, b2)| {
                let bad = match (b1, b2) {
                    (Some(a), Some(b)) => Some(if a.index <= b.index { a } else { b }),
                    (a, b) => a.or(b),
                };
                (s1.max(s2), bad)
            },
        )
}
