//! Worlds with colliders of their own in a GPU batch ([`super::CudaBatch`]): when the worlds'
//! colliders differ (a swept obstacle's place, size, shape, boundary rule or friction), every
//! world's collider records and poses go to per-world tables on the device once, and the grid
//! update reads a node's world's (`kernels/grid_update.cu`: `node_boundary`, through
//! `c_batch.colliders` and `c_batch.poses`); when they are the same in every world, the scene's
//! shared tables serve them all, as before.
//!
//! Only static colliders may differ: a collider that moves (a velocity, an angular velocity or
//! keyframes) in any world is the same in every world, so the shared clock's time step (the
//! driver's CFL bound reads world 0's colliders) and its reset rule hold for every world, and
//! the tables never change after they are made.

use crate::contract::{ColliderPoses, GpuCollider};
use crate::error::err;
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr};
use rtmpm_geometry::{Collider, Shape};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Every world's collider records and poses on the device.
pub(crate) struct WorldColliders {
    /// `worlds x n_colliders` [`GpuCollider`] records.
    records: CudaSlice<u8>,
    /// One [`ColliderPoses`] per world.
    poses: CudaSlice<u8>,
}

impl WorldColliders {
    /// The worlds' own tables, or `None` when their colliders are the same (the scene's serve
    /// every world); the worlds passed [`refusal`].
    pub fn new(
        worlds: &[Scene],
        stream: &Arc<CudaStream>,
    ) -> Result<Option<WorldColliders>, SimError> {
        if !differ(worlds) {
            return Ok(None);
        }
        let mut records: Vec<GpuCollider> = Vec::new();
        let mut poses: Vec<ColliderPoses> = Vec::with_capacity(worlds.len());
        for s in worlds {
            records.extend(crate::encode::colliders(s)?.0);
            // Static colliders: their pose at any time.
            poses.push(crate::encode::poses(s, 0.0));
        }
        let records = stream
            .clone_htod(bytemuck::cast_slice::<GpuCollider, u8>(&records))
            .map_err(err("upload the worlds' colliders"))?;
        let poses = stream
            .clone_htod(bytemuck::cast_slice::<ColliderPoses, u8>(&poses))
            .map_err(err("upload the worlds' collider poses"))?;
        Ok(Some(WorldColliders { records, poses }))
    }

    /// Bytes of the tables.
    pub fn bytes(&self) -> usize {
        self.records.len() + self.poses.len()
    }

    /// Device addresses for `BatchParams`: (records, poses).
    pub fn pointers(&self, stream: &Arc<CudaStream>) -> (u64, u64) {
        let (a, _) = self.records.device_ptr(stream);
        let (b, _) = self.poses.device_ptr(stream);
        (a, b)
    }
}

/// Whether some world's colliders differ from world 0's.
fn differ(worlds: &[Scene]) -> bool {
    let Some(base) = worlds.first() else {
        return false;
    };
    let key = |s: &Scene| format!("{:?}", s.colliders);
    let want = key(base);
    worlds.iter().skip(1).any(|s| key(s) != want)
}

/// A collider that moves with the clock.
fn moves(c: &Collider) -> bool {
    c.keyframes.is_some()
        || c.velocity != rtmpm_physics::math::Vec3::ZERO
        || c.angular_velocity != rtmpm_physics::math::Vec3::ZERO
}

/// Why the worlds' colliders cannot run in one GPU batch, or `None`: the same in every world,
/// or as many in every world, each a mesh only where world 0's is the same mesh, and the
/// colliders that move the same in every world (only static ones differ).
pub fn refusal(worlds: &[Scene]) -> Option<String> {
    if !differ(worlds) {
        return None;
    }
    let base = &worlds[0];
    let n = base.colliders.len();
    for (w, s) in worlds.iter().enumerate() {
        if s.colliders.len() != n {
            return Some(format!(
                "world {w} has {} colliders and world 0 has {n}: on the GPU every world has the \
                 same number (their static ones may differ in place, shape and boundary rule)",
                s.colliders.len()
            ));
        }
        for (k, (c, c0)) in s.colliders.iter().zip(&base.colliders).enumerate() {
            let same = format!("{c:?}") == format!("{c0:?}");
            if same {
                continue;
            }
            if moves(c) || moves(c0) {
                return Some(format!(
                    "collider {k} moves and differs between world 0 and world {w}: on the GPU \
                     only static colliders may differ between worlds (a moving one is the same \
                     in every world)"
                ));
            }
            let mesh = |s: &Shape| matches!(s, Shape::Mesh(_));
            if (mesh(&c.shape) || mesh(&c0.shape)) && c.shape != c0.shape {
                return Some(format!(
                    "collider {k} of world {w} is a mesh other than world 0's: on the GPU every \
                     world's mesh colliders share world 0's meshes"
                ));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Water and `extra` (colliders).
    fn scene(extra: &str) -> Scene {
        let text = format!(
            "[domain]\nmin = [0,0,0]\nmax = [0.4,0.4,0.4]\ndx = 0.02\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
             bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
             min = [0.06, 0.06, 0.06]\nmax = [0.16, 0.2, 0.34]\n{extra}"
        );
        Scene::from_toml(&text, "test").unwrap_or_else(|e| panic!("{e}"))
    }

    fn wall(x: f32, extra: &str) -> String {
        format!(
            "[[collider]]\nshape = \"box\"\nmin = [{x}, 0.0, 0.1]\nmax = [{}, 0.15, 0.3]\n{extra}",
            x + 0.04
        )
    }

    /// Worlds whose static colliders differ (place, rule) run with tables of their own;
    /// the same colliders need none; different counts and moving colliders that differ are
    /// refused with the reason; a moving collider the same in every world is fine.
    #[test]
    fn static_colliders_may_differ_between_worlds_and_the_rest_is_refused_with_the_reason() {
        let same = [scene(&wall(0.2, "")), scene(&wall(0.2, ""))];
        assert!(!differ(&same) && refusal(&same).is_none());
        let placed = [
            scene(&wall(0.2, "")),
            scene(&wall(0.24, "")),
            scene(&wall(0.22, "condition = \"sticky\"\nfriction = 0.5\n")),
        ];
        assert!(differ(&placed));
        assert_eq!(refusal(&placed), None);
        let o = crate::CudaOptions::default();
        assert_eq!(crate::batch::unsupported(&placed, &o), None);
        let counts = [scene(&wall(0.2, "")), scene("")];
        let why = refusal(&counts).expect("refused");
        assert!(
            why.contains("world 1 has 0 colliders and world 0 has 1"),
            "{why}"
        );
        let moving = [
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
            scene(&wall(0.24, "velocity = [0.1, 0.0, 0.0]\n")),
        ];
        let why = crate::batch::unsupported(&moving, &o).expect("refused");
        assert!(why.contains("collider 0 moves and differs"), "{why}");
        let both = [
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
        ];
        assert_eq!(crate::batch::unsupported(&both, &o), None);
    }
}
