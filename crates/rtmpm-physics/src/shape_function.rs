//! Shape functions of the transfers ([`Transfer`]): quadratic B-splines (MLS-MPM, Hu et al.
//! 2018; Steffen et al. 2008), uGIMP (Bardenhagen & Kober 2004) and linear hats (Sulsky et al.
//! 1994). One source of truth: `kernels/shape.cuh` mirrors this file formula by formula.
//!
//! A particle at grid coordinate `xg = (x - origin) / dx` interacts with the 3x3x3 nodes starting
//! at `base = floor(xg - 0.5)`. With `fx = xg - base` in `[0.5, 1.5)` the quadratic 1D weights are
//! `w0 = (1.5 - fx)^2 / 2`, `w1 = 3/4 - (fx - 1)^2`, `w2 = (fx - 0.5)^2 / 2`. The uGIMP function
//! (half-size dx/4, support 1.25 dx) and the linear hat (support dx) of node `n` at distance
//! `r = fx - n` vanish outside the same three nodes, so every transfer shares the stencil, the
//! block layout and the free zone. All weights are tensor products of 1D weights.

use crate::math::{IVec3, Real, ToReal, Vec3};
use crate::transfer::Transfer;

/// Weights of the three nodes of one axis.
#[inline]
pub fn weights_1d(fx: Real) -> [Real; 3] {
    [
        0.5 * (1.5 - fx) * (1.5 - fx),
        0.75 - (fx - 1.0) * (fx - 1.0),
        0.5 * (fx - 0.5) * (fx - 0.5),
    ]
}

/// Derivatives d w / d fx of the three weights of one axis.
#[inline]
pub fn dweights_1d(fx: Real) -> [Real; 3] {
    [fx - 1.5, -2.0 * (fx - 1.0), fx - 0.5]
}

/// uGIMP particle half-size in cells (dx/4: the particle domain of 2 particles per cell and axis).
pub const GIMP_HALF_SIZE: Real = 0.25;

/// uGIMP 1D weight and its derivative d S / d r of a node at signed distance `r = x_p - x_i`
/// (in cells), half-size `l` = [`GIMP_HALF_SIZE`], spacing 1 (Bardenhagen & Kober 2004, eq. 31):
/// `1 - (r^2 + l^2) / 2l` for `|r| < l`, `1 - |r|` for `l <= |r| < 1 - l`,
/// `(1 + l - |r|)^2 / 4l` for `1 - l <= |r| < 1 + l`, else 0.
#[inline]
pub fn gimp_1d(r: Real) -> (Real, Real) {
    let l = GIMP_HALF_SIZE;
    let a = r.abs();
    let s = if r < 0.0 { -1.0 } else { 1.0 };
    if a < l {
        (1.0 - (r * r + l * l) / (2.0 * l), -r / l)
    } else if a < 1.0 - l {
        (1.0 - a, -s)
    } else if a < 1.0 + l {
        let d = 1.0 + l - a;
        (d * d / (4.0 * l), -s * d / (2.0 * l))
    } else {
        (0.0, 0.0)
    }
}

/// Linear hat 1D weight `max(0, 1 - |r|)` and its derivative d w / d r (Sulsky et al. 1994). At
/// the kinks the derivative is the one to the right (`r = -1`: +1, `r = 0`: -1, `r = 1`: 0), so
/// that the three nodes' derivatives still sum to zero on cell faces.
#[inline]
pub fn linear_1d(r: Real) -> (Real, Real) {
    if !(-1.0..1.0).contains(&r) {
        (0.0, 0.0)
    } else if r >= 0.0 {
        (1.0 - r, -1.0)
    } else {
        (1.0 + r, 1.0)
    }
}

/// Weights and derivatives d w / d fx of the three nodes of one axis for a transfer.
#[inline]
pub fn shape_1d(transfer: Transfer, fx: Real) -> ([Real; 3], [Real; 3]) {
    match transfer {
        // CK-MPM's stencils are in `compact_kernel`; it shares the B-spline's base and layout.
        Transfer::Mls | Transfer::CkMpm => (weights_1d(fx), dweights_1d(fx)),
        Transfer::Gimp => {
            let (a, b, c) = (gimp_1d(fx), gimp_1d(fx - 1.0), gimp_1d(fx - 2.0));
            ([a.0, b.0, c.0], [a.1, b.1, c.1])
        }
        Transfer::MpmLinear => {
            let (a, b, c) = (linear_1d(fx), linear_1d(fx - 1.0), linear_1d(fx - 2.0));
            ([a.0, b.0, c.0], [a.1, b.1, c.1])
        }
    }
}

/// The stencil of one particle: base node, fractional offset and per-axis weights.
#[derive(Clone, Copy, Debug)]
pub struct Stencil {
    /// First node of the 3x3x3 stencil (grid index).
    pub base: IVec3,
    /// `xg - base`, in `[0.5, 1.5)` per axis.
    pub fx: Vec3,
    /// `w[axis][node]`.
    pub w: [[Real; 3]; 3],
    /// `dw[axis][node]`: d w / d fx (per cell); only filled by [`Stencil::for_transfer`].
    pub dw: [[Real; 3]; 3],
}

impl Stencil {
    /// Stencil of a particle at grid coordinate `xg` (position in units of dx from the grid origin).
    #[inline]
    pub fn new(xg: Vec3) -> Stencil {
        let base = Stencil::base_of(xg);
        let fx = xg - base.to_real();
        Stencil {
            base,
            fx,
            w: [weights_1d(fx.x), weights_1d(fx.y), weights_1d(fx.z)],
            dw: [[0.0; 3]; 3],
        }
    }

    /// First node of the stencil of a particle at grid coordinate `xg`: `floor(xg - 0.5)`, with
    /// the floor done by a cast and a compare (no libm call), the same value as the float floor
    /// (also for NaN: 0, and saturated past the i32 range).
    #[inline]
    pub fn base_of(xg: Vec3) -> IVec3 {
        #[inline]
        fn floor(v: Real) -> i32 {
            let t = v as i32;
            if (t as Real) > v {
                t.saturating_sub(1)
            } else {
                t
            }
        }
        IVec3::new(floor(xg.x - 0.5), floor(xg.y - 0.5), floor(xg.z - 0.5))
    }

    /// Stencil of a particle at grid coordinate `xg` whose base node is already known
    /// (`base == floor(xg - 0.5)`), avoiding the floor.
    #[inline]
    pub fn with_base(xg: Vec3, base: IVec3) -> Stencil {
        let fx = xg - base.to_real();
        Stencil {
            base,
            fx,
            w: [weights_1d(fx.x), weights_1d(fx.y), weights_1d(fx.z)],
            dw: [[0.0; 3]; 3],
        }
    }

    /// Weights and gradients of the active transfer for a particle at grid coordinate `xg`
    /// whose base node is known: the per-(particle, node) interface every P2G/G2P variant uses.
    #[inline]
    pub fn for_transfer(transfer: Transfer, xg: Vec3, base: IVec3) -> Stencil {
        let fx = xg - base.to_real();
        let (wx, dx) = shape_1d(transfer, fx.x);
        let (wy, dy) = shape_1d(transfer, fx.y);
        let (wz, dz) = shape_1d(transfer, fx.z);
        Stencil {
            base,
            fx,
            w: [wx, wy, wz],
            dw: [dx, dy, dz],
        }
    }

    /// Gradient of the weight of node `(i, j, k)` with respect to the particle position, per
    /// cell (multiply by 1/dx for world units). Needs [`Stencil::for_transfer`].
    #[inline]
    pub fn grad(&self, i: usize, j: usize, k: usize) -> Vec3 {
        let w = &self.w;
        let d = &self.dw;
        Vec3::new(
            d[0][i] * w[1][j] * w[2][k],
            w[0][i] * d[1][j] * w[2][k],
            w[0][i] * w[1][j] * d[2][k],
        )
    }

    /// Weight of node `(i, j, k)` of the stencil.
    #[inline]
    pub fn weight(&self, i: usize, j: usize, k: usize) -> Real {
        self.w[0][i] * self.w[1][j] * self.w[2][k]
    }

    /// Node position minus particle position, in units of dx: `(i, j, k) - fx`.
    #[inline]
    pub fn dpos(&self, i: usize, j: usize, k: usize) -> Vec3 {
        Vec3::new(i as Real, j as Real, k as Real) - self.fx
    }
}

/// `D^-1` of APIC/MLS-MPM for the quadratic B-spline: `4 / dx^2`.
#[inline]
pub fn inv_d(dx: Real) -> Real {
    4.0 / (dx * dx)
}

/// PIC/FLIP blend of a particle velocity: `(1 - alpha) v_PIC + alpha (v_p + dv)`, with
/// `v_PIC = sum_i w_ip v_i` and the FLIP increment `dv = sum_i w_ip (v_i - v_i_old)` (Brackbill &
/// Ruppel 1986; Stomakhin et al. 2013, eq. 11). Mirrored by `flip_blend` in `kernels/shape.cuh`.
#[inline]
pub fn flip_blend(alpha: Real, v_p: Vec3, v_pic: Vec3, dv: Vec3) -> Vec3 {
    v_pic * (1.0 - alpha) + (v_p + dv) * alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    fn each_position(mut f: impl FnMut(Vec3)) {
        // Sweep the cell, including the branch points of the spline.
        for a in 0..=20 {
            for b in [0.0 as Real, 0.37, 0.5, 0.99] {
                let t = a as Real / 20.0;
                f(Vec3::new(3.0 + t, 5.0 + b, 7.5 + 0.5 * t));
            }
        }
    }

    #[test]
    fn partition_of_unity() {
        each_position(|xg| {
            let s = Stencil::new(xg);
            let mut sum = 0.0;
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        sum += s.weight(i, j, k);
                    }
                }
            }
            assert!((sum - 1.0).abs() < 1e-6, "sum of weights {sum} at {xg}");
        });
    }

    #[test]
    fn linear_reproduction() {
        // sum_i w_i x_i = x_p: the node positions weighted reproduce the particle position.
        each_position(|xg| {
            let s = Stencil::new(xg);
            let mut x = Vec3::ZERO;
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let node = (s.base + IVec3::new(i as i32, j as i32, k as i32)).to_real();
                        x += s.weight(i, j, k) * node;
                    }
                }
            }
            assert!((x - xg).length() < 2e-5, "reproduced {x} for {xg}");
        });
    }

    #[test]
    fn gradient_sums_to_zero_and_matches_finite_difference() {
        for &fx in &[0.5 as Real, 0.75, 1.0, 1.3, 1.49] {
            let d = dweights_1d(fx);
            assert!((d[0] + d[1] + d[2]).abs() < 1e-6);
            let h = 1e-3;
            let (wp, wm) = (weights_1d(fx + h), weights_1d(fx - h));
            for n in 0..3 {
                let fd = (wp[n] - wm[n]) / (2.0 * h);
                assert!(
                    (fd - d[n]).abs() < 1e-3,
                    "node {n} at {fx}: {fd} vs {}",
                    d[n]
                );
            }
        }
    }

    /// Deterministic positions spread over many cells, including the branch points of every
    /// shape function (cell centres, faces, GIMP's 0.25/0.75 breaks).
    fn random_positions() -> Vec<Vec3> {
        let mut v = Vec::new();
        let mut x = 0x2545_f491u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as Real / u32::MAX as Real
        };
        for _ in 0..400 {
            v.push(Vec3::new(
                5.0 + 3.0 * next(),
                7.0 + 3.0 * next(),
                2.0 + 3.0 * next(),
            ));
        }
        for t in [0.0 as Real, 0.25, 0.5, 0.75, 0.999] {
            v.push(Vec3::new(4.0 + t, 6.0 + t, 9.5 - t));
        }
        v
    }

    /// Sums over the stencil of `w`, `grad w`, `w (x_i - x_p)` and `(x_i - x_p) (x) grad w`.
    fn moments(t: Transfer, xg: Vec3) -> (Real, Vec3, Vec3, crate::math::Mat3) {
        let base = Stencil::new(xg).base;
        let s = Stencil::for_transfer(t, xg, base);
        let (mut w, mut g, mut m1) = (0.0, Vec3::ZERO, Vec3::ZERO);
        let mut m = crate::math::Mat3::ZERO;
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    let d = s.dpos(i, j, k);
                    w += s.weight(i, j, k);
                    g += s.grad(i, j, k);
                    m1 += s.weight(i, j, k) * d;
                    m += crate::math::outer(d, s.grad(i, j, k));
                }
            }
        }
        (w, g, m1, m)
    }

    #[test]
    fn every_transfer_is_a_partition_of_unity_with_consistent_gradients() {
        for t in [Transfer::Mls, Transfer::Gimp, Transfer::MpmLinear] {
            for xg in random_positions() {
                let (w, g, m1, m) = moments(t, xg);
                assert!((w - 1.0).abs() < 1e-5, "{t:?} at {xg}: sum w = {w}");
                assert!(g.length() < 1e-5, "{t:?} at {xg}: sum grad w = {g}");
                assert!(
                    m1.length() < 1e-5,
                    "{t:?} at {xg}: sum w (x_i - x_p) = {m1}"
                );
                let e = m - crate::math::Mat3::IDENTITY;
                assert!(
                    crate::math::norm2(e).sqrt() < 1e-5,
                    "{t:?} at {xg}: sum (x_i - x_p) grad w^T = {m:?}"
                );
            }
        }
    }

    #[test]
    fn gimp_and_linear_derivatives_match_finite_differences_and_vanish_outside() {
        for f in [gimp_1d as fn(Real) -> (Real, Real), linear_1d] {
            for i in 0..=300 {
                let r = -1.6 + i as Real * 0.0107;
                let h = 1e-3;
                let fd = (f(r + h).0 - f(r - h).0) / (2.0 * h);
                // Away from the kinks (GIMP is C1, the hat is not differentiable at 0 and 1).
                let near_kink = [0.0 as Real, 1.0, -1.0]
                    .iter()
                    .any(|k| (r - k).abs() < 2.0 * h);
                if !near_kink {
                    assert!((fd - f(r).1).abs() < 2e-2, "r = {r}: {fd} vs {}", f(r).1);
                }
                assert!(f(r).0 >= 0.0);
            }
        }
        // GIMP's support is 1 + 1/4 cells, the hat's 1 cell: node 3 of a stencil is never reached.
        assert_eq!(gimp_1d(1.25), (0.0, 0.0));
        assert!(gimp_1d(1.2).0 > 0.0);
        assert_eq!(linear_1d(1.0), (0.0, 0.0));
        // GIMP is continuous at its breaks.
        for b in [0.25 as Real, 0.75, 1.25] {
            let (lo, hi) = (gimp_1d(b - 1e-4).0, gimp_1d(b + 1e-4).0);
            assert!((lo - hi).abs() < 1e-3, "jump at {b}: {lo} {hi}");
        }
    }

    #[test]
    fn base_is_half_cell_shifted() {
        // A particle in the lower half of cell 4 starts its stencil at node 3, upper half at 4.
        assert_eq!(Stencil::new(Vec3::splat(4.2)).base, IVec3::splat(3));
        assert_eq!(Stencil::new(Vec3::splat(4.7)).base, IVec3::splat(4));
    }
}
