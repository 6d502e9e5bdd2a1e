//! The CPU reference backend: explicit MLS-MPM (APIC, quadratic B-splines) or, per scene, the
//! classic MPM transfers (uGIMP or linear hats, USL or MUSL, PIC/FLIP; see [`physics::transfer`]),
//! parallel with rayon and deterministic: the same scene gives the same result bit for bit
//! whatever the number of threads. Every quantity of the step is a [`Real`]: f32 in the package
//! `rtmpm-cpu`, f64 in the package `rtmpm-cpu-f64`, which compiles these same files with its
//! feature `f64` against `rtmpm-physics-f64` (both name their physics dependency `physics`; see
//! [`physics::real`]).
//!
//! One step is four stages, each in its own file (MUSL adds a re-map: `g2p_mpm_velocity`,
//! `p2g_musl`, `grid_update_musl` before the final G2P):
//! 1. [`rebuild`]: stencil base of every particle, block layout (sorted block codes, gblocks,
//!    pblocks, 3x3x3 neighbour lists) and the particle order (sorted by block, then cell), all in
//!    parallel. The CPU rebuilds every step (the free zone that avoids it is a GPU optimisation)
//!    and re-sorts the particle storage every [`rebuild::RESORT_EVERY`] steps.
//! 2. [`p2g`]: particle to grid, scattered block by block in 8 colour passes (no atomics).
//! 3. [`grid_update`]: momentum to velocity, gravity, walls and colliders.
//! 4. [`g2p`]: grid to particle, deformation update, plasticity, advection, health check.

// Statistics are widened to f64 with `as f64`, a no-op in the f64 package.
#![cfg_attr(feature = "f64", allow(clippy::unnecessary_cast))]

mod collider;
pub mod g2p;
pub mod grid_update;
pub mod p2g;
pub mod rebuild;
// Written for f32 (step constants and particles built by hand); the f64 package is checked
// against this one by its tests/precision.rs.
#[cfg(all(test, not(feature = "f64")))]
mod tests;
#[cfg(all(test, not(feature = "f64")))]
mod tests_steer;

pub use collider::Collider;
use physics::boundary::Walls;
use physics::grid::BlockLayout;
use physics::material::Material;
use physics::math::{IVec3, Real, Vec3};
use physics::transfer::{SolverSettings, Transfer, Update};
use physics::{Particles, real};
use rtmpm_scene::Scene;
use rtmpm_sim as sim;
use rtmpm_sim::{Backend, BadParticle, SimError};

/// Grid nodes of padding below the domain's min corner (one block), so indices stay non-negative.
pub const GRID_PAD: i32 = 4;

/// Most worker threads a CPU backend starts (`--threads`).
pub const MAX_THREADS: usize = 1024;

/// Read-only per-scene constants of a step.
#[derive(Clone, Debug)]
pub struct StepConstants {
    pub dx: Real,
    pub inv_dx: Real,
    /// World position of grid node (0, 0, 0): the domain's min corner minus [`GRID_PAD`] cells.
    pub origin: Vec3,
    pub domain_min: Vec3,
    pub domain_max: Vec3,
    pub n_cells: [u32; 3],
    pub gravity: Vec3,
    pub walls: Walls,
    /// Settling damping of the grid velocities.
    pub damping: rtmpm_scene::Damping,
    pub colliders: Vec<Collider>,
    /// The user's tool of a live view ([`Backend::set_tool`]), after the colliders.
    pub tool: Option<rtmpm_geometry::Tool>,
    pub materials: Vec<Material>,
    /// Particle-grid transfer (`[solver]`).
    pub solver: SolverSettings,
}

impl StepConstants {
    /// Constants of a scene.
    pub fn from_scene(scene: &Scene) -> Result<StepConstants, SimError> {
        Ok(StepConstants {
            dx: real::real(scene.dx),
            inv_dx: 1.0 / real::real(scene.dx),
            origin: real::vec3(scene.domain_min)
                - Vec3::splat(GRID_PAD as Real * real::real(scene.dx)),
            domain_min: real::vec3(scene.domain_min),
            domain_max: real::vec3(scene.domain_max),
            n_cells: scene.n_cells(),
            gravity: real::vec3(scene.gravity),
            walls: real::walls(&scene.walls),
            damping: scene.time.damping,
            colliders: scene.colliders.iter().map(Collider::new).collect(),
            tool: None,
            materials: real::materials(&scene.materials).map_err(SimError::Backend)?,
            solver: scene.solver,
        })
    }
}

/// Grid node: mass, then momentum (after P2G) or velocity (after the grid update).
pub type Node = [Real; 4];

/// Spare arrays of the storage re-sort: one per element type of the particle state.
#[derive(Default)]
struct Scratch {
    vec3: Vec<Vec3>,
    mat3: Vec<physics::math::Mat3>,
    real: Vec<Real>,
    word: Vec<u32>,
}

/// The CPU backend's state.
pub struct CpuBackend {
    pub consts: StepConstants,
    /// Particle state in storage order: sorted by block and cell at every rebuild, so that P2G
    /// and G2P walk memory in order. `ids[i]` is the original index of stored particle `i`.
    pub particles: Particles,
    /// Original index of each stored particle.
    pub ids: Vec<u32>,
    /// One spare array per element type, for re-sorting the storage.
    scratch: Scratch,
    /// Steps since the storage was last re-sorted ([`rebuild::RESORT_EVERY`]).
    since_sort: u32,
    /// Block layout of the current step.
    pub layout: BlockLayout,
    /// Stencil base node of each particle (grid indices).
    pub bases: Vec<IVec3>,
    /// Node storage, 64 nodes per pblock.
    pub grid: Vec<Node>,
    /// Second value per node, used by the classic MPM transfers only (empty for MLS): the
    /// internal force times dt after P2G, the velocity before the update (`v_old`, for FLIP) after
    /// the grid update, and the re-mapped velocity after the MUSL re-map.
    pub grid_aux: Vec<Vec3>,
    /// gblocks of each of the 8 colours `(bx & 1, by & 1, bz & 1)`.
    pub colours: [Vec<u32>; 8],
    /// Accumulated wall time of each stage: rebuild, p2g, grid update, g2p (seconds).
    pub stage_seconds: [f64; 4],
    pool: Option<rayon::ThreadPool>,
    max_speed: Real,
    bad: Option<BadParticle>,
    /// The rigid bodies coupled to the grid (`[[rigid_body]]`), if any.
    pub rigid: Option<rtmpm_rigid::RigidWorld>,
}

impl CpuBackend {
    /// A backend for `scene` starting from `particles` (converted to [`Real`]); `threads` fixes
    /// the number of worker threads (None: rayon's default, one per core).
    pub fn new(
        scene: &Scene,
        particles: sim::Particles,
        threads: Option<usize>,
    ) -> Result<Self, SimError> {
        let mut b = Self::from_constants(StepConstants::from_scene(scene)?, particles, threads)?;
        if !scene.rigid_bodies.is_empty() && scene.solver.update == Update::Musl {
            return Err(SimError::Backend(
                "rigid bodies are coupled in the grid update of USL steps: use [solver] update = \
                 \"usl\" with [[rigid_body]] tables"
                    .into(),
            ));
        }
        b.rigid = rtmpm_rigid::RigidWorld::new(
            &scene.rigid_bodies,
            &scene.joints,
            scene.gravity,
            scene.interior(),
        )
        .map_err(SimError::Backend)?;
        Ok(b)
    }

    /// A backend from explicit step constants (tests, benchmarks).
    pub fn from_constants(
        consts: StepConstants,
        particles: sim::Particles,
        threads: Option<usize>,
    ) -> Result<Self, SimError> {
        if let Some(n) = threads
            && n > MAX_THREADS
        {
            return Err(SimError::Backend(format!(
                "{n} CPU threads is more than the {MAX_THREADS} allowed; give --threads 1 to \
                 {MAX_THREADS} (default: one per core)"
            )));
        }
        let particles = real::particles(particles);
        let pool = match threads {
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n.max(1))
                    .build()
                    .map_err(|e| SimError::Backend(format!("cannot start {n} CPU threads: {e}")))?,
            ),
            None => None,
        };
        let max_speed = particles.v.iter().map(|v| v.length()).fold(0.0, Real::max);
        Ok(CpuBackend {
            consts,
            ids: (0..particles.len() as u32).collect(),
            particles,
            scratch: Scratch::default(),
            since_sort: u32::MAX,
            layout: BlockLayout::default(),
            bases: Vec::new(),
            grid: Vec::new(),
            grid_aux: Vec::new(),
            colours: Default::default(),
            stage_seconds: [0.0; 4],
            pool,
            max_speed,
            bad: None,
            rigid: None,
        })
    }

    /// Number of worker threads in use.
    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    /// Overwrite the positions and/or the velocities of every particle, given in original order
    /// in the interface's f32 (widened exactly in f64), keeping the rest of each particle's
    /// state. The next step rebuilds the layout from the new positions (the CPU rebuilds every
    /// step); the CFL speed is taken from the new velocities.
    pub fn set_x_v(
        &mut self,
        x: Option<&[glam::Vec3]>,
        v: Option<&[glam::Vec3]>,
    ) -> Result<(), SimError> {
        let n = self.particles.len();
        for (what, a) in [("positions", x), ("velocities", v)] {
            if let Some(a) = a
                && a.len() != n
            {
                return Err(SimError::Backend(format!(
                    "{} {what} given for {n} particles",
                    a.len()
                )));
            }
        }
        for (i, &id) in self.ids.iter().enumerate() {
            if let Some(x) = x {
                self.particles.x[i] = real::vec3(x[id as usize]);
            }
            if let Some(v) = v {
                self.particles.v[i] = real::vec3(v[id as usize]);
            }
        }
        // New positions: re-sort the storage at the next step.
        if x.is_some() {
            self.since_sort = u32::MAX;
        }
        if v.is_some() {
            self.max_speed = self
                .particles
                .v
                .iter()
                .map(|v| v.length())
                .fold(0.0, Real::max);
        }
        Ok(())
    }

    /// Give the rigid bodies the step's impulses and advance them by `dt` (their new pose is
    /// the next step's boundary).
    fn advance_bodies(&mut self, exchange: &[rtmpm_rigid::Exchange], dt: Real) {
        if let Some(w) = self.rigid.as_mut() {
            w.advance(exchange, real::to_f32(dt));
        }
    }

    fn step_inner(&mut self, dt: Real, t: f32) {
        let t0 = std::time::Instant::now();
        rebuild::rebuild(self);
        let t1 = std::time::Instant::now();
        let solver = self.consts.solver;
        let (max_speed, bad, t2, t3);
        if solver.transfer == Transfer::Mls {
            p2g::p2g(self, dt);
            t2 = std::time::Instant::now();
            let exchange = grid_update::grid_update(self, dt, t);
            self.advance_bodies(&exchange, dt);
            t3 = std::time::Instant::now();
            (max_speed, bad) = g2p::g2p(self, dt);
        } else {
            p2g::p2g_mpm(self, dt);
            t2 = std::time::Instant::now();
            let exchange = grid_update::grid_update(self, dt, t);
            self.advance_bodies(&exchange, dt);
            t3 = std::time::Instant::now();
            let musl = solver.update == Update::Musl;
            if musl {
                // MUSL (Sulsky et al. 1995): new particle velocities, their momenta mapped to
                // the grid again, then the velocity gradient from that grid.
                g2p::g2p_mpm_velocity(self);
                p2g::p2g_musl(self);
                grid_update::grid_update_musl(self, t);
            }
            (max_speed, bad) = g2p::g2p_mpm(self, dt, musl);
        }
        let t4 = std::time::Instant::now();
        for (acc, (a, b)) in
            self.stage_seconds
                .iter_mut()
                .zip([(t0, t1), (t1, t2), (t2, t3), (t3, t4)])
        {
            *acc += (b - a).as_secs_f64();
        }
        self.max_speed = max_speed;
        if self.bad.is_none() {
            self.bad = bad;
        }
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> String {
        match real::PRECISION {
            "f32" => format!("cpu ({} threads)", self.threads()),
            p => format!("cpu ({} threads, {p})", self.threads()),
        }
    }

    fn num_particles(&self) -> usize {
        self.particles.len()
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let dt = real::real(dt);
        match self.pool.take() {
            Some(pool) => {
                pool.install(|| self.step_inner(dt, t));
                self.pool = Some(pool);
            }
            None => self.step_inner(dt, t),
        }
        Ok(())
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        Ok(real::to_f32(self.max_speed))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        Ok(self.bad)
    }

    fn read_particles(&mut self, out: &mut sim::Particles) -> Result<(), SimError> {
        // Back to the original order, and to the interface's f32.
        let p = &self.particles;
        let n = p.len();
        out.x.resize(n, Default::default());
        out.v.resize(n, Default::default());
        out.c.resize(n, Default::default());
        out.f.resize(n, Default::default());
        out.plastic.resize(n, 0.0);
        out.mass.resize(n, 0.0);
        out.vol0.resize(n, 0.0);
        out.material.resize(n, 0);
        for (i, &id) in self.ids.iter().enumerate() {
            let id = id as usize;
            out.x[id] = real::vec3_to_f32(p.x[i]);
            out.v[id] = real::vec3_to_f32(p.v[i]);
            out.c[id] = real::mat3_to_f32(p.c[i]);
            out.f[id] = real::mat3_to_f32(p.f[i]);
            out.plastic[id] = real::to_f32(p.plastic[i]);
            out.mass[id] = real::to_f32(p.mass[i]);
            out.vol0[id] = real::to_f32(p.vol0[i]);
            out.material[id] = p.material[i];
        }
        Ok(())
    }

    fn export_frame(&mut self, sink: &mut dyn sim::ChunkSink) -> Result<(), SimError> {
        // Gathered chunk by chunk through the inverse of the storage order (4 bytes a particle)
        // rather than a copy of every particle.
        let slot = sim::invert_ids(&self.ids)?;
        let p = &self.particles;
        sim::fill_chunks(slot.len(), sink, |id, cols| {
            let i = slot[id] as usize;
            let mut r = rtmpm_io::chunks::ParticleRow {
                x: real::vec3_to_f32(p.x[i]).to_array(),
                ..Default::default()
            };
            if cols.v {
                r.v = real::vec3_to_f32(p.v[i]).to_array();
            }
            if cols.material {
                r.material = p.material[i];
            }
            if cols.plastic {
                r.plastic = real::to_f32(p.plastic[i]);
            }
            if cols.mass {
                r.mass = real::to_f32(p.mass[i]);
            }
            if cols.vol0 {
                r.vol0 = real::to_f32(p.vol0[i]);
            }
            if cols.f {
                r.f = real::mat3_to_f32(p.f[i]).to_cols_array();
            }
            if cols.c {
                r.c = real::mat3_to_f32(p.c[i]).to_cols_array();
            }
            r
        })
    }

    fn cheap_check(&self) -> bool {
        true
    }

    fn memory_bytes(&self) -> Option<(u64, u64)> {
        fn cap<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let (p, s) = (&self.particles, &self.scratch);
        let bytes = cap(&p.x)
            + cap(&p.v)
            + cap(&p.c)
            + cap(&p.f)
            + cap(&p.plastic)
            + cap(&p.mass)
            + cap(&p.vol0)
            + cap(&p.material)
            + cap(&self.ids)
            + cap(&s.vec3)
            + cap(&s.mat3)
            + cap(&s.real)
            + cap(&s.word)
            + cap(&self.bases)
            + cap(&self.grid)
            + cap(&self.grid_aux)
            + self.colours.iter().map(cap).sum::<usize>()
            + self.layout.memory_bytes();
        Some((bytes as u64, 0))
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        self.rigid
            .as_ref()
            .map_or_else(Vec::new, |w| w.states().to_vec())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        self.rigid.as_ref().map_or_else(Vec::new, |w| w.poses())
    }

    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        match self.rigid.as_mut() {
            Some(w) => w.set_poses(poses).map_err(SimError::Backend),
            None if poses.is_empty() => Ok(()),
            None => Err(SimError::Backend(format!(
                "{} rigid-body states for a scene without rigid bodies",
                poses.len()
            ))),
        }
    }

    fn add_particles(&mut self, p: &sim::Particles) -> Result<(), SimError> {
        // The next original indices; the next step's rebuild sorts them in.
        let first = self.ids.len();
        if first + p.len() > u32::MAX as usize {
            return Err(SimError::Backend(format!(
                "{} particles exceed the CPU backend's 2^32 - 1 (emitters): lower their rates",
                first + p.len()
            )));
        }
        let add = real::particles(p.clone());
        let fastest = add.v.iter().map(|v| v.length()).fold(0.0, Real::max);
        self.max_speed = self.max_speed.max(fastest);
        self.particles.extend(&add);
        self.ids.extend(first as u32..(first + p.len()) as u32);
        // Stored at the end: re-sort the storage at the next step (locality only; P2G's sum
        // order comes from the layout, whatever the storage order).
        self.since_sort = u32::MAX;
        Ok(())
    }

    fn set_gravity(&mut self, gravity: glam::Vec3) -> Result<(), SimError> {
        if !gravity.is_finite() {
            return Err(SimError::Backend(format!(
                "gravity must be finite, got {gravity}"
            )));
        }
        self.consts.gravity = real::vec3(gravity);
        if let Some(w) = self.rigid.as_mut() {
            w.set_gravity(gravity);
        }
        Ok(())
    }

    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        if let Some(t) = &tool {
            t.check().map_err(SimError::Backend)?;
        }
        self.consts.tool = tool;
        Ok(())
    }

    fn stage_times(&self) -> Vec<(&'static str, f64)> {
        ["rebuild", "p2g", "grid_update", "g2p"]
            .into_iter()
            .zip(self.stage_seconds)
            .collect()
    }
}
