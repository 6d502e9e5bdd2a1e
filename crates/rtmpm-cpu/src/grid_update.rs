//! Stage 3: grid velocities, gravity, domain walls and colliders.

use crate::state::{CpuBackend, GRID_PAD, Node, StepConstants};
use physics::boundary::BoundaryRule;
use physics::grid::codes::{BLOCK_NODES, BLOCK_SIZE};
use physics::math::{IVec3, Real, ToReal, Vec3};
use physics::real;
use physics::transfer::Transfer;
use rayon::prelude::*;
use rtmpm_rigid::{BodyState, Exchange};

/// Grid index of node `cell` of the block at `corner` (inverse of cell_code: `(i1 i0 j1 j0 k1 k0)`).
#[inline]
fn node_index(corner: IVec3, cell: usize) -> IVec3 {
    corner
        + IVec3::new(
            (cell >> 4) as i32,
            (cell >> 2 & 3) as i32,
            (cell & 3) as i32,
        )
}

/// Boundary conditions of node `idx` at time `t`: domain walls, then colliders, then the
/// user's tool (separating, no friction; geometry in f32 as the colliders'). Every grid tests
/// the boundaries at the position of its node's index on the B-spline grid: for CK-MPM's two
/// grids ([`physics::compact_kernel::GRID_SHIFT`], nodes a quarter cell to either side) the
/// boundary of a node of the B-spline grid holds the nodes of both grids on either side of it.
/// A boundary tested at the grids' true node positions fixed only one of them where a collider's
/// surface passes through a node plane: a vibrating bar held by a sticky plane at its end had its
/// end node fixed on one grid and free on the other, and G2P's mean of the two let the end move
/// (period 5.7 % long, amplitude 29 % low at 28 cells; 0.10 % and 0.85 % with both held).
#[inline]
fn boundary(c: &StepConstants, idx: IVec3, mut v: Vec3, t: f32) -> Vec3 {
    let rel = idx - IVec3::splat(GRID_PAD);
    v = c.walls.apply([rel.x, rel.y, rel.z], c.n_cells, v);
    if !c.colliders.is_empty() || c.tool.is_some() {
        let xw = c.origin + idx.to_real() * c.dx;
        for col in &c.colliders {
            if let Some((n, vc)) = col.query(xw, t) {
                v = vc + col.rule.apply(v - vc, n);
            }
        }
        if let Some((n, vt)) = c.tool.and_then(|tool| tool.query(real::vec3_to_f32(xw))) {
            let (n, vt) = (real::vec3(n).normalize_or(Vec3::Y), real::vec3(vt));
            v = vt + BoundaryRule::default().apply(v - vt, n);
        }
    }
    v
}

/// The rigid bodies' boundary rule on node velocity `v` (mass `m`, world position `xw`), and
/// the reaction on each body added to `acc` (see [`rtmpm_rigid`]: the boundary-rule form of
/// the CPIC coupling of Hu et al. 2018). Geometry in f32, as the colliders'.
#[inline]
fn couple(
    bodies: &[BodyState],
    xw: Vec3,
    m: Real,
    mut v: Vec3,
    g_dt: Vec3,
    acc: &mut [Exchange],
) -> Vec3 {
    let x32 = real::vec3_to_f32(xw);
    for (b, e) in bodies.iter().zip(acc.iter_mut()) {
        let Some((n, vb)) = b.query(x32) else {
            continue;
        };
        let (n, vb) = (real::vec3(n), real::vec3(vb));
        let rule = physics::boundary::BoundaryRule {
            condition: b.condition,
            friction: real::real(b.friction),
        };
        let new = vb + rule.apply(v - vb, n);
        // The node's momentum change less the gravity it received this step: the weight of
        // the material mass that the kernel spreads onto nodes inside the body (a shell about
        // half a cell thick) is an artefact of the transfer, not a load on the body; its
        // pressure on the body is in the internal forces. On a slip face the rule holds up
        // only the normal velocity, so this also lifts the body by the weight of the mass
        // on the nodes just inside its side faces: at 5 cells per body height that lift
        // makes up much of what the bottom face falls short of rho g d A (measured:
        // validation/RESULTS.md, "Dithered node membership"; CUDA: grid_update.cu, the same).
        // Summed for every body: only a dynamic one is moved by it (RigidWorld::advance), a
        // kinematic or fixed one reports it as its load (Backend::rigid_loads).
        let dp = (new - v + g_dt) * m;
        let r = x32 - b.center;
        e.add_reaction(
            [r.x as f64, r.y as f64, r.z as f64],
            [dp.x as f64, dp.y as f64, dp.z as f64],
        );
        v = new;
    }
    v
}

/// Turn node momentum into velocity, add gravity, damp (settling) and apply boundary conditions
/// (walls, colliders, rigid bodies). For the classic MPM transfers the internal force (times dt)
/// comes from `grid_aux`, which then keeps the velocity before the update, `v_old = p / m` (no
/// force, no boundary condition), for FLIP. Returns the impulses the grid gave each rigid body,
/// summed block by block in a fixed order (deterministic).
pub fn grid_update(b: &mut CpuBackend, dt: Real, t: f32) -> Vec<Exchange> {
    let c = &b.consts;
    let damp = real::real(c.damping.factor(real::to_f32(dt), t));
    let coords = &b.layout.block_coords;
    let bodies: &[BodyState] = b.rigid.as_ref().map_or(&[], |w| w.states());
    let nb = bodies.len();
    let node_x = |idx: IVec3| c.origin + idx.to_real() * c.dx;
    let partial: Vec<Vec<Exchange>> = if c.solver.transfer == Transfer::Mls {
        update_apic(&mut b.grid, coords, c, bodies, 0.0, (dt, damp, t))
    } else if c.solver.transfer == Transfer::CkMpm {
        // No rigid bodies (refused by `CpuBackend::new`): each grid carries the full mass.
        let [s0, s1] = physics::compact_kernel::GRID_SHIFT;
        update_apic(&mut b.grid, coords, c, &[], s0, (dt, damp, t));
        update_apic(&mut b.grid_dual, coords, c, &[], s1, (dt, damp, t))
    } else {
        b.grid
            .par_chunks_mut(BLOCK_NODES)
            .zip(b.grid_aux.par_chunks_mut(BLOCK_NODES))
            .enumerate()
            .map(|(id, (block, aux))| {
                let mut acc = vec![Exchange::default(); nb];
                let corner = coords[id] * BLOCK_SIZE;
                for (cell, (node, a)) in block.iter_mut().zip(aux.iter_mut()).enumerate() {
                    let m = node[0];
                    if m <= 0.0 {
                        continue;
                    }
                    let idx = node_index(corner, cell);
                    let p = Vec3::new(node[1], node[2], node[3]);
                    let v_old = p / m;
                    // v_new = (p + dt f) / m + dt g, then the boundary conditions.
                    let v = ((p + *a) / m + dt * c.gravity) * damp;
                    let mut v = boundary(c, idx, v, t);
                    if nb > 0 {
                        v = couple(bodies, node_x(idx), m, v, dt * c.gravity, &mut acc);
                    }
                    node[1] = v.x;
                    node[2] = v.y;
                    node[3] = v.z;
                    *a = v_old;
                }
                acc
            })
            .collect()
    };
    partial
        .iter()
        .fold(vec![Exchange::default(); nb], |sum, p| {
            sum.iter().zip(p).map(|(a, b)| a.plus(b)).collect()
        })
}

/// The grid update of the MLS-MPM/APIC transfers on one grid (`shift`: the offset of its nodes
/// from the B-spline grid in cells, CK-MPM's; rigid bodies see the nodes' true positions):
/// momentum to velocity, gravity, damping, boundary conditions, rigid bodies. Returns each
/// block's impulses on the bodies.
fn update_apic(
    grid: &mut [Node],
    coords: &[IVec3],
    c: &StepConstants,
    bodies: &[BodyState],
    shift: Real,
    (dt, damp, t): (Real, Real, f32),
) -> Vec<Vec<Exchange>> {
    let nb = bodies.len();
    grid.par_chunks_mut(BLOCK_NODES)
        .enumerate()
        .map(|(id, block)| {
            let mut acc = vec![Exchange::default(); nb];
            let corner = coords[id] * BLOCK_SIZE;
            for (cell, node) in block.iter_mut().enumerate() {
                let m = node[0];
                if m <= 0.0 {
                    continue;
                }
                let idx = node_index(corner, cell);
                let v = (Vec3::new(node[1], node[2], node[3]) / m + dt * c.gravity) * damp;
                let mut v = boundary(c, idx, v, t);
                if nb > 0 {
                    let xw = c.origin + (idx.to_real() + Vec3::splat(shift)) * c.dx;
                    v = couple(bodies, xw, m, v, dt * c.gravity, &mut acc);
                }
                node[1] = v.x;
                node[2] = v.y;
                node[3] = v.z;
            }
            acc
        })
        .collect()
}

/// MUSL re-map: re-mapped momentum in `grid_aux` to velocity, with the same boundary conditions
/// (gravity is already in the particle velocities).
pub fn grid_update_musl(b: &mut CpuBackend, t: f32) {
    let c = &b.consts;
    let coords = &b.layout.block_coords;
    b.grid
        .par_chunks(BLOCK_NODES)
        .zip(b.grid_aux.par_chunks_mut(BLOCK_NODES))
        .enumerate()
        .for_each(|(id, (block, aux))| {
            let corner = coords[id] * BLOCK_SIZE;
            for (cell, (node, a)) in block.iter().zip(aux.iter_mut()).enumerate() {
                let m = node[0];
                if m <= 0.0 {
                    continue;
                }
                *a = boundary(c, node_index(corner, cell), *a / m, t);
            }
        });
}
