//! Boundary conditions on grid velocities: domain walls and colliders.
//!
//! Both use one rule, [`BoundaryRule::apply`], on the velocity relative to the obstacle.

pub mod collider;
pub mod keyframes;
pub mod mesh;
pub mod sdf;
pub mod tool;

pub use collider::Collider;
pub use keyframes::{Keyframe, Keyframes};
pub use rtmpm_physics::boundary::{BoundaryRule, Condition, Walls};
pub use tool::{Tool, ToolShape};
