//! Quadratic B-spline shape functions (MLS-MPM, Hu et al. 2018; Steffen et al. 2008).
//!
//! A particle at grid coordinate `xg = (x - origin) / dx` interacts with the 3x3x3 nodes starting
//! at `base = floor(xg - 0.5)`. With `fx = xg - base` in `[0.5, 1.5)` the 1D weights are
//! `w0 = (1.5 - fx)^2 / 2`, `w1 = 3/4 - (fx - 1)^2`, `w2 = (fx - 0.5)^2 / 2`.

use crate::math::{IVec3, Real, ToReal, Vec3};

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

/// The stencil of one particle: base node, fractional offset and per-axis weights.
#[derive(Clone, Copy, Debug)]
pub struct Stencil {
    /// First node of the 3x3x3 stencil (grid index).
    pub base: IVec3,
    /// `xg - base`, in `[0.5, 1.5)` per axis.
    pub fx: Vec3,
    /// `w[axis][node]`.
    pub w: [[Real; 3]; 3],
}

impl Stencil {
    /// Stencil of a particle at grid coordinate `xg` (position in units of dx from the grid origin).
    #[inline]
    pub fn new(xg: Vec3) -> Stencil {
        let base_f = (xg - 0.5).floor();
        let fx = xg - base_f;
        Stencil {
            base: base_f.as_ivec3(),
            fx,
            w: [weights_1d(fx.x), weights_1d(fx.y), weights_1d(fx.z)],
        }
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
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn each_position(mut f: impl FnMut(Vec3)) {
        // Sweep the cell, including the branch points of the spline.
        for a in 0..=20 {
            for b in [0.0f32, 0.37, 0.5, 0.99] {
                let t = a as f32 / 20.0;
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
                        let node = (s.base + IVec3::new(i as i32, j as i32, k as i32)).as_vec3();
                        x += s.weight(i, j, k) * node;
                    }
                }
            }
            assert!((x - xg).length() < 2e-5, "reproduced {x} for {xg}");
        });
    }

    #[test]
    fn gradient_sums_to_zero_and_matches_finite_difference() {
        for &fx in &[0.5f32, 0.75, 1.0, 1.3, 1.49] {
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

    #[test]
    fn base_is_half_cell_shifted() {
        // A particle in the lower half of cell 4 starts its stencil at node 3, upper half at 4.
        assert_eq!(Stencil::new(Vec3::splat(4.2)).base, IVec3::splat(3));
        assert_eq!(Stencil::new(Vec3::splat(4.7)).base, IVec3::splat(4));
    }
}
