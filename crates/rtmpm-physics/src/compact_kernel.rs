//! The compact kernel on two staggered grids ([`crate::transfer::Transfer::CkMpm`]; Liu, Wang &
//! Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025).
//!
//! * **Kernel.** The 1D weight of a node at distance `r` (cells) is
//!   `N(r) = 1 - |r| + sin(2 pi |r|) / (2 pi)` for `|r| < 1`, else 0: C2 (its first and second
//!   derivatives vanish at `|r| = 0` and `|r| = 1`), support one cell on each side, so a particle
//!   touches the 2 nodes of the cell it occupies per axis (2x2x2 in 3D). On one grid the 2
//!   weights of an axis sum to 1 (`N(d) + N(1 - d) = 1`); the 3D weight is the tensor product.
//! * **Two grids.** Grid 0 has its nodes at `(n - 1/4) dx`, grid 1 at `(n + 1/4) dx` (per axis,
//!   from the grid origin): staggered by half a cell. Node `n` of either grid is stored at the
//!   index of node `n` of the MLS-MPM grid, so a particle's two 2x2x2 stencils lie inside its
//!   quadratic B-spline 3x3x3 stencil (base `floor(xg - 1/2)`) and share the block layout. A
//!   particle at distance `d` from the first node of its cell on one grid is at `d +- 1/2` on
//!   the other, so the first moments `sum_i w_ip (x_i - x_p)` of the two grids
//!   (`-sin(2 pi d) / (2 pi)` per axis) cancel and the sum of the second moments never vanishes
//!   (on one grid it does when the particle sits on a node).
//! * **P2G.** Each grid receives the particle's full mass `w_ip m_p` and MLS-MPM momentum
//!   `w_ip (m_p v_p + A_p (x_i - x_p))`, `A_p = m_p C_p - dt V0_p tau_p D_p^-1` (Hu et al. 2018,
//!   eq. 29), with the particle's own `D_p = 1/2 sum_{grids} sum_i w_ip (x_i - x_p)(x_i - x_p)^T`
//!   (not the B-spline's constant `dx^2 / 4`). `tau D_p^-1` (not `D_p^-1 tau`: the two differ
//!   now that `D_p` is a matrix) is the force `-V0 tau grad w_ip` with MLS's
//!   `grad w_ip = w_ip D_p^-1 (x_i - x_p)`, and keeps the torque on the nodes zero. Each grid's
//!   node velocities are then `p_i / m_i`, as on a single grid.
//! * **G2P.** The particle velocity is the mean of the two grids' interpolations,
//!   `v_p = 1/2 sum_{grids} sum_i w_ip v_i`, and APIC's affine matrix the least-squares fit over
//!   both, `C_p = (1/2 sum w_ip v_i (x_i - x_p)^T) D_p^-1`; `F <- (I + dt C_p) F`.
//!
//! The paper's implementation was read for the grid offsets and the per-particle `D_p`; no code
//! was copied.

use crate::math::{Mat3, Real, Vec3, outer};

/// Offset of grid `g`'s nodes from the MLS-MPM grid's, in cells: `-1/4` for grid 0, `+1/4` for
/// grid 1.
pub const GRID_SHIFT: [Real; 2] = [-0.25, 0.25];

/// The compact kernel's 1D weight of a node at distance `r` (cells):
/// `1 - |r| + sin(2 pi |r|) / (2 pi)` for `|r| < 1`, else 0.
#[inline]
pub fn ck_1d(r: Real) -> Real {
    let a = r.abs();
    if a >= 1.0 {
        return 0.0;
    }
    let tau = std::f64::consts::TAU as Real;
    1.0 - a + (tau * a).sin() / tau
}

/// One grid's 2x2x2 stencil of a particle.
#[derive(Clone, Copy, Debug)]
pub struct CkGrid {
    /// Index of the stencil's first node per axis, relative to the particle's MLS-MPM base node
    /// (0 or 1).
    pub offset: [usize; 3],
    /// `w[axis][node]`, node 0 or 1 of the cell.
    pub w: [[Real; 2]; 3],
    /// Distance from the cell's first node to the particle, per axis, in cells (`[0, 1)`).
    pub d: Vec3,
}

impl CkGrid {
    /// Weight of node `(i, j, k)` (each 0 or 1) of this grid's stencil.
    #[inline]
    pub fn weight(&self, i: usize, j: usize, k: usize) -> Real {
        self.w[0][i] * self.w[1][j] * self.w[2][k]
    }

    /// Node position minus particle position, in cells.
    #[inline]
    pub fn dpos(&self, i: usize, j: usize, k: usize) -> Vec3 {
        Vec3::new(i as Real, j as Real, k as Real) - self.d
    }

    /// Index of node `(i, j, k)` in the particle's 3x3x3 MLS-MPM stencil (`i * 9 + j * 3 + k`
    /// of [`crate::grid::BlockLayout::stencil_nodes`]).
    #[inline]
    pub fn stencil_index(&self, i: usize, j: usize, k: usize) -> usize {
        (self.offset[0] + i) * 9 + (self.offset[1] + j) * 3 + self.offset[2] + k
    }

    /// Second moment `sum_i w_ip (x_i - x_p)(x_i - x_p)^T` of this grid, in cells^2.
    fn moment(&self) -> Mat3 {
        let mut m = Mat3::ZERO;
        for i in 0..2 {
            for j in 0..2 {
                for k in 0..2 {
                    let r = self.dpos(i, j, k);
                    m += outer(r, r) * self.weight(i, j, k);
                }
            }
        }
        m
    }
}

/// A particle's stencils on both grids.
#[derive(Clone, Copy, Debug)]
pub struct CkStencil {
    pub grids: [CkGrid; 2],
}

impl CkStencil {
    /// Stencils of a particle at `fx = xg - base` (cells from its MLS-MPM base node,
    /// `[0.5, 1.5)` per axis).
    #[inline]
    pub fn new(fx: Vec3) -> CkStencil {
        CkStencil {
            grids: [0, 1].map(|g| {
                let mut offset = [0; 3];
                let mut w = [[0.0; 2]; 3];
                let mut d = Vec3::ZERO;
                for a in 0..3 {
                    // Distance from grid node 0 (at base + GRID_SHIFT) to the particle; the
                    // particle's cell starts at node 0 or 1 (fx + 1/4 in [0.75, 1.75),
                    // fx - 1/4 in [0.25, 1.25)).
                    let r = fx[a] - GRID_SHIFT[g];
                    let o = usize::from(r >= 1.0);
                    let da = (r - o as Real).clamp(0.0, 1.0);
                    let w0 = ck_1d(da);
                    offset[a] = o;
                    w[a] = [w0, 1.0 - w0];
                    d[a] = da;
                }
                CkGrid { offset, w, d }
            }),
        }
    }

    /// `D_p^-1` in cells^-2: the inverse of the mean of the two grids' second moments (positive
    /// definite: the grids' variances per axis are never both zero).
    #[inline]
    pub fn inv_moment(&self) -> Mat3 {
        ((self.grids[0].moment() + self.grids[1].moment()) * 0.5).inverse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Real, b: Real, tol: Real) -> bool {
        (a - b).abs() <= tol
    }

    /// Sample positions `fx` over the range a particle's offset from its base takes.
    fn samples() -> Vec<Vec3> {
        (0..40)
            .map(|n| {
                let t = n as Real / 40.0;
                Vec3::new(0.5 + t, 1.5 - 0.999 * t, 0.5 + (0.37 * n as Real) % 1.0)
            })
            .collect()
    }

    #[test]
    fn kernel_values_and_smoothness() {
        assert!(close(ck_1d(0.0), 1.0, 1e-6));
        assert!(close(ck_1d(0.5), 0.5, 1e-6));
        assert_eq!(ck_1d(1.0), 0.0);
        assert_eq!(ck_1d(-1.5), 0.0);
        // Slope 0 at 0 and at 1 (C1 there; by construction C2): finite differences.
        let h = 1e-3;
        assert!(((ck_1d(h) - ck_1d(0.0)) / h).abs() < 1e-2);
        assert!(((ck_1d(1.0) - ck_1d(1.0 - h)) / h).abs() < 1e-2);
        // Partition of unity on one grid, per axis.
        for n in 0..20 {
            let d = n as Real / 20.0;
            assert!(close(ck_1d(d) + ck_1d(1.0 - d), 1.0, 1e-6));
        }
    }

    #[test]
    fn each_grid_sums_to_one_and_first_moments_cancel() {
        for fx in samples() {
            let s = CkStencil::new(fx);
            let mut first = Vec3::ZERO;
            for g in &s.grids {
                let mut sum = 0.0;
                for i in 0..2 {
                    for j in 0..2 {
                        for k in 0..2 {
                            sum += g.weight(i, j, k);
                            first += g.weight(i, j, k) * g.dpos(i, j, k);
                            assert!(g.stencil_index(i, j, k) < 27);
                        }
                    }
                }
                assert!(close(sum, 1.0, 1e-5), "{fx}: {sum}");
            }
            assert!(first.abs().max_element() < 1e-5, "{fx}: {first}");
        }
    }

    #[test]
    fn nodes_are_those_of_the_particles_cells() {
        for fx in samples() {
            let s = CkStencil::new(fx);
            for (g, grid) in s.grids.iter().enumerate() {
                for a in 0..3 {
                    // Node 0 of the cell at base + offset + shift, within one cell below.
                    let node0 = grid.offset[a] as Real + GRID_SHIFT[g];
                    let r = fx[a] - node0;
                    assert!(
                        (0.0..1.0 + 1e-6).contains(&r),
                        "{fx} grid {g} axis {a}: {r}"
                    );
                    assert!(close(grid.d[a], r, 1e-6));
                }
            }
        }
    }

    #[test]
    fn moment_is_invertible_everywhere_including_on_nodes() {
        // On a grid-0 node (fx = 0.75): grid 0's second moment is zero, grid 1's is not.
        let mut points = samples();
        points.push(Vec3::splat(0.75));
        points.push(Vec3::splat(1.25));
        for fx in points {
            let s = CkStencil::new(fx);
            let inv = s.inv_moment();
            assert!(inv.is_finite(), "{fx}");
            let m = (s.grids[0].moment() + s.grids[1].moment()) * 0.5;
            let id = m * inv;
            assert!(id.abs_diff_eq(Mat3::IDENTITY, 1e-3), "{fx}: {id}");
        }
    }

    #[test]
    fn affine_field_is_reproduced() {
        // Node velocities of an affine field v(x) = v0 + G x: the G2P fit returns v0 + G x_p and
        // G exactly (the mean of the grids' interpolations is exact for linear fields because
        // the first moments cancel).
        let v0 = Vec3::new(0.3, -1.0, 2.0);
        let g = Mat3::from_cols(
            Vec3::new(0.1, 0.2, -0.3),
            Vec3::new(0.5, -0.4, 0.0),
            Vec3::new(-0.2, 0.7, 0.6),
        );
        for fx in samples() {
            let s = CkStencil::new(fx);
            let (mut v, mut b) = (Vec3::ZERO, Mat3::ZERO);
            for grid in &s.grids {
                for i in 0..2 {
                    for j in 0..2 {
                        for k in 0..2 {
                            let r = grid.dpos(i, j, k);
                            let vi = v0 + g * (fx + r);
                            v += 0.5 * grid.weight(i, j, k) * vi;
                            b += outer(vi, r) * (0.5 * grid.weight(i, j, k));
                        }
                    }
                }
            }
            let c = b * s.inv_moment();
            assert!((v - (v0 + g * fx)).abs().max_element() < 1e-4, "{fx}: {v}");
            assert!(c.abs_diff_eq(g, 1e-3), "{fx}: {c}");
        }
    }
}
