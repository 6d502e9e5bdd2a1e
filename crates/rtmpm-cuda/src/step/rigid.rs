//! Rigid bodies on the GPU (`[[rigid_body]]`): the bodies move in rapier3d on the host
//! ([`rtmpm_rigid::RigidWorld`], cargo feature `rigid` of rtmpm-rigid), the grid update
//! couples them (`kernels/grid_update.cu`: `couple_bodies`, each body by `couple_body`, the same
//! rule as the CPU backend's `cpu/grid_update.rs`) and sums the reaction of every body, dynamic,
//! kinematic or fixed: the sums move a dynamic body, and divided by the step's dt they are the
//! load every body reports ([`LastLoads`], `Backend::rigid_loads`).
//!
//! Per step: the bodies' states go to constant memory with the step parameters; after the step
//! its impulse sums are copied to page-locked memory and cleared. By default
//! ([`crate::options::CudaOptions::rigid_overlap`]) the host then gives the bodies the sums of
//! the step before (copied while this one runs) and advances the rapier world, so the GPU never
//! waits for the host: the bodies see the material one step late (a pose lag of v dt, 0.1 mm
//! at 1 m/s and dt = 1e-4 s), and every impulse is applied once, so momentum is conserved. With
//! `rigid_overlap=off` the host waits for every step's sums before the next step: the CPU
//! backend's order exactly, at the cost of a host round trip per step (bench/RESULTS.md). The
//! step itself (its graph) is unchanged.

use crate::contract::{BODY_EXCHANGE_SLOTS, GpuBody, GpuCollider, MAX_BODIES};
use crate::error::err;
use cudarc::driver::{CudaEvent, CudaModule, CudaSlice, CudaStream, DevicePtr, PinnedHostSlice};
use rtmpm_rigid::{BodyLoad, BodyPose, BodyState, Exchange, RigidWorld};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::sync::Arc;

/// The device record of a body's state; a mesh body's distance grid starts at `mesh_offset` in
/// the mesh table (`encode::Tables::body_mesh`).
pub fn encode(b: &BodyState, mesh_offset: u32) -> GpuBody {
    let s = &b.shape;
    let mut col = GpuCollider {
        kind: crate::contract::collider_kind(s),
        cond: crate::contract::condition(b.condition),
        friction: b.friction,
        ..Default::default()
    };
    crate::encode::shape_params(s, &mut col);
    col.mesh_offset = mesh_offset;
    let mut r = GpuBody {
        shape: col,
        // The farthest point of the shape from its centre, and a little more for rounding.
        bound: b.shape.bounding_radius() * 1.001 + 1e-6,
        dynamic: b.dynamic as u32,
        ..Default::default()
    };
    encode_motion(b, &mut r);
    r
}

/// The fields of `r`, the device record of a body ([`encode`]), that move with the body: its
/// rotation, centre and velocities from its state `b`; the others (shape, boundary rule, bound,
/// kind) are a body's for good, left as [`encode`] wrote them (a batch's worlds rewrite their
/// records after every step: `crate::batch::bodies`).
pub fn encode_motion(b: &BodyState, r: &mut GpuBody) {
    r.rot = b.rotation.to_cols_array();
    r.center = b.center.to_array();
    r.velocity = b.velocity.to_array();
    r.omega = b.angular_velocity.to_array();
}

/// Words after the `BODY_EXCHANGE_SLOTS` x bodies x 6 impulse sums of [`BodyLink`]'s buffer and
/// of each of its host copies, which no kernel writes: zero on one GPU and in one process; in a
/// run of several processes each process puts the check of its rapier world there before the
/// buffer is summed across the processes (`crate::multi::rigid`).
pub const CHECK_WORDS: usize = 8;

/// The device side of the coupling on one GPU: the bodies' states the grid update reads and
/// the impulse sums it writes, with their page-locked copies on the host. One GPU has one
/// inside its [`Bodies`]; each GPU of several has its own, and the bodies move in the one
/// rapier world of the multi-GPU backend (`crate::multi::threaded`).
pub struct BodyLink {
    /// Global copy of `c_bodies` (`Ctx::bodies`): `MAX_BODIES` [`GpuBody`] records.
    states: CudaSlice<u8>,
    /// `BODY_EXCHANGE_SLOTS` x bodies x 6 f64 impulse sums (`Ctx::body_exchange`), then
    /// [`CHECK_WORDS`].
    exchange: CudaSlice<f64>,
    /// Page-locked copies of the sums of the last two steps, each with the event after its copy.
    host: [(PinnedHostSlice<f64>, CudaEvent); 2],
    /// The copy the next step's sums go to.
    next: usize,
    /// Bodies.
    n: usize,
    /// Where each body's distance grid starts in the mesh table (mesh bodies).
    mesh_offsets: Vec<u32>,
}

impl BodyLink {
    /// The buffers of `n` bodies (at most [`MAX_BODIES`]) on `stream`; `mesh_offsets`:
    /// `encode::Tables::body_mesh`.
    pub fn new(
        stream: &Arc<CudaStream>,
        n: usize,
        mesh_offsets: Vec<u32>,
    ) -> Result<BodyLink, SimError> {
        if n > MAX_BODIES {
            return Err(SimError::Backend(format!(
                "CUDA backend: at most {MAX_BODIES} rigid bodies (the scene has {n}); merge \
                 bodies or run on the CPU backend"
            )));
        }
        let len = BODY_EXCHANGE_SLOTS * n * 6 + CHECK_WORDS;
        let states = stream
            .alloc_zeros::<u8>(MAX_BODIES * std::mem::size_of::<GpuBody>())
            .map_err(err("alloc rigid bodies"))?;
        let exchange = stream
            .alloc_zeros::<f64>(len)
            .map_err(err("alloc rigid-body impulses"))?;
        let pinned = || -> Result<(PinnedHostSlice<f64>, CudaEvent), SimError> {
            // SAFETY: each copy is written by a device copy before the host reads it (after
            // its event).
            let h = unsafe { stream.context().alloc_pinned_with_flags::<f64>(len, 0) }
                .map_err(err("allocate page-locked memory"))?;
            let e = stream.record_event(None).map_err(err("record an event"))?;
            Ok((h, e))
        };
        Ok(BodyLink {
            states,
            exchange,
            host: [pinned()?, pinned()?],
            next: 0,
            n,
            mesh_offsets,
        })
    }

    /// Device addresses for [`crate::contract::Ctx`]: (bodies, impulse sums, count).
    pub fn ctx_fields(&self, stream: &Arc<CudaStream>) -> (u64, u64, u32) {
        let (a, _) = self.states.device_ptr(stream);
        let (b, _) = self.exchange.device_ptr(stream);
        (a, b, self.n as u32)
    }

    /// Words of the impulse buffer and of each host copy: the sums' slots, then
    /// [`CHECK_WORDS`].
    pub fn words(&self) -> usize {
        BODY_EXCHANGE_SLOTS * self.n * 6 + CHECK_WORDS
    }

    /// Put `words` in the [`CHECK_WORDS`] after the sums (on `stream`, after the step's
    /// kernels; the sums' copy to the host clears them with the sums).
    pub fn write_check(
        &mut self,
        stream: &Arc<CudaStream>,
        words: &[f64; CHECK_WORDS],
    ) -> Result<(), SimError> {
        let at = self.words() - CHECK_WORDS;
        stream
            .memcpy_htod(&words[..], &mut self.exchange.slice_mut(at..))
            .map_err(err("upload the rigid-body check"))
    }

    /// Before a step: `states` to constant memory (and its global copy).
    pub fn upload(
        &mut self,
        module: &Arc<CudaModule>,
        stream: &Arc<CudaStream>,
        states: &[BodyState],
    ) -> Result<(), SimError> {
        let recs: Vec<GpuBody> = states
            .iter()
            .enumerate()
            .map(|(i, b)| encode(b, self.mesh_offsets.get(i).copied().unwrap_or(0)))
            .collect();
        let bytes: &[u8] = bytemuck::cast_slice(&recs);
        stream
            .memcpy_htod(bytes, &mut self.states.slice_mut(..bytes.len()))
            .map_err(err("upload rigid bodies"))?;
        crate::kernels::write_symbol(module, stream, "c_bodies", bytes)
    }

    /// After a step was queued: its impulse sums are copied to the host and cleared for the
    /// next step. Returns the copy they go to (for [`BodyLink::sums`]).
    pub fn queue_sums(&mut self, stream: &Arc<CudaStream>) -> Result<usize, SimError> {
        let k = self.next;
        let (host, event) = &mut self.host[k];
        stream
            .memcpy_dtoh(&self.exchange, host)
            .map_err(err("read rigid-body impulses"))?;
        *event = stream.record_event(None).map_err(err("record an event"))?;
        stream
            .memset_zeros(&mut self.exchange)
            .map_err(err("clear rigid-body impulses"))?;
        self.next ^= 1;
        Ok(k)
    }

    /// Wait for copy `k` and add up its slots, body by body.
    pub fn sums(&self, k: usize) -> Result<Vec<Exchange>, SimError> {
        Ok(exchange_sums(self.copy(k)?, self.n))
    }

    /// Wait for copy `k`: its [`BodyLink::words`] words (the sums' slots, then the check).
    pub fn copy(&self, k: usize) -> Result<&[f64], SimError> {
        let (host, event) = &self.host[k & 1];
        event
            .synchronize()
            .map_err(err("wait for rigid-body impulses"))?;
        host.as_slice().map_err(err("page-locked memory"))
    }
}

/// The rigid bodies of a GPU run: their rapier world and the device side of the coupling.
pub struct Bodies {
    world: RigidWorld,
    link: BodyLink,
    /// A step whose sums the bodies have not taken yet: its copy and its dt.
    pending: Option<(usize, f32)>,
    /// See [`crate::options::CudaOptions::rigid_overlap`].
    overlap: bool,
    /// The sums of the last step the bodies took (the loads).
    last: LastLoads,
}

impl Bodies {
    /// Gravity from the next advance of the bodies on.
    pub fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) {
        self.world.set_gravity(gravity);
    }

    /// The bodies of `scene` (`None` without any), their device buffers allocated on `stream`;
    /// `mesh_offsets`: `encode::Tables::body_mesh`. Refused with the MUSL update, as on the CPU.
    pub fn new(
        scene: &Scene,
        stream: &Arc<CudaStream>,
        overlap: bool,
        mesh_offsets: Vec<u32>,
    ) -> Result<Option<Bodies>, SimError> {
        let Some(world) = world(scene)? else {
            return Ok(None);
        };
        let link = BodyLink::new(stream, scene.rigid_bodies.len(), mesh_offsets)?;
        Ok(Some(Bodies {
            world,
            link,
            pending: None,
            overlap,
            last: LastLoads::default(),
        }))
    }

    /// Device addresses for [`crate::contract::Ctx`]: (bodies, impulse sums, count).
    pub fn ctx_fields(&self, stream: &Arc<CudaStream>) -> (u64, u64, u32) {
        self.link.ctx_fields(stream)
    }

    /// The bodies' states at the current time.
    pub fn states(&self) -> &[BodyState] {
        self.world.states()
    }

    /// Where each body's distance grid starts in the mesh table (`encode::Tables::body_mesh`).
    pub fn mesh_offsets(&self) -> Vec<u32> {
        self.link.mesh_offsets.clone()
    }

    /// Before a step: the bodies' states to constant memory (and its global copy).
    pub fn upload(
        &mut self,
        module: &Arc<CudaModule>,
        stream: &Arc<CudaStream>,
    ) -> Result<(), SimError> {
        self.link.upload(module, stream, self.world.states())
    }

    /// After a step of `dt` was queued: its impulse sums are copied to the host and cleared
    /// for the next step. Without overlap the host waits for them and moves the bodies now;
    /// with overlap it moves them by the previous step's sums (already there while this step
    /// runs), so the next step sees bodies one step late.
    pub fn after_step(&mut self, stream: &Arc<CudaStream>, dt: f32) -> Result<(), SimError> {
        let k = self.link.queue_sums(stream)?;
        let due = if self.overlap {
            self.pending.replace((k, dt))
        } else {
            Some((k, dt))
        };
        match due {
            Some((q, dt)) => self.apply(q, dt),
            None => Ok(()),
        }
    }

    /// Give the bodies the sums of a step that was queued and not yet taken (before the state
    /// is read or stored: the end of a frame, a checkpoint).
    pub fn flush(&mut self) -> Result<(), SimError> {
        match self.pending.take() {
            Some((q, dt)) => self.apply(q, dt),
            None => Ok(()),
        }
    }

    /// Wait for copy `k`, give its sums to the bodies and advance the world by `dt`.
    fn apply(&mut self, k: usize, dt: f32) -> Result<(), SimError> {
        let ex = self.link.sums(k)?;
        self.world.advance(&ex, dt);
        self.last.record(ex, dt);
        Ok(())
    }
}

impl HeldBodies for Bodies {
    fn states(&self) -> &[BodyState] {
        self.world.states()
    }

    fn poses(&self) -> Vec<BodyPose> {
        self.world.poses()
    }

    fn loads(&self) -> Vec<BodyLoad> {
        self.last.loads(self.world.states().len())
    }

    /// Impulses not yet taken are dropped.
    fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError> {
        self.pending = None;
        self.world.set_poses(poses).map_err(SimError::Backend)
    }
}

/// The impulse sums of the last step whose sums the bodies took, and that step's dt: divided by
/// dt, the load (force, and torque about the centre of mass) the material put on each body,
/// dynamic, kinematic or fixed, as the CPU backend reports it (`Backend::rigid_loads`). With
/// [`crate::options::CudaOptions::rigid_overlap`] the bodies take a step's sums during the next
/// step, so the last step's load is there after `Backend::flush_rigid` (which Python's
/// `rigid_bodies` and every frame end call).
#[derive(Clone, Debug, Default)]
pub struct LastLoads {
    last: Option<(Vec<Exchange>, f32)>,
}

impl LastLoads {
    /// The bodies took `sums` of a step of `dt` (summed over every GPU of a run).
    pub fn record(&mut self, sums: Vec<Exchange>, dt: f32) {
        self.last = Some((sums, dt));
    }

    /// Each of `bodies` bodies' load over the last step taken: zeros before the first.
    pub fn loads(&self, bodies: usize) -> Vec<BodyLoad> {
        match &self.last {
            Some((sums, dt)) if sums.len() == bodies => {
                sums.iter().map(|e| e.load(*dt as f64)).collect()
            }
            _ => vec![BodyLoad::default(); bodies],
        }
    }
}

/// The rigid bodies as a backend holds them (one GPU's [`Bodies`], the multi-GPU backends'
/// world): what the `Backend` methods of the bodies read and set, through [`states_of`],
/// [`poses_of`], [`loads_of`] and [`set_poses_of`].
pub(crate) trait HeldBodies {
    /// The bodies' states at the current time.
    fn states(&self) -> &[BodyState];
    /// Every body's pose and velocities (what a checkpoint stores).
    fn poses(&self) -> Vec<BodyPose>;
    /// Every body's load over the last step taken ([`LastLoads`]).
    fn loads(&self) -> Vec<BodyLoad>;
    /// Put the bodies at `poses` (resuming a checkpoint, a script moving them).
    fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError>;
}

/// `Backend::rigid_bodies` of a backend holding `bodies` (none without `[[rigid_body]]`).
pub(crate) fn states_of<B: HeldBodies>(bodies: Option<&B>) -> Vec<BodyState> {
    bodies.map_or_else(Vec::new, |b| b.states().to_vec())
}

/// `Backend::rigid_poses` of a backend holding `bodies`.
pub(crate) fn poses_of<B: HeldBodies>(bodies: Option<&B>) -> Vec<BodyPose> {
    bodies.map_or_else(Vec::new, HeldBodies::poses)
}

/// `Backend::rigid_loads` of a backend holding `bodies`: every body's, for every kind of body
/// (none without bodies, as on the CPU).
pub(crate) fn loads_of<B: HeldBodies>(bodies: Option<&B>) -> Option<Vec<BodyLoad>> {
    Some(bodies.map_or_else(Vec::new, HeldBodies::loads))
}

/// `Backend::set_rigid_poses` of a backend holding `bodies`: poses for a scene without bodies
/// are refused (none are accepted).
pub(crate) fn set_poses_of<B: HeldBodies>(
    bodies: Option<&mut B>,
    poses: &[BodyPose],
) -> Result<(), SimError> {
    match bodies {
        Some(b) => b.set_poses(poses),
        None if poses.is_empty() => Ok(()),
        None => Err(SimError::Backend(format!(
            "{} rigid-body states for a scene without rigid bodies",
            poses.len()
        ))),
    }
}

/// The rapier world of the scene's bodies (`None` without any). Refused with more bodies than
/// the GPU's table holds, and with the MUSL update, as on the CPU.
pub fn world(scene: &Scene) -> Result<Option<RigidWorld>, SimError> {
    if scene.rigid_bodies.is_empty() {
        return Ok(None);
    }
    if scene.rigid_bodies.len() > MAX_BODIES {
        return Err(SimError::Backend(format!(
            "CUDA backend: at most {MAX_BODIES} rigid bodies (the scene has {}); merge bodies \
             or run on the CPU backend",
            scene.rigid_bodies.len()
        )));
    }
    if scene.solver.update == rtmpm_physics::transfer::Update::Musl {
        return Err(SimError::Backend(
            "rigid bodies are coupled in the grid update of USL steps: use [solver] update = \
             \"usl\" with [[rigid_body]] tables"
                .into(),
        ));
    }
    RigidWorld::new(
        &scene.rigid_bodies,
        &scene.joints,
        scene.gravity,
        scene.interior(),
    )
    .map_err(SimError::Backend)
}

/// The impulse sums of every body from the `BODY_EXCHANGE_SLOTS` copies (slot-major: slot,
/// body, 6 values), added in slot order (the same sum for the same copies); the
/// [`CHECK_WORDS`] after the slots are not sums and are left out.
pub fn exchange_sums(sums: &[f64], bodies: usize) -> Vec<Exchange> {
    let mut out = vec![Exchange::default(); bodies];
    for slot in sums
        .chunks_exact(6 * bodies.max(1))
        .take(BODY_EXCHANGE_SLOTS)
    {
        for (e, v) in out.iter_mut().zip(slot.chunks_exact(6)) {
            for a in 0..3 {
                e.impulse[a] += v[a];
                e.torque[a] += v[3 + a];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_geometry::Shape;
    use rtmpm_physics::boundary::Condition;

    /// The loads are the last step's sums over its dt, body by body; zeros before any step
    /// (and for a count of bodies the sums do not have).
    #[test]
    fn the_loads_are_the_last_sums_over_their_dt() {
        let mut last = LastLoads::default();
        assert_eq!(last.loads(2), vec![BodyLoad::default(); 2]);
        let e = |i: f64, t: f64| Exchange {
            impulse: [i, -2.0 * i, 0.0],
            torque: [0.0, 0.0, t],
        };
        last.record(vec![e(1e-3, 0.0), e(0.0, 5e-4)], 1e-3);
        last.record(vec![e(2e-3, 1e-4), e(-1e-3, 0.0)], 5e-4);
        let l = last.loads(2);
        // dt = 5e-4 in f32: within 1e-7 of it.
        let near = |a: [f64; 3], b: [f64; 3]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-6 * y.abs())
        };
        assert!(near(l[0].force, [4.0, -8.0, 0.0]), "{l:?}");
        assert!(near(l[0].torque, [0.0, 0.0, 0.2]), "{l:?}");
        assert!(near(l[1].force, [-2.0, 4.0, 0.0]), "{l:?}");
        assert!(near(l[1].torque, [0.0; 3]), "{l:?}");
        assert_eq!(last.loads(3), vec![BodyLoad::default(); 3]);
    }

    /// A backend without bodies reports no loads (an empty list, as the CPU backend) and
    /// accepts no poses but none, with the count in the error.
    #[test]
    fn a_backend_without_bodies_has_no_loads_and_takes_no_poses() {
        let none: Option<&mut Bodies> = None;
        assert_eq!(loads_of::<Bodies>(None), Some(Vec::new()));
        assert!(states_of::<Bodies>(None).is_empty() && poses_of::<Bodies>(None).is_empty());
        assert!(set_poses_of(none, &[]).is_ok());
        let pose = BodyPose {
            position: glam::Vec3::ONE,
            rotation: glam::Quat::IDENTITY,
            velocity: glam::Vec3::ZERO,
            angular_velocity: glam::Vec3::ZERO,
        };
        let e = set_poses_of::<Bodies>(None, &[pose, pose]).expect_err("refused");
        assert!(
            e.to_string()
                .contains("2 rigid-body states for a scene without rigid bodies"),
            "{e}"
        );
    }

    #[test]
    fn the_slots_add_up_body_by_body() {
        let mut sums = vec![0.0; BODY_EXCHANGE_SLOTS * 2 * 6];
        // Body 1's impulse y in slot 0 and slot 31, body 0's torque z in slot 5.
        sums[6 + 1] = 1.5;
        sums[31 * 12 + 6 + 1] = 2.0;
        sums[5 * 12 + 5] = -3.0;
        let e = exchange_sums(&sums, 2);
        assert_eq!(e[1].impulse, [0.0, 3.5, 0.0]);
        assert_eq!(e[0].torque, [0.0, 0.0, -3.0]);
        assert_eq!(e[0].impulse, [0.0; 3]);
    }

    /// The check words after the slots (a buffer of [`BodyLink::words`]) are no impulse, even
    /// for one body, whose 6 values are fewer than the check's words.
    #[test]
    fn the_check_words_after_the_slots_are_no_impulse() {
        for bodies in [1, 2, 5] {
            let slots = BODY_EXCHANGE_SLOTS * bodies * 6;
            let mut sums = vec![1.0; slots + CHECK_WORDS];
            sums[slots..].fill(1e9);
            for e in exchange_sums(&sums, bodies) {
                assert_eq!(e.impulse, [BODY_EXCHANGE_SLOTS as f64; 3], "{bodies}");
                assert_eq!(e.torque, [BODY_EXCHANGE_SLOTS as f64; 3], "{bodies}");
            }
        }
    }

    /// A mesh body's distance grid goes to the mesh table after the mesh colliders' (and their
    /// sentinel), and its record points there with the grid's origin, spacing and dims (the
    /// body frame): what `mesh_distance` reads for colliders.
    #[test]
    fn a_mesh_body_is_encoded_as_a_mesh_grid_after_the_colliders_meshes() {
        let dir = std::env::temp_dir().join(format!("rtmpm-cuda-mesh-body-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj = dir.join("cube.obj");
        std::fs::write(
            &obj,
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
             f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
        )
        .unwrap();
        let text = format!(
            "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
             bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
             min = [0.2, 0.2, 0.2]\nmax = [0.4, 0.4, 0.4]\n\
             [[collider]]\nshape = \"mesh\"\nfile = \"{0}\"\nscale = 0.1\n\
             translate = [0.7, 0.2, 0.2]\n\
             [[rigid_body]]\nshape = \"sphere\"\ncenter = [0.3, 0.7, 0.3]\nradius = 0.1\n\
             density = 500.0\n\
             [[rigid_body]]\nshape = \"mesh\"\nfile = \"{0}\"\nscale = [0.2, 0.1, 0.2]\n\
             translate = [0.6, 0.6, 0.6]\ndensity = 500.0\n",
            obj.display()
        );
        let scene = rtmpm_scene::Scene::from_toml(&text, "test").unwrap_or_else(|e| panic!("{e}"));
        let t = crate::encode::tables(&scene, false).unwrap();
        let Shape::Mesh(col) = &scene.colliders[0].shape else {
            panic!("a mesh collider")
        };
        // Collider grid, sentinel, then the body's grid.
        let at = col.sdf.values.len() as u32 + 1;
        assert_eq!(t.body_mesh, vec![0, at]);
        let Shape::Mesh(m) = &scene.rigid_bodies[1].shape else {
            panic!("a mesh body")
        };
        assert_eq!(&t.mesh[at as usize..], &m.sdf.values[..]);
        let b = BodyState {
            shape: scene.rigid_bodies[1].shape.clone(),
            rotation: glam::Mat3::IDENTITY,
            center: scene.rigid_bodies[1].position,
            velocity: glam::Vec3::ZERO,
            angular_velocity: glam::Vec3::ZERO,
            dynamic: true,
            condition: Condition::Slip,
            friction: 0.0,
        };
        assert!((b.center - glam::Vec3::new(0.7, 0.65, 0.7)).length() < 1e-5);
        let g = encode(&b, at);
        assert_eq!(
            g.shape.kind,
            crate::contract::collider_kind(&scene.rigid_bodies[1].shape)
        );
        assert_eq!(g.shape.mesh_offset, at);
        assert_eq!(g.shape.dims, m.sdf.dims);
        assert_eq!(
            &g.shape.p[..4],
            &[
                m.sdf.origin.x,
                m.sdf.origin.y,
                m.sdf.origin.z,
                m.sdf.spacing
            ]
        );
        // The body frame is about the centre of mass: the grid spans the box about 0.
        assert!(m.sdf.origin.cmplt(glam::Vec3::new(-0.1, -0.05, -0.1)).all());
        let corner = glam::Vec3::new(0.1, 0.05, 0.1).length();
        assert!(g.bound >= corner && g.bound < corner * 1.01, "{}", g.bound);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_body_is_encoded_as_its_collider_shape_about_its_centre() {
        let b = BodyState {
            shape: Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                glam::Vec3::ZERO,
                glam::Vec3::new(0.1, 0.2, 0.3),
            )),
            rotation: glam::Mat3::from_rotation_z(0.5),
            center: glam::Vec3::new(1.0, 2.0, 3.0),
            velocity: glam::Vec3::X,
            angular_velocity: glam::Vec3::Y,
            dynamic: true,
            condition: Condition::Separate,
            friction: 0.25,
        };
        let g = encode(&b, 0);
        assert_eq!(g.shape.kind, Shape::code_of("box").expect("a box"));
        // Its min and max in the body frame (kernels/geometry/box.cuh).
        assert_eq!(&g.shape.p[..6], &[-0.1, -0.2, -0.3, 0.1, 0.2, 0.3]);
        assert_eq!(
            g.shape.cond,
            crate::contract::condition(Condition::Separate)
        );
        assert_eq!(g.rot, b.rotation.to_cols_array());
        assert_eq!(g.dynamic, 1);
        // Every corner of the box is inside the bounding sphere.
        let corner = glam::Vec3::new(0.1, 0.2, 0.3).length();
        assert!(g.bound >= corner && g.bound < corner * 1.01, "{}", g.bound);
    }
}
