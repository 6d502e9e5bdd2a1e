//! Many worlds in the same kernels ([`CudaBatch`]): the worlds of a batch (`[batch]`,
//! `rtmpm_scene::BatchScene`) share one set of device arrays and one launch per stage, each
//! world isolated in the sparse grid.
//!
//! Layout. Particles keep their positions in their world's own coordinates; world `w`'s grid
//! lies `w * stride + WORLD_ORIGIN_CELLS` cells along x from the grid's origin, so its block
//! coordinates (and the 64-bit block codes made of them) are its own: the stencil of a particle
//! of world `w` (`stencil_of` in `kernels/common.cuh`) is shifted by that many cells, and
//! `stride` leaves a gap of at least [`WORLD_GAP_CELLS`] cells past every node a world can
//! touch (its domain, the 4-cell margin, the free zone's neighbour blocks), so no world reaches
//! another's nodes. A particle's world is its material row divided by the materials of a world
//! (row `w * m + k` is material `k` of world `w`): each world has its own material parameters,
//! read from global memory. The grid update finds a node's world from its x block coordinate and
//! applies gravity from a per-world table, the domain walls and the colliders in the world's own
//! coordinates (`kernels/grid_update.cu`).
//!
//! The kernels of one world are compiled without `RTMPM_BATCH` and are unchanged by all this
//! (their PTX is the same); a batch compiles its own program with it.
//!
//! Rigid bodies ([`bodies`]): each world has its own rapier world on the host and its own rows of
//! a per-world body table on the device; the grid update couples a node to its world's bodies
//! only (in the world's coordinates) and sums the reaction of every body, dynamic or not, per
//! world and body: the loads of [`Worlds::world_rigid_loads`], and what moves a dynamic body.
//!
//! Colliders ([`colliders`]): the scene's, shared by every world, or, when the worlds'
//! colliders differ (place, size, turn, boundary rule, velocity, keyframes), each world's own
//! records and poses in per-world tables that the grid update reads by the node's world; the
//! poses of moving ones evaluated on the host for every world at each step's time.
//!
//! What a batch shares: the time step (the caller's; one `dt` for every world: the driver's
//! bound counts every world, [`CudaBatch::scene`]), the domain and grid spacing, the walls and
//! solver, the number of colliders and rigid bodies (and a mesh's mesh). Not yet: emitters.

mod accept;
mod bodies;
mod colliders;
mod initial;
mod layout;
mod put;
mod put_slots;
mod redo;
mod staging;

pub use accept::unsupported;
use accept::{batch_capacities, check_particles};
pub use layout::{
    BatchParams, MAX_GRID_CELLS_X, WORLD_GAP_CELLS, WORLD_ORIGIN_CELLS, world_stride,
};
pub use put_slots::{PutSlots, old_puts};
pub use redo::plan::{PutWorlds, Redo, RedoCounts, old_redo, wave_redo};
pub use staging::old_resets;

use crate::backend::{CudaBackend, Part};
use crate::error::err;
use crate::options::CudaOptions;
use crate::setup::Initial;
use cudarc::driver::{CudaSlice, DevicePtr};
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::{BodyLoad, BodyPose, BodyState};
use rtmpm_scene::Scene;
use rtmpm_sim::{Backend, BadParticle, SimError, Worlds};

/// Page-locked buffers a batch's puts go through at most ([`CudaBatch::put_worlds`]: a put is
/// written into one whose last copy is done; 1, waited for, with `RTMPM_BATCH_WAITS=old`).
const PUT_BUFFERS: usize = 8;

/// `RTMPM_STEP_TIMING=1`: where a batch's step spends the host's time, printed to stderr every
/// 100 steps (the means of the rigid bodies' table put in and uploaded, the worlds' own
/// colliders' poses, the step's kernels queued, and the bodies' sums and advance after it); off
/// by default. With the driver's advance parts (rtmpm-driver, the same variable).
static STEP_TIMING: rtmpm_sim::timing::PartTimes<4> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_STEP_TIMING",
    "batch step",
    "steps",
    [
        "bodies up",
        "colliders",
        "kernels queued",
        "bodies advanced",
    ],
);

/// The worlds of a batch on one GPU, stepped together.
pub struct CudaBatch {
    backend: CudaBackend,
    /// First particle (original index) of each world, and the total at the end.
    offsets: Vec<usize>,
    /// Materials of one world.
    materials: usize,
    /// The per-world gravity table (kept alive: `c_batch` points into it).
    gravity: CudaSlice<u8>,
    params: BatchParams,
    /// Every world's rigid bodies, if the worlds have any.
    bodies: Option<bodies::WorldBodies>,
    /// The worlds' own colliders, when they differ (kept alive: `c_batch` points into them).
    colliders: Option<colliders::WorldColliders>,
    /// The rewind point ([`CudaBatch::save_point`]): a copy of the particle state on the
    /// device, allocated at the first save.
    point: Option<CudaSlice<u8>>,
    /// The next call's rewind point, kept while the last call's check may still need `point`
    /// ([`CudaBatch::save_next_point`]), allocated at the first such save.
    next_point: Option<CudaSlice<u8>>,
    /// The device had no memory for the point: the driver keeps it on the host instead.
    no_point: bool,
    /// Every world's particles at time 0, packed (rows of the batch's particle count), kept by
    /// [`CudaBatch::keep_initial`] for [`CudaBatch::put_initial`].
    initial: Option<CudaSlice<u8>>,
    /// The worlds' images the last [`CudaBatch::put_worlds`] uploaded (kept for the next; it
    /// grows to the largest put).
    put_buffer: Option<CudaSlice<u8>>,
    /// The host side of the puts, kept between calls (no allocation, no fresh pages a put):
    /// the particles of a run of worlds, and the images of all runs uploaded.
    put_run: Particles,
    put_host: Vec<u8>,
    /// The page-locked copies of `put_host` the device reads the uploads from
    /// ([`CudaBatch::put_worlds`] without a wait for the device).
    put_staging: crate::staging::StagingRing,
    /// The scene of the shared clock ([`CudaBatch::scene`]).
    clock: Scene,
    /// The worlds put since the last step, whose P2G the next redoes ([`CudaBatch::redo_puts`]).
    put_since: PutWorlds,
    /// After a put, redo every world's P2G ([`CudaBatch::set_full_redo`]).
    full_redo: bool,
    /// The redos so far ([`CudaBatch::redo_counts`]).
    redo_counts: RedoCounts,
    /// Whether the last rebuild's gblock slot ranges can serve a put ([`put_slots`]).
    put_slots: PutSlots,
    /// Puts use `batch_put_gblocks` where the ranges serve ([`CudaBatch::set_gblock_puts`]).
    gblock_puts: bool,
    /// Every particle of the image [`CudaBatch::keep_initial`] kept lies within the domain's x
    /// range (a put from it leaves the slot ranges trusted).
    initial_within: bool,
    /// The partial redo launches its kernels of a warp an item over a full wave
    /// ([`CudaBatch::set_wave_redo`]).
    wave_redo: bool,
}

impl CudaBatch {
    /// The worlds `worlds` (the scenes of a batch, e.g. `BatchScene::worlds`) with their
    /// initial particles, on CUDA device 0. Refused before anything is allocated: worlds that
    /// differ in what they must share, a batch whose grid the block codes cannot address, a
    /// batch larger than the GPU's free memory (with the numbers).
    pub fn new(
        worlds: &[Scene],
        particles: &[Particles],
        options: CudaOptions,
    ) -> Result<CudaBatch, SimError> {
        if let Some(why) = unsupported(worlds, &options) {
            return Err(SimError::Backend(format!(
                "CUDA batch: {why} (fix: --backend cpu)"
            )));
        }
        check_particles(worlds, particles)?;
        let m = worlds[0].materials.len();
        let stride = world_stride(worlds[0].n_cells()[0] as usize);
        let merged = merged_scene(worlds);
        let clock = Scene {
            colliders: colliders::clock_colliders(worlds),
            ..merged.clone()
        };
        let mut all = Particles::default();
        let mut offsets = vec![0];
        for (w, p) in particles.iter().enumerate() {
            let first = all.len();
            all.extend(p);
            for k in &mut all.material[first..] {
                *k += (w * m) as u32;
            }
            offsets.push(all.len());
        }
        let options = batch_capacities(worlds, particles, options);
        let (g, p) = (
            options.gblock_capacity.unwrap_or(0),
            options.pblock_capacity.unwrap_or(0),
        );
        let mut backend = CudaBackend::build_for(
            &merged,
            Initial::Particles(&all),
            &Part::default(),
            options,
            true,
        )
        .map_err(|e| match e {
            SimError::Backend(why) if why.contains("of GPU memory") => SimError::Backend(format!(
                "CUDA batch of {} worlds ({} particles; {g} gblocks and {p} pblocks of grid, \
                 the worlds' own summed): {why}\n  fix for a batch: fewer worlds (the grid grows \
                 with each world's domain: a smaller domain or a coarser dx per world)",
                worlds.len(),
                all.len(),
            )),
            e => e,
        })?;
        drop(all);
        let bodies = world_bodies(&mut backend, worlds)?;
        let colliders = colliders::WorldColliders::new(worlds, &backend.stream)?;
        let (own_colliders, own_poses) = colliders
            .as_ref()
            .map_or((0, 0), |c| c.pointers(&backend.stream));
        let real_bytes = if backend.options.f64 { 8 } else { 4 };
        let mut table = Vec::with_capacity(worlds.len() * 3 * real_bytes);
        for s in worlds {
            for a in 0..3 {
                if real_bytes == 8 {
                    table.extend_from_slice(&(s.gravity[a] as f64).to_le_bytes());
                } else {
                    table.extend_from_slice(&s.gravity[a].to_le_bytes());
                }
            }
        }
        let gravity = backend
            .stream
            .clone_htod(&table)
            .map_err(err("upload the worlds' gravity"))?;
        let params = BatchParams {
            worlds: worlds.len() as u32,
            materials: m as u32,
            stride: stride as u32,
            origin: WORLD_ORIGIN_CELLS as u32,
            gravity: gravity.device_ptr(&backend.stream).0,
            colliders: own_colliders,
            poses: own_poses,
        };
        crate::kernels::write_symbol(
            &backend.module,
            &backend.stream,
            "c_batch",
            bytemuck::bytes_of(&params),
        )?;
        Ok(CudaBatch {
            backend,
            offsets,
            materials: m,
            gravity,
            params,
            bodies,
            colliders,
            point: None,
            next_point: None,
            no_point: false,
            initial: None,
            put_buffer: None,
            put_run: Particles::default(),
            put_host: Vec::new(),
            put_staging: crate::staging::StagingRing::new(PUT_BUFFERS, 1),
            clock,
            put_since: PutWorlds::default(),
            full_redo: old_redo(),
            redo_counts: RedoCounts::default(),
            put_slots: PutSlots::default(),
            gblock_puts: !old_puts(),
            initial_within: false,
            wave_redo: wave_redo(),
        })
    }

    /// Worlds.
    pub fn worlds(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The parameters the kernels read.
    pub fn params(&self) -> BatchParams {
        self.params
    }

    /// The scene of the worlds' shared clock, which the driver steps the batch by: world 0's,
    /// with every world's materials (rows `w * materials ..` are world `w`'s, as in the
    /// kernels), the strongest world's gravity, and every world's moving colliders (collider
    /// `k` is world 0's, or the first world's that moves when world 0's is static; the other
    /// moving ones after them): what bounds the shared time step (its CFL step counts the
    /// fastest collider of any world and ends at any world's keyframe) and refuses a reset of
    /// some worlds while a collider of any world moves.
    pub fn scene(&self) -> &Scene {
        &self.clock
    }

    /// The one backend that holds every world (for its timing and memory figures).
    pub fn backend(&mut self) -> &mut CudaBackend {
        &mut self.backend
    }

    /// Bytes of the gravity table.
    pub fn gravity_bytes(&self) -> usize {
        self.gravity.len()
    }

    /// Bytes of the worlds' own collider tables (0 when the worlds share the scene's).
    pub fn collider_bytes(&self) -> usize {
        self.colliders.as_ref().map_or(0, |c| c.bytes())
    }

    /// One step of `dt` for every world at time `t`: every world's rigid bodies, and the poses
    /// of its own moving colliders at `t`, go to the device before it, and the P2G of the
    /// worlds put since the last step is queued first (with G2P2G, [`CudaBatch::redo_puts`]);
    /// the bodies advance by it after (their sums read back).
    pub fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let t0 = std::time::Instant::now();
        let stream = self.backend.stream.clone();
        if let Some(b) = self.bodies.as_mut() {
            // The step reads the table just given the rows (the two are taken in turn).
            let k = b.upload(&stream)?;
            let c = &mut self.backend.ctx;
            (c.bodies, c.body_exchange, c.n_bodies) = b.ctx_fields(&stream, k);
            self.backend.body_table = k;
        }
        let t1 = std::time::Instant::now();
        if let Some(c) = self.colliders.as_mut() {
            c.update(&stream, t, &self.backend.waits)?;
        }
        let t2 = std::time::Instant::now();
        if self.backend.p2g_due_for(dt) {
            // The step redoes every world's P2G (a new dt).
            self.put_since.clear();
        } else {
            self.redo_puts()?;
        }
        self.backend.step(dt, t)?;
        self.put_slots.stepped();
        let t3 = std::time::Instant::now();
        if let Some(b) = self.bodies.as_mut() {
            b.after_step(&stream, dt)?;
        }
        STEP_TIMING.record(1, [t0, t1, t2, t3], std::time::Instant::now());
        Ok(())
    }

    /// Rigid bodies of one world (every world has as many).
    pub fn bodies_per_world(&self) -> usize {
        self.bodies.as_ref().map_or(0, |b| b.per_world())
    }

    /// World `w`'s rigid bodies' poses and velocities (empty without bodies).
    pub fn world_poses(&self, w: usize) -> Vec<BodyPose> {
        self.bodies.as_ref().map_or_else(Vec::new, |b| b.poses(w))
    }

    /// Put world `w`'s rigid bodies at `poses` from the next step on (a tool posed by a
    /// script, a reset, a rewind); the other worlds' bodies are not touched.
    pub fn set_world_poses(&mut self, w: usize, poses: &[BodyPose]) -> Result<(), SimError> {
        match self.bodies.as_mut() {
            Some(b) => b.set_poses(w, poses),
            None if poses.is_empty() => Ok(()),
            None => Err(SimError::Backend(format!(
                "CUDA batch: {} rigid-body poses for world {w}, whose scene has no rigid bodies",
                poses.len()
            ))),
        }
    }

    /// World `w`'s rigid bodies' poses into `out` (emptied first; empty without bodies).
    pub fn world_poses_into(&self, w: usize, out: &mut Vec<BodyPose>) {
        match self.bodies.as_ref() {
            Some(b) => b.poses_into(w, out),
            None => out.clear(),
        }
    }

    /// Rigid body `body` of world `w` now (its pose and velocities), `None` where there is no
    /// such world or body.
    pub fn world_body_pose(&self, w: usize, body: usize) -> Option<BodyPose> {
        self.bodies.as_ref()?.pose(w, body)
    }

    /// Rigid body `body` of each world of `worlds` now into `out` (emptied first; `None` where
    /// there is no such world or body): [`CudaBatch::world_body_pose`] of each, read at once (a
    /// script posing a tool in every world reads them all before it poses them).
    pub fn world_body_poses(&self, body: usize, worlds: &[usize], out: &mut Vec<Option<BodyPose>>) {
        match self.bodies.as_ref() {
            Some(b) => b.body_poses(body, worlds, out),
            None => {
                out.clear();
                out.resize(worlds.len(), None);
            }
        }
    }

    /// Put rigid body `body` of each world `w` of `poses` at its pose from the next step on,
    /// the worlds' other bodies where they are ([`Worlds::set_body_poses`]): every world and the
    /// body checked first (nothing changes on an error), then the poses kept until the next
    /// step's upload puts them into the worlds' rapier worlds on every core (or a read that needs
    /// them does; `CudaOptions::batch_poses`: the same state bit for bit as putting each in at
    /// once). A script posing a tool in every world pays no vector per world and touches no
    /// world's rapier world.
    pub fn set_body_poses(
        &mut self,
        body: usize,
        poses: &[(usize, BodyPose)],
    ) -> Result<(), SimError> {
        match self.bodies.as_mut() {
            Some(b) => b.set_body_poses(body, poses),
            None if poses.is_empty() => Ok(()),
            None => Err(SimError::Backend(format!(
                "CUDA batch: a pose for rigid body {body} of {} worlds, whose scenes have no \
                 rigid bodies",
                poses.len()
            ))),
        }
    }

    /// The force and torque the material put on each of world `w`'s rigid bodies over the
    /// last step (zeros before the first), for every kind of body (the CPU backend's
    /// `rigid_loads`); waits for the last step.
    pub fn world_loads(&self, w: usize) -> Result<Vec<BodyLoad>, SimError> {
        if w >= self.worlds() {
            return Err(SimError::Backend(format!(
                "CUDA batch: no world {w} (the batch has {})",
                self.worlds()
            )));
        }
        match self.bodies.as_ref() {
            Some(b) => b.loads(w),
            None => Ok(Vec::new()),
        }
    }

    /// Every world's particles, in their own coordinates and material indices (read in
    /// original order, then cut into worlds on every core).
    pub fn read_worlds(&mut self) -> Result<Vec<Particles>, SimError> {
        use rayon::prelude::*;
        let mut all = Particles::default();
        self.backend.read_particles(&mut all)?;
        let (offsets, materials) = (&self.offsets, self.materials);
        Ok((0..self.worlds())
            .into_par_iter()
            .map(|w| world_of(&all, offsets, materials, w))
            .collect())
    }

    /// The world of particle `index` (original order) and its index in that world.
    pub fn world_of_particle(&self, index: usize) -> Option<(usize, usize)> {
        let w = self
            .offsets
            .partition_point(|&o| o <= index)
            .checked_sub(1)?;
        (w < self.worlds()).then(|| (w, index - self.offsets[w]))
    }

    /// The host's waits for the device so far, by reason ([`crate::waits`]): the batch's steps,
    /// puts, poses and reads.
    pub fn host_waits(&self) -> crate::waits::WaitCounts {
        self.backend.host_waits()
    }

    /// The first world with a bad particle (non-finite, or faster than two cells a step) since
    /// the last call, and that particle in its world; `None`: every world is healthy.
    pub fn bad_world(&mut self) -> Result<Option<(usize, BadParticle)>, SimError> {
        Ok(self.backend.check()?.and_then(|b| {
            self.world_of_particle(b.index).map(|(w, i)| {
                (
                    w,
                    BadParticle {
                        index: i,
                        reason: b.reason,
                        seen: b.seen,
                    },
                )
            })
        }))
    }
}

/// The batch as one backend: every world stepped by the same launches (one `dt` for all), its
/// health check over every world (the bad particle's index is over all worlds:
/// [`Worlds::world_of_particle`] says whose), its particles all worlds' in order.
impl Backend for CudaBatch {
    fn name(&self) -> String {
        format!("{}, {} worlds", self.backend.name(), self.worlds())
    }

    fn num_particles(&self) -> usize {
        self.backend.num_particles()
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        CudaBatch::step(self, dt, t)
    }

    /// Every world's bodies, world by world (the driver's CFL bound counts their speeds).
    fn rigid_bodies(&self) -> Vec<BodyState> {
        self.bodies.as_ref().map_or_else(Vec::new, |b| b.states())
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        self.backend.max_speed()
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        self.backend.check()
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        self.backend.read_particles(out)
    }

    fn cheap_check(&self) -> bool {
        self.backend.cheap_check()
    }

    fn stage_times(&self) -> Vec<(&'static str, f64)> {
        self.backend.stage_times()
    }

    fn memory_bytes(&self) -> Option<(u64, u64)> {
        self.backend.memory_bytes()
    }

    fn setup_details(&self) -> Option<String> {
        self.backend.setup_details()
    }

    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.backend.end_of_frame()
    }
}

impl Worlds for CudaBatch {
    fn worlds(&self) -> usize {
        CudaBatch::worlds(self)
    }

    fn read_worlds(&mut self) -> Result<Vec<Particles>, SimError> {
        CudaBatch::read_worlds(self)
    }

    fn put_world(&mut self, w: usize, particles: &Particles) -> Result<(), SimError> {
        CudaBatch::put_world(self, w, particles)
    }

    fn put_worlds(&mut self, worlds: &[(usize, &Particles)]) -> Result<(), SimError> {
        self.put_many(worlds)
    }

    fn put_initial(&mut self, worlds: &[usize]) -> Result<bool, SimError> {
        CudaBatch::put_initial(self, worlds)
    }

    fn save_point(&mut self) -> Result<bool, SimError> {
        CudaBatch::save_point(self)
    }

    /// The kept rigid-body poses put into their worlds ([`CudaBatch::set_body_poses`]).
    fn prepare_steps(&mut self) -> Result<(), SimError> {
        if crate::waits::old_waits() {
            return Ok(());
        }
        if let Some(b) = self.bodies.as_mut() {
            b.flush_kept();
        }
        Ok(())
    }

    fn save_next_point(&mut self) -> Result<bool, SimError> {
        CudaBatch::save_next_point(self)
    }

    fn use_next_point(&mut self) -> Result<(), SimError> {
        CudaBatch::use_next_point(self)
    }

    fn drop_queued_steps(&mut self) -> Result<(), SimError> {
        CudaBatch::drop_queued_steps(self)
    }

    fn queues_checks(&self) -> bool {
        self.backend.queues_checks()
    }

    /// The control words copied behind the steps queued ([`CudaBackend::queue_check`]).
    fn queue_check(&mut self) -> Result<bool, SimError> {
        self.backend.queue_check()
    }

    fn restore_point(&mut self) -> Result<(), SimError> {
        CudaBatch::restore_point(self)
    }

    fn world_of_particle(&self, index: usize) -> Option<(usize, usize)> {
        CudaBatch::world_of_particle(self, index)
    }

    fn world_rigid_poses(&self, w: usize) -> Vec<BodyPose> {
        self.world_poses(w)
    }

    fn set_world_rigid_poses(&mut self, w: usize, poses: &[BodyPose]) -> Result<(), SimError> {
        self.set_world_poses(w, poses)
    }

    fn world_rigid_poses_into(&self, w: usize, out: &mut Vec<BodyPose>) {
        self.world_poses_into(w, out)
    }

    /// From the bodies' rows under one lock (none: every world's empty).
    fn each_world_rigid_poses(&self, each: &mut dyn FnMut(usize, &[BodyPose])) {
        match self.bodies.as_ref() {
            Some(b) => b.each_poses(each),
            None => (0..self.worlds()).for_each(|w| each(w, &[])),
        }
    }

    fn set_body_poses(&mut self, body: usize, poses: &[(usize, BodyPose)]) -> Result<(), SimError> {
        CudaBatch::set_body_poses(self, body, poses)
    }

    fn world_rigid_loads(&self, w: usize) -> Result<Option<Vec<BodyLoad>>, SimError> {
        self.world_loads(w).map(Some)
    }
}

/// World `w`'s particles of `all` (every world's, in original order; world `w`'s from
/// `offsets[w]`), its material rows (`materials` a world) back to its own indices.
fn world_of(all: &Particles, offsets: &[usize], materials: usize, w: usize) -> Particles {
    let r = offsets[w]..offsets[w + 1];
    let k0 = (w * materials) as u32;
    Particles {
        x: all.x[r.clone()].to_vec(),
        v: all.v[r.clone()].to_vec(),
        c: all.c[r.clone()].to_vec(),
        f: all.f[r.clone()].to_vec(),
        plastic: all.plastic[r.clone()].to_vec(),
        mass: all.mass[r.clone()].to_vec(),
        vol0: all.vol0[r.clone()].to_vec(),
        material: all.material[r].iter().map(|k| k - k0).collect(),
    }
}

/// The scene the kernels run: world 0's, with every world's materials (rows `w * m ..` are
/// world `w`'s) and the strongest world's gravity (the driver's gravity bound on the step).
fn merged_scene(worlds: &[Scene]) -> Scene {
    let mut merged = worlds[0].clone();
    merged.materials = worlds.iter().flat_map(|s| s.materials.clone()).collect();
    merged.gravity = worlds.iter().map(|s| s.gravity).fold(Vec3::ZERO, |a, g| {
        if g.length() > a.length() { g } else { a }
    });
    merged
}

/// The worlds' rigid bodies on `backend` (built for the merged scene, world 0's bodies): the
/// single run's bodies it made are dropped (their mesh offsets kept: the mesh table is world
/// 0's, which every world shares) and every world's take their place in the kernels' `Ctx`.
fn world_bodies(
    backend: &mut CudaBackend,
    worlds: &[Scene],
) -> Result<Option<bodies::WorldBodies>, SimError> {
    let Some(single) = backend.bodies.take() else {
        return Ok(None);
    };
    let mesh_offsets = single.mesh_offsets();
    drop(single);
    let o = &backend.options;
    let lazy = (o.batch_sums_at_read, o.batch_poses, o.batch_body_turns);
    let waits = backend.waits.clone();
    let made = bodies::WorldBodies::new(worlds, &backend.stream, mesh_offsets, lazy, waits)?;
    if let Some(b) = &made {
        let c = &mut backend.ctx;
        (c.bodies, c.body_exchange, c.n_bodies) = b.ctx_fields(&backend.stream, 0);
    }
    Ok(made)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_world_stride_leaves_the_gap_past_every_node_a_world_touches() {
        for n in [1usize, 7, 16, 32, 63, 64, 100, 1000] {
            let s = world_stride(n);
            assert_eq!(s % 4, 0, "stride {s} is whole blocks");
            // The last node a world can touch, from its stripe's start, then the next world's
            // first (WORLD_ORIGIN_CELLS - 4 into its stripe).
            let last = WORLD_ORIGIN_CELLS + n + 11;
            let next_first = s + WORLD_ORIGIN_CELLS - 4;
            assert!(next_first - last > WORLD_GAP_CELLS, "n = {n}, stride {s}");
            assert!(last < s, "n = {n}: a world's nodes stay in its stripe");
        }
    }
}
