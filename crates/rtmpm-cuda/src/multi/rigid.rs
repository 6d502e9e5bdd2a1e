//! Rigid bodies (`[[rigid_body]]`) on several GPUs: one rapier world on the host
//! ([`SharedBodies`]), the coupling on every GPU. Each GPU's grid update couples the bodies to
//! the nodes of its own pblocks and sums their reactions (`kernels/grid_update.cu`:
//! `couple_bodies`); a pblock that k GPUs hold has the same summed nodes on each of them after
//! the shared-block reduction, so each adds 1/k of its reaction and the sum over the GPUs
//! ([`sum_over_ranks`]) counts every node once. The host advances the world once with that sum,
//! and every GPU gets the same poses before its next step. With
//! [`crate::options::CudaOptions::rigid_overlap`] the world advances by a step's sums while the
//! GPUs run the next one, as on one GPU (`crate::step::rigid`).

use crate::options::CudaOptions;
use rtmpm_rigid::{BodyPose, BodyState, Exchange, RigidWorld};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;

/// The bodies of a multi-GPU run: their world and the step whose sums it has not taken yet.
pub(crate) struct SharedBodies {
    world: RigidWorld,
    /// A step queued on every GPU whose sums the bodies have not taken yet: its host copy and
    /// its dt.
    pending: Option<(usize, f32)>,
    overlap: bool,
}

impl SharedBodies {
    /// The bodies of `scene` (`None` without any; the same refusals as on one GPU).
    pub(crate) fn new(scene: &Scene, o: &CudaOptions) -> Result<Option<SharedBodies>, SimError> {
        Ok(crate::step::rigid::world(scene)?.map(|world| SharedBodies {
            world,
            pending: None,
            overlap: o.rigid_overlap,
        }))
    }

    /// The states every GPU couples in the coming step.
    pub(crate) fn states(&self) -> &[BodyState] {
        self.world.states()
    }

    /// Every body's pose and velocities.
    pub(crate) fn poses(&self) -> Vec<BodyPose> {
        self.world.poses()
    }

    /// Put the bodies at `poses`; sums not yet taken are dropped.
    pub(crate) fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError> {
        self.pending = None;
        self.world.set_poses(poses).map_err(SimError::Backend)
    }

    /// Gravity from the next advance on.
    pub(crate) fn set_gravity(&mut self, g: rtmpm_physics::math::Vec3) {
        self.world.set_gravity(g);
    }

    /// A step of `dt` was queued on every GPU, its sums going to host copy `k`: the step whose
    /// sums the bodies take now (this one without overlap, the one before with it), if any.
    pub(crate) fn queued(&mut self, k: usize, dt: f32) -> Option<(usize, f32)> {
        if self.overlap {
            self.pending.replace((k, dt))
        } else {
            Some((k, dt))
        }
    }

    /// The step whose sums are still to be taken (flushing), if any.
    pub(crate) fn take_pending(&mut self) -> Option<(usize, f32)> {
        self.pending.take()
    }

    /// Advance the world by `dt` with every GPU's sums of one step (in rank order).
    pub(crate) fn advance(&mut self, per_rank: &[Vec<Exchange>], dt: f32) {
        let total = sum_over_ranks(per_rank, self.world.states().len());
        self.world.advance(&total, dt);
    }
}

/// Each body's impulse sums added over the GPUs, in rank order (the same sum for the same
/// sums).
pub(crate) fn sum_over_ranks(per_rank: &[Vec<Exchange>], bodies: usize) -> Vec<Exchange> {
    let mut out = vec![Exchange::default(); bodies];
    for rank in per_rank {
        for (o, e) in out.iter_mut().zip(rank) {
            *o = o.plus(e);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ranks_sums_add_up_body_by_body() {
        let e = |i: f64, t: f64| Exchange {
            impulse: [i, 0.0, -i],
            torque: [0.0, t, 0.0],
        };
        // Two bodies, three GPUs; the third GPU holds none of body 1's nodes.
        let per_rank = vec![
            vec![e(1.0, 0.5), e(2.0, 0.0)],
            vec![e(0.25, 0.5), e(-1.0, 1.0)],
            vec![e(0.0, 0.0), e(0.0, 0.0)],
        ];
        let s = sum_over_ranks(&per_rank, 2);
        assert_eq!(s[0], e(1.25, 1.0));
        assert_eq!(s[1], e(1.0, 1.0));
        // A shared node's reaction r split 1/k on each of its k GPUs adds up to r once.
        let r = 0.3_f64;
        for k in 2..=8 {
            let per_rank: Vec<Vec<Exchange>> = (0..k).map(|_| vec![e(r / k as f64, 0.0)]).collect();
            let s = sum_over_ranks(&per_rank, 1);
            assert!((s[0].impulse[0] - r).abs() < 1e-15, "{k}: {:?}", s[0]);
        }
    }
}
