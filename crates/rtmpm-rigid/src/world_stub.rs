//! Without the cargo feature `rigid`: no rigid-body world; scenes with rigid bodies are refused.

use crate::joint::JointSpec;
use crate::spec::RigidBodySpec;
use crate::state::{BodyPose, BodyState, Exchange};

/// Stands for the rapier3d world of the feature `rigid`; never built.
#[derive(Debug)]
pub struct RigidWorld {
    never: std::convert::Infallible,
}

impl RigidWorld {
    /// `None` without bodies; an error naming the feature otherwise.
    pub fn new(
        bodies: &[RigidBodySpec],
        _joints: &[JointSpec],
        _gravity: glam::Vec3,
        _interior: (glam::Vec3, glam::Vec3),
    ) -> Result<Option<RigidWorld>, String> {
        if bodies.is_empty() {
            return Ok(None);
        }
        Err(
            "the scene has [[rigid_body]] tables, but this build has no rigid-body engine \
             (it was built without the cargo feature `rigid`, rapier3d, which the default \
             features include): build with the default features, e.g. `cargo build --release`, \
             or add `--features rigid`"
                .into(),
        )
    }

    /// Change gravity from the next advance on.
    pub fn set_gravity(&mut self, _gravity: glam::Vec3) {
        match self.never {}
    }

    /// Mass and principal moments of inertia of body `i`.
    pub fn mass_properties(&self, _i: usize) -> Option<(f32, glam::Vec3)> {
        match self.never {}
    }

    /// Every body's state.
    pub fn states(&self) -> &[BodyState] {
        match self.never {}
    }

    /// Every body's pose and velocities.
    pub fn poses(&self) -> Vec<BodyPose> {
        match self.never {}
    }

    /// Body `i`'s pose and velocities.
    pub fn pose(&self, _i: usize) -> Option<BodyPose> {
        match self.never {}
    }

    /// Every body's pose and velocities into `out`.
    pub fn poses_into(&self, _out: &mut Vec<BodyPose>) {
        match self.never {}
    }

    /// Put body `i` at `pose`, the others where they are.
    pub fn set_pose(&mut self, _i: usize, _pose: &BodyPose) -> Result<(), String> {
        match self.never {}
    }

    /// Put every body at `poses`.
    pub fn set_poses(&mut self, _poses: &[BodyPose]) -> Result<(), String> {
        match self.never {}
    }

    /// Every advance through the engine's step.
    pub fn with_rapier_steps(self) -> RigidWorld {
        match self.never {}
    }

    /// The world's advance moves its kinematic bodies itself (no dynamic body).
    pub fn kinematic_only(&self) -> bool {
        match self.never {}
    }

    /// Apply the step's exchanges and advance by `dt`.
    pub fn advance(&mut self, _exchange: &[Exchange], _dt: f32) {
        match self.never {}
    }
}
