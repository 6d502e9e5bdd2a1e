//! Boundary conditions on grid velocities: domain walls and colliders.
//!
//! Both use one rule, [`BoundaryRule::apply`], on the velocity relative to the obstacle.

pub mod collider;
pub mod keyframes;
pub mod mesh;
pub mod rules;
pub mod sdf;
pub mod tool;

pub use collider::Collider;
pub use keyframes::{Keyframe, Keyframes};
pub use rules::{BoundaryRule, Walls};
pub use tool::{Tool, ToolShape};

/// How the material interacts with an obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Condition {
    /// The relative velocity becomes zero.
    Sticky,
    /// The normal component of the relative velocity is removed (both directions).
    Slip,
    /// Only an approaching normal component is removed; the material may leave the obstacle.
    Separate,
}
