//! Stage 4: grid to particle (APIC, Jiang et al. 2015; MLS-MPM), deformation gradient update,
//! plastic return mapping, advection and health check.

use crate::state::{CpuBackend, StepConstants};
use physics::compact_kernel::CkStencil;
use physics::math::{Mat3, Real, ToReal, Vec3, outer};
use physics::real;
use physics::shape_function::{Stencil, flip_blend, inv_d};
use rayon::prelude::*;
use rtmpm_sim::{BadParticle, BadReason, MAX_CELLS_PER_STEP};

/// Gather velocities back to the particles and advance them. Returns the largest particle speed
/// and the bad particle of lowest original index, if any (by original index: the same whatever
/// the storage order).
pub fn g2p(b: &mut CpuBackend, dt: Real) -> (Real, Option<BadParticle>) {
    let c = &b.consts;
    let (layout, grid, bases, ids) = (&b.layout, &b.grid, &b.bases, &b.ids);
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
            let motion = Motion {
                l: new_c,
                v_move: new_v,
                v: new_v,
                dt,
            };
            finish_particle(c, materials[pi] as usize, ids[pi], (x, f, plastic), motion)
        })
        .reduce(|| (0.0, None), worst)
}

/// G2P of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method"): the mean
/// of the two staggered grids' interpolations `v_p = 1/2 sum_g sum_i w_ip v_i`, APIC's
/// `C_p = (1/2 sum_g sum_i w_ip v_i (x_i - x_p)^T) D_p^-1` over both grids
/// ([`physics::compact_kernel`]), then `F`, the return mapping and advection as in [`g2p`].
pub fn g2p_ck(b: &mut CpuBackend, dt: Real) -> (Real, Option<BadParticle>) {
    let c = &b.consts;
    let (layout, bases, ids) = (&b.layout, &b.bases, &b.ids);
    let grids = [&b.grid, &b.grid_dual];
    let p = &mut b.particles;
    let materials = &p.material;
    p.x.par_iter_mut()
        .zip(p.v.par_iter_mut())
        .zip(p.c.par_iter_mut())
        .zip(p.f.par_iter_mut())
        .zip(p.plastic.par_iter_mut())
        .enumerate()
        .map(|(pi, ((((x, v), cp), f), plastic))| {
            let base = bases[pi];
            let s = CkStencil::new((*x - c.origin) * c.inv_dx - base.to_real());
            let nodes = layout.stencil_nodes(layout.gblock_of(pi), base);
            // Sums over both grids; B in cells (x_i - x_p = dx dpos).
            let (mut sum_v, mut sum_b) = (Vec3::ZERO, Mat3::ZERO);
            for (stencil, grid) in s.grids.iter().zip(grids) {
                for i in 0..2 {
                    for j in 0..2 {
                        for k in 0..2 {
                            let n = grid[nodes[stencil.stencil_index(i, j, k)] as usize];
                            let wv = stencil.weight(i, j, k) * Vec3::new(n[1], n[2], n[3]);
                            sum_v += wv;
                            sum_b += outer(wv, stencil.dpos(i, j, k));
                        }
                    }
                }
            }
            let new_v = 0.5 * sum_v;
            // C = (1/2 B dx) (D dx^2)^-1 with B, D in cells.
            let new_c = sum_b * s.inv_moment() * (0.5 * c.inv_dx);
            *v = new_v;
            *cp = new_c;
            let motion = Motion {
                l: new_c,
                v_move: new_v,
                v: new_v,
                dt,
            };
            finish_particle(c, materials[pi] as usize, ids[pi], (x, f, plastic), motion)
        })
        .reduce(|| (0.0, None), worst)
}

/// How a particle moves in a step, from the grid: the velocity gradient `L` (the affine `C` of
/// APIC/MLS-MPM), the velocity that advects it and the velocity it keeps (the same except for
/// the PIC/FLIP blend of the classic transfers), and the time step.
struct Motion {
    l: Mat3,
    v_move: Vec3,
    v: Vec3,
    dt: Real,
}

/// The end of G2P, the same for every transfer: `F^{n+1} = (I + dt L) F^n` then the material's
/// plastic return mapping, the health check of the moved particle (before the clamp, which
/// turns a NaN position into the domain's corner), and advection `x += dt v_move` clamped to
/// the domain. Returns the kept velocity's speed (0 when not finite) and the particle's problem.
fn finish_particle(
    c: &StepConstants,
    material: usize,
    id: u32,
    (x, f, plastic): (&mut Vec3, &mut Mat3, &mut Real),
    m: Motion,
) -> (Real, Option<BadParticle>) {
    let model = &c.materials[material].model;
    *f = model.project((Mat3::IDENTITY + m.l * m.dt) * *f, plastic, m.dt);
    let moved = *x + m.dt * m.v_move;
    let bad = check_particle(moved, m.v, f, m.dt, c.dx).map(|reason| BadParticle {
        index: id as usize,
        reason,
        seen: Some((real::vec3_to_f32(moved), real::vec3_to_f32(m.v))),
    });
    *x = moved.clamp(c.domain_min, c.domain_max);
    let speed = if m.v.is_finite() { m.v.length() } else { 0.0 };
    (speed, bad)
}

/// Health check of one particle after a step: a non-finite position (before the clamp to the
/// domain), velocity or deformation gradient, or a move of more than [`MAX_CELLS_PER_STEP`]
/// cells in the step.
#[inline]
fn check_particle(x: Vec3, v: Vec3, f: &Mat3, dt: Real, dx: Real) -> Option<BadReason> {
    if !(x.is_finite() && v.is_finite() && f.is_finite()) {
        Some(BadReason::NonFinite)
    } else if v.length() * dt > real::real(MAX_CELLS_PER_STEP) * dx {
        Some(BadReason::TooFast)
    } else {
        None
    }
}

/// Combine the (max speed, lowest-index bad particle) of two ranges of particles.
fn worst(
    (s1, b1): (Real, Option<BadParticle>),
    (s2, b2): (Real, Option<BadParticle>),
) -> (Real, Option<BadParticle>) {
    let bad = match (b1, b2) {
        (Some(a), Some(b)) => Some(if a.index <= b.index { a } else { b }),
        (a, b) => a.or(b),
    };
    (s1.max(s2), bad)
}

/// G2P of the classic MPM transfers (uGIMP, linear hats). The grid holds `v_i` (after the
/// update) and `grid_aux` `v_i_old` (USL) or the MUSL re-mapped velocities. Positions move with
/// `v_PIC = sum_i w_ip v_i`; the velocity gradient `L_p = sum_i v_i (x) grad w_ip` (of the
/// re-mapped velocities with MUSL) updates `F = (I + dt L) F` and is kept in the particle's `C`.
/// With USL the particle velocity is the PIC/FLIP blend; with MUSL [`g2p_mpm_velocity`] has
/// already set it.
pub fn g2p_mpm(b: &mut CpuBackend, dt: Real, musl: bool) -> (Real, Option<BadParticle>) {
    let c = &b.consts;
    let (layout, grid, aux, bases) = (&b.layout, &b.grid, &b.grid_aux, &b.bases);
    let (transfer, alpha) = (c.solver.transfer, real::real(c.solver.flip));
    let ids = &b.ids;
    let p = &mut b.particles;
    let materials = &p.material;
    p.x.par_iter_mut()
        .zip(p.v.par_iter_mut())
        .zip(p.c.par_iter_mut())
        .zip(p.f.par_iter_mut())
        .zip(p.plastic.par_iter_mut())
        .enumerate()
        .map(|(pi, ((((x, v), cp), f), plastic))| {
            let s = Stencil::for_transfer(transfer, (*x - c.origin) * c.inv_dx, bases[pi]);
            let nodes = layout.stencil_nodes(layout.gblock_of(pi), s.base);
            let (mut v_pic, mut dv, mut l) = (Vec3::ZERO, Vec3::ZERO, Mat3::ZERO);
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let idx = nodes[i * 9 + j * 3 + k] as usize;
                        let n = grid[idx];
                        let vi = Vec3::new(n[1], n[2], n[3]);
                        let w = s.weight(i, j, k);
                        v_pic += w * vi;
                        let grad = s.grad(i, j, k) * c.inv_dx;
                        if musl {
                            l += outer(aux[idx], grad);
                        } else {
                            dv += w * (vi - aux[idx]);
                            l += outer(vi, grad);
                        }
                    }
                }
            }
            if !musl {
                *v = flip_blend(alpha, *v, v_pic, dv);
            }
            *cp = l;
            let motion = Motion {
                l,
                v_move: v_pic,
                v: *v,
                dt,
            };
            finish_particle(c, materials[pi] as usize, ids[pi], (x, f, plastic), motion)
        })
        .reduce(|| (0.0, None), worst)
}

/// MUSL, first pass: the PIC/FLIP blend of the particle velocities only (positions and `F` wait
/// for the re-map, [`g2p_mpm`] with `musl`).
pub fn g2p_mpm_velocity(b: &mut CpuBackend) {
    let c = &b.consts;
    let (layout, grid, aux, bases) = (&b.layout, &b.grid, &b.grid_aux, &b.bases);
    let (transfer, alpha) = (c.solver.transfer, real::real(c.solver.flip));
    let p = &mut b.particles;
    p.v.par_iter_mut()
        .zip(p.x.par_iter())
        .enumerate()
        .for_each(|(pi, (v, x))| {
            let s = Stencil::for_transfer(transfer, (*x - c.origin) * c.inv_dx, bases[pi]);
            let nodes = layout.stencil_nodes(layout.gblock_of(pi), s.base);
            let (mut v_pic, mut dv) = (Vec3::ZERO, Vec3::ZERO);
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let idx = nodes[i * 9 + j * 3 + k] as usize;
                        let n = grid[idx];
                        let vi = Vec3::new(n[1], n[2], n[3]);
                        let w = s.weight(i, j, k);
                        v_pic += w * vi;
                        dv += w * (vi - aux[idx]);
                    }
                }
            }
            *v = flip_blend(alpha, *v, v_pic, dv);
        });
}
