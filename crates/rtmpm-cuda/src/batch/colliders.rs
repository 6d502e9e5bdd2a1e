//! Worlds with colliders of their own in a GPU batch ([`super::CudaBatch`]): when the worlds'
//! colliders differ (a swept obstacle's place, size, shape, boundary rule or friction, or a
//! pusher's speed or keyframes), every world's collider records go to a per-world table on the
//! device once, and their poses at the step's time to another, `worlds x n_colliders` rows
//! ([`GpuColliderPose`]); the grid update reads a node's world's rows (`kernels/grid_update.cu`:
//! `node_boundary`, through `c_batch.colliders` and `c_batch.poses`). When they are the same in
//! every world, the scene's shared tables serve them all, as before.
//!
//! Static colliders' poses go up once. While a collider of some world moves (a velocity, an
//! angular velocity or keyframes), every world's poses are evaluated on the host at each step's
//! time by the CPU backend's formula (`crate::encode::collider_pose`: `Collider::rotation`,
//! `pivot_at`, `motion_at`) and the table goes up before the step when it changed. The shared
//! clock's time step counts every world's colliders (the scene [`super::CudaBatch::scene`] gives
//! the driver).

use crate::contract::{GpuCollider, GpuColliderPose};
use crate::error::err;
use crate::waits::{HostWaits, WaitReason};
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr};
use rayon::prelude::*;
use rtmpm_geometry::{Collider, Shape};
use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::collections::HashSet;
use std::sync::Arc;

/// Every world's collider records and poses on the device.
pub(crate) struct WorldColliders {
    /// `worlds x n_colliders` [`GpuCollider`] records.
    records: CudaSlice<u8>,
    /// `worlds x n_colliders` [`GpuColliderPose`] rows.
    poses: CudaSlice<u8>,
    /// Every world's colliders, when one of them moves (the poses follow the clock); empty:
    /// every collider is static and the poses went up once.
    moving: Vec<Vec<Collider>>,
    /// The rows last uploaded.
    last: Vec<GpuColliderPose>,
    /// The page-locked memory the moving poses' uploads go through (a copy from pageable memory
    /// may wait for the steps queued ahead of it).
    staging: crate::staging::StagingRing,
}

/// Page-locked buffers the moving poses' uploads go through at most (1 with
/// `RTMPM_BATCH_WAITS=old`, which copies them from pageable memory as before).
const UPLOAD_BUFFERS: usize = 64;

impl WorldColliders {
    /// The worlds' own tables (their poses at time 0), or `None` when their colliders are the
    /// same (the scene's serve every world); the worlds passed [`refusal`].
    pub fn new(
        worlds: &[Scene],
        stream: &Arc<CudaStream>,
    ) -> Result<Option<WorldColliders>, SimError> {
        if !differ(worlds) {
            return Ok(None);
        }
        let mut records: Vec<GpuCollider> = Vec::new();
        for s in worlds {
            records.extend(crate::encode::colliders(s)?.0);
        }
        let all: Vec<Vec<Collider>> = worlds.iter().map(|s| s.colliders.clone()).collect();
        let last = pose_rows(&all, 0.0);
        let records = stream
            .clone_htod(bytemuck::cast_slice::<GpuCollider, u8>(&records))
            .map_err(err("upload the worlds' colliders"))?;
        // At least one byte: a table of no rows is still an address.
        let mut poses = stream
            .alloc_zeros::<u8>((last.len() * size_of::<GpuColliderPose>()).max(1))
            .map_err(err("allocate the worlds' collider poses"))?;
        upload(stream, &last, &mut poses)?;
        let moving = if all.iter().flatten().any(moves) {
            all
        } else {
            Vec::new()
        };
        Ok(Some(WorldColliders {
            records,
            poses,
            moving,
            last,
            staging: crate::staging::StagingRing::new(UPLOAD_BUFFERS, 1),
        }))
    }

    /// Before the step from time `t`: every world's poses at `t`, uploaded when they changed
    /// (only while a collider moves), through page-locked memory; `waits`: the backend's count
    /// of the host's waits.
    pub fn update(
        &mut self,
        stream: &Arc<CudaStream>,
        t: f32,
        waits: &HostWaits,
    ) -> Result<(), SimError> {
        if self.moving.is_empty() {
            return Ok(());
        }
        let rows = pose_rows(&self.moving, t);
        if rows != self.last {
            let bytes: &[u8] = bytemuck::cast_slice(&rows);
            let old = crate::waits::old_waits();
            if old && !bytes.is_empty() {
                waits.wait(WaitReason::Pageable, || ());
                upload(stream, &rows, &mut self.poses)?;
            } else if !bytes.is_empty() {
                self.staging
                    .copy_to_device(stream, bytes, &mut self.poses, waits)?;
            }
            self.last = rows;
        }
        Ok(())
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

/// Copy the rows `rows` to the poses table `to` (in order on `stream`, behind the last step).
fn upload(
    stream: &Arc<CudaStream>,
    rows: &[GpuColliderPose],
    to: &mut CudaSlice<u8>,
) -> Result<(), SimError> {
    let bytes: &[u8] = bytemuck::cast_slice(rows);
    if bytes.is_empty() {
        return Ok(());
    }
    stream
        .memcpy_htod(bytes, &mut to.slice_mut(..bytes.len()))
        .map_err(err("upload the worlds' collider poses"))
}

/// Every world's collider poses at time `t`, world by world (row `w * n + k`: collider `k` of
/// world `w`; every world has `n`), by the CPU backend's formula; the worlds on every core (in
/// order).
pub(crate) fn pose_rows(worlds: &[Vec<Collider>], t: f32) -> Vec<GpuColliderPose> {
    worlds
        .par_iter()
        .with_min_len(256)
        .flat_map_iter(|w| w.iter().map(|c| crate::encode::collider_pose(c, t)))
        .collect()
}

/// Whether some world's colliders differ from world 0's.
fn differ(worlds: &[Scene]) -> bool {
    let Some(base) = worlds.first() else {
        return false;
    };
    worlds.iter().skip(1).any(|s| {
        s.colliders.len() != base.colliders.len()
            || s.colliders
                .iter()
                .zip(&base.colliders)
                .any(|(a, b)| !same(a, b))
    })
}

/// Whether two colliders are the same: motion and rule first, the shape last (a mesh's
/// distance grid is compared only when everything else is the same).
fn same(a: &Collider, b: &Collider) -> bool {
    a.velocity == b.velocity
        && a.angular_velocity == b.angular_velocity
        && a.pivot == b.pivot
        && a.keyframes == b.keyframes
        && a.rule == b.rule
        && a.shape == b.shape
}

/// A collider that moves with the clock.
pub(crate) fn moves(c: &Collider) -> bool {
    c.keyframes.is_some() || c.velocity != Vec3::ZERO || c.angular_velocity != Vec3::ZERO
}

/// The colliders that bound the shared clock of the worlds (so the driver's CFL step counts the
/// fastest collider of any world, a step ends at any world's keyframe, and a reset of some
/// worlds is refused when a collider of any world moves with the clock): collider `k` is world
/// 0's, or when that one is static the first world's collider `k` that moves (so a message
/// naming collider `k` names it in every world's file), then every other world's moving
/// colliders not already among them (each once).
pub(crate) fn clock_colliders(worlds: &[Scene]) -> Vec<Collider> {
    let Some(base) = worlds.first() else {
        return Vec::new();
    };
    let mut out: Vec<Collider> = base
        .colliders
        .iter()
        .enumerate()
        .map(|(k, c0)| {
            let moving = worlds
                .iter()
                .filter_map(|s| s.colliders.get(k))
                .find(|c| moves(c));
            moving.unwrap_or(c0).clone()
        })
        .collect();
    // What the clock reads of a collider (its motion, and its rest bounds for a spin's reach):
    // colliders alike in it count once, in time linear in the worlds.
    let clock_key = |c: &Collider| {
        let f = |v: Vec3| v.to_array().map(f32::to_bits);
        let bounds = c.shape.finite_bounds().map(|(lo, hi)| (f(lo), f(hi)));
        let keys = format!("{:?}", c.keyframes);
        (
            f(c.velocity),
            f(c.angular_velocity),
            f(c.pivot),
            bounds,
            keys,
        )
    };
    let mut seen: HashSet<_> = out.iter().map(clock_key).collect();
    for c in worlds.iter().flat_map(|s| &s.colliders) {
        if moves(c) && seen.insert(clock_key(c)) {
            out.push(c.clone());
        }
    }
    out
}

/// Why the worlds' colliders cannot run in one GPU batch, or `None`: the same in every world,
/// or as many in every world, each a mesh only where world 0's is the same mesh (the mesh
/// table is shared). They may differ in anything else, moving or not (place, size, shape,
/// boundary rule, velocity, angular velocity, keyframes).
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
                 same number (they may differ in place, shape, boundary rule and motion)",
                s.colliders.len()
            ));
        }
        for (k, (c, c0)) in s.colliders.iter().zip(&base.colliders).enumerate() {
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

    /// Worlds whose colliders differ (place, rule, motion) run with tables of their own; the
    /// same colliders need none; different counts and different meshes are refused with the
    /// reason.
    #[test]
    fn colliders_may_differ_between_worlds_moving_or_not_and_counts_are_refused() {
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
            scene(&wall(0.24, "velocity = [0.3, 0.0, 0.0]\n")),
            scene(&wall(0.24, "")),
        ];
        assert!(differ(&moving));
        assert_eq!(crate::batch::unsupported(&moving, &o), None);
        let moving_counts = [
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
            scene(&format!(
                "{}{}",
                wall(0.2, "velocity = [0.2, 0.0, 0.0]\n"),
                wall(0.3, "")
            )),
        ];
        let why = crate::batch::unsupported(&moving_counts, &o).expect("refused");
        assert!(
            why.contains("world 1 has 2 colliders and world 0 has 1"),
            "{why}"
        );
        let both = [
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
            scene(&wall(0.2, "velocity = [0.1, 0.0, 0.0]\n")),
        ];
        assert!(!differ(&both));
        assert_eq!(crate::batch::unsupported(&both, &o), None);
    }

    /// A pusher swept over its speed in one world, keyframed in another, static in a third: the
    /// pose rows at any time are, world by world, the single run's poses of that world
    /// (`encode::poses`, what a separate CUDA run uploads), in rows `w * n + k`.
    #[test]
    fn each_worlds_pose_rows_are_its_single_runs_poses_at_every_time() {
        let keyframed = "keyframes = [{ t = 0.0, position = [0.22, 0.075, 0.2] }, \
                         { t = 0.05, position = [0.24, 0.075, 0.2], rotation = [0.0, 0.5, 0.0] }, \
                         { t = 0.1, position = [0.22, 0.1, 0.2] }]\n";
        let worlds = [
            scene(&format!(
                "{}{}",
                wall(0.2, "velocity = [0.1, 0.0, 0.0]\n"),
                wall(0.3, "")
            )),
            scene(&format!(
                "{}{}",
                wall(
                    0.2,
                    "velocity = [0.4, 0.0, 0.0]\nangular_velocity = [0.0, 1.0, 0.0]\n"
                ),
                wall(0.3, "")
            )),
            scene(&format!("{}{}", wall(0.2, keyframed), wall(0.3, ""))),
            scene(&format!("{}{}", wall(0.24, ""), wall(0.3, ""))),
        ];
        assert_eq!(refusal(&worlds), None);
        let all: Vec<Vec<Collider>> = worlds.iter().map(|s| s.colliders.clone()).collect();
        assert!(
            all[2][0].keyframes.is_some(),
            "world 2's pusher is keyframed"
        );
        for t in [0.0f32, 0.01, 0.03, 0.05, 0.07, 0.2] {
            let rows = pose_rows(&all, t);
            assert_eq!(rows.len(), 4 * 2);
            for (w, s) in worlds.iter().enumerate() {
                let single = crate::encode::poses(s, t);
                for k in 0..2 {
                    let r = rows[w * 2 + k];
                    assert_eq!(r.rot, single.rot[k], "world {w}, collider {k}, t {t}");
                    assert_eq!(r.pivot, single.pivot[k], "world {w}, collider {k}, t {t}");
                    assert_eq!(r.velocity, single.velocity[k], "world {w}, collider {k}");
                    assert_eq!(r.omega, single.omega[k], "world {w}, collider {k}");
                }
            }
        }
        // The worlds' pushers are where their own motion puts them.
        let at = pose_rows(&all, 0.05);
        assert!(
            (at[0].pivot[0] - (0.22 + 0.1 * 0.05)).abs() < 1e-6,
            "{:?}",
            at[0]
        );
        assert!(
            (at[2].pivot[0] - (0.22 + 0.4 * 0.05)).abs() < 1e-6,
            "{:?}",
            at[2]
        );
        assert_eq!(at[6].velocity, [0.0; 3], "world 3's wall is static");
        assert_ne!(at[0], at[2]);
        assert_ne!(at[2], at[4]);
        // The static second wall is the same row in every world.
        assert!((0..4).all(|w| at[w * 2 + 1] == at[1]));
        // Many worlds (evaluated on every core) keep their order.
        let many: Vec<Vec<Collider>> = (0..3000).map(|w| all[w % 4].clone()).collect();
        let rows = pose_rows(&many, 0.05);
        assert_eq!(rows.len(), 6000);
        assert!((0..6000).all(|r| rows[r] == at[r % 8]));
    }

    /// The shared clock's colliders: world 0's, then the moving ones of the other worlds that
    /// are not world 0's (each once): the CFL bound counts the fastest of any world and a step
    /// ends at any world's keyframe.
    #[test]
    fn the_shared_clock_counts_every_worlds_moving_colliders() {
        let keyframed = "keyframes = [{ t = 0.0, position = [0.22, 0.075, 0.2] }, \
                         { t = 0.05, position = [0.22, 0.075, 0.2] }, \
                         { t = 0.06, position = [0.27, 0.075, 0.2] }]\n";
        let worlds = [
            scene(&wall(0.2, "")),
            scene(&wall(0.2, "velocity = [0.5, 0.0, 0.0]\n")),
            scene(&wall(0.2, "velocity = [2.0, 0.0, 0.0]\n")),
            scene(&wall(0.2, "velocity = [0.5, 0.0, 0.0]\n")),
            scene(&wall(0.2, keyframed)),
        ];
        let clock = Scene {
            colliders: clock_colliders(&worlds),
            ..worlds[0].clone()
        };
        // World 0's wall is static: collider 0 of the clock is world 1's (the first that
        // moves), then world 2's and world 4's (world 3's is world 1's).
        assert_eq!(clock.colliders.len(), 3, "{:?}", clock.colliders);
        let key = |c: &Collider| format!("{c:?}");
        assert_eq!(key(&clock.colliders[0]), key(&worlds[1].colliders[0]));
        assert_eq!(key(&clock.colliders[1]), key(&worlds[2].colliders[0]));
        assert_eq!(key(&clock.colliders[2]), key(&worlds[4].colliders[0]));
        assert_eq!(clock.colliders.iter().position(moves), Some(0));
        let fastest = rtmpm_scene::speeds::fastest_boundary(&clock, (0.0, 0.0), &[])
            .expect("a moving collider");
        assert!((fastest.speed - 2.0).abs() < 1e-6, "{fastest:?}");
        // World 0 alone would not bound the step at all.
        assert!(rtmpm_scene::speeds::fastest_boundary(&worlds[0], (0.0, 0.0), &[]).is_none());
        // World 4's keyframe at 0.05 s (5 m/s after it) ends a step that would pass it.
        let step = rtmpm_scene::speeds::keyframe_step(&clock, 0.049, 0.01, |v| 0.2 * 0.02 / v);
        assert!((step - 0.001).abs() < 1e-6, "{step}");
        // World 0's moving collider keeps its place; a static one of every world is world 0's.
        let two = |v: &str| format!("{}{}", wall(0.1, ""), wall(0.2, v));
        let mixed = [
            scene(&two("velocity = [0.5, 0.0, 0.0]\n")),
            scene(&two("velocity = [1.0, 0.0, 0.0]\n")),
        ];
        let c = clock_colliders(&mixed);
        assert_eq!(c.len(), 3);
        assert_eq!(key(&c[0]), key(&mixed[0].colliders[0]));
        assert_eq!(key(&c[1]), key(&mixed[0].colliders[1]));
        assert_eq!(key(&c[2]), key(&mixed[1].colliders[1]));
        // Same colliders everywhere: the clock's are world 0's.
        let same = [
            scene(&wall(0.2, "velocity = [0.5, 0.0, 0.0]\n")),
            scene(&wall(0.2, "velocity = [0.5, 0.0, 0.0]\n")),
        ];
        assert_eq!(clock_colliders(&same).len(), 1);
    }
}
