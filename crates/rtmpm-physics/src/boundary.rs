//! Boundary conditions on grid velocities: the rule on a velocity relative to an obstacle
//! (domain walls and colliders both apply it), and the six domain walls, in the precision of
//! [`crate::real`].

use crate::math::{Real, Vec3};

/// How the material interacts with an obstacle (the same type in both precisions).
#[cfg(not(feature = "f64"))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Condition {
    /// The relative velocity becomes zero.
    Sticky,
    /// The normal component of the relative velocity is removed (both directions).
    Slip,
    /// Only an approaching normal component is removed; the material may leave the obstacle.
    Separate,
}
#[cfg(feature = "f64")]
pub use rtmpm_physics::boundary::Condition;

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

/// The six domain walls: nodes at most `thickness` cells from a domain face obey that face's rule.
/// The node plane `thickness` cells in, where bodies may start (the domain minus the walls), is
/// part of the wall: material resting on a wall then stays on that plane instead of sinking a cell
/// into the wall band.
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
            if i <= t {
                normal[axis] = 1.0;
                v = self.faces[2 * axis].apply(v, normal);
            } else if i >= n_cells[axis] as i32 - t {
                normal[axis] = -1.0;
                v = self.faces[2 * axis + 1].apply(v, normal);
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wall_includes_the_plane_where_bodies_start() {
        // 3 cells thick in a 16-cell domain: nodes 0..=3 and 13..=16 are wall nodes.
        let w = Walls::default();
        let down = Vec3::new(-1.0, -1.0, 0.0);
        let n = [16; 3];
        assert_eq!(w.apply([3, 8, 8], n, down), Vec3::new(0.0, -1.0, 0.0));
        assert_eq!(w.apply([4, 8, 8], n, down), down);
        assert_eq!(w.apply([8, 13, 8], n, -down), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(w.apply([8, 12, 8], n, -down), -down);
    }
}
