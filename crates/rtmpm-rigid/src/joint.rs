//! Joints between rigid bodies (`[[joint]]`), simulated by rapier3d's impulse joints: a body
//! hinged to the world or to another body (revolute), held at a point (spherical), welded
//! (fixed) or sliding along an axis (prismatic). The joint's anchor and axis are given in the
//! world at t = 0 and carried by each body from there.

use glam::Vec3;

/// What a joint leaves free.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    /// No relative motion.
    Fixed,
    /// Rotation about the anchor, no translation (a ball joint).
    Spherical,
    /// Rotation about `axis` through the anchor (a hinge); `limits` on the angle (rad).
    Revolute {
        axis: Vec3,
        limits: Option<[f32; 2]>,
    },
    /// Translation along `axis`, no rotation (a slider); `limits` on the distance (m).
    Prismatic {
        axis: Vec3,
        limits: Option<[f32; 2]>,
    },
}

/// A validated `[[joint]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSpec {
    pub kind: JointKind,
    /// The jointed body (index in the scene's rigid bodies).
    pub body: usize,
    /// The other body, or `None` for the world (a fixed point).
    pub to: Option<usize>,
    /// The joint's position in the world at t = 0 (m).
    pub anchor: Vec3,
}

impl JointKind {
    /// The name used in the scene file.
    pub fn name(&self) -> &'static str {
        match self {
            JointKind::Fixed => "fixed",
            JointKind::Spherical => "spherical",
            JointKind::Revolute { .. } => "revolute",
            JointKind::Prismatic { .. } => "prismatic",
        }
    }
}
