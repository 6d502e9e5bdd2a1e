//! The boundary rule on a velocity relative to an obstacle, and the six domain walls (in the
//! precision of [`crate::real`]).

use super::Condition;
use crate::math::{Real, Vec3};

/// A condition and its Coulomb friction coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryRule {
    pub condition: Condition,
    /// Coulomb friction coefficient (>= 0) on the tangential velocity, for slip and separate.
    pub friction: Real,
}

impl Default for BoundaryRule {
    fn default() -> Self {
        BoundaryRule {
            condition: Condition::Separate,
            friction: 0.0,
        }
    }
}

impl BoundaryRule {
    /// Apply the rule to a velocity `v` relative to the obstacle; `n` is the unit normal pointing
    /// out of the obstacle, into the material.
    #[inline]
    pub fn apply(&self, v: Vec3, n: Vec3) -> Vec3 {
        let vn = v.dot(n);
        match self.condition {
            Condition::Sticky => Vec3::ZERO,
            Condition::Separate if vn >= 0.0 => v,
            Condition::Slip | Condition::Separate => {
                let vt = v - vn * n;
                // Coulomb friction: the tangential speed drops by mu times the removed normal speed.
                let vt_len = vt.length();
                if self.friction > 0.0 && vt_len > 0.0 {
                    let reduced = vt_len - self.friction * vn.abs();
                    if reduced <= 0.0 {
                        Vec3::ZERO
                    } else {
                        vt * (reduced / vt_len)
                    }
                } else {
                    vt
                }
            }
        }
    }
}

/// The six domain walls: nodes within `thickness` cells of a domain face obey that face's rule.
#[derive(Clone, Debug, PartialEq)]
pub struct Walls {
    /// Wall thickness in cells.
    pub thickness: u32,
    /// Rules of the faces -x, +x, -y, +y, -z, +z.
    pub faces: [BoundaryRule; 6],
}

impl Default for Walls {
    fn default() -> Self {
        Walls {
            thickness: 3,
            faces: [BoundaryRule::default(); 6],
        }
    }
}

impl Walls {
    /// Apply the wall rules to the velocity of the node with integer index `node` (counted in
    /// cells from the domain's min corner) in a domain of `n_cells` cells per axis.
    #[inline]
    pub fn apply(&self, node: [i32; 3], n_cells: [u32; 3], mut v: Vec3) -> Vec3 {
        let t = self.thickness as i32;
        for axis in 0..3 {
            let i = node[axis];
            let mut normal = Vec3::ZERO;
            if i < t {
                normal[axis] = 1.0;
                v = self.faces[2 * axis].apply(v, normal);
            } else if i > n_cells[axis] as i32 - t {
                normal[axis] = -1.0;
                v = self.faces[2 * axis + 1].apply(v, normal);
            }
        }
        v
    }
}
