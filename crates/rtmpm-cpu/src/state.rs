//! The CPU backend's state: the step's constants, the particles in storage order, the grid and
//! the layout of the current step.

use crate::collider::Collider;
use physics::boundary::Walls;
use physics::grid::BlockLayout;
use physics::material::Material;
use physics::math::{IVec3, Real, Vec3};
use physics::transfer::{SolverSettings, Transfer, Update};
use physics::{Particles, real};
use rtmpm_scene::Scene;
use rtmpm_sim as sim;
use rtmpm_sim::{BadParticle, SimError};

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
            walls: physics::convert::walls(&scene.walls),
            damping: scene.time.damping,
            colliders: scene.colliders.iter().map(Collider::new).collect(),
            tool: None,
            materials: physics::convert::materials(&scene.materials).map_err(SimError::Backend)?,
            solver: scene.solver,
        })
    }
}

/// Grid node: mass, then momentum (after P2G) or velocity (after the grid update).
pub type Node = [Real; 4];

/// Spare arrays of the storage re-sort: one per element type of the particle state.
#[derive(Default)]
pub(crate) struct Scratch {
    pub(crate) vec3: Vec<Vec3>,
    pub(crate) mat3: Vec<physics::math::Mat3>,
    pub(crate) real: Vec<Real>,
    pub(crate) word: Vec<u32>,
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
    pub(crate) scratch: Scratch,
    /// Steps since the storage was last re-sorted ([`crate::rebuild::RESORT_EVERY`]).
    pub(crate) since_sort: u32,
    /// Block layout of the current step.
    pub layout: BlockLayout,
    /// Stencil base node of each particle (grid indices).
    pub bases: Vec<IVec3>,
    /// Node storage, 64 nodes per pblock.
    pub grid: Vec<Node>,
    /// CK-MPM's second grid (nodes a quarter cell above the B-spline grid's, `grid` holding the
    /// one a quarter cell below), in `grid`'s layout; empty for the other transfers.
    pub grid_dual: Vec<Node>,
    /// Second value per node, used by the classic MPM transfers only (empty for MLS): the
    /// internal force times dt after P2G, the velocity before the update (`v_old`, for FLIP) after
    /// the grid update, and the re-mapped velocity after the MUSL re-map.
    pub grid_aux: Vec<Vec3>,
    /// gblocks of each of the 8 colours `(bx & 1, by & 1, bz & 1)`.
    pub colours: [Vec<u32>; 8],
    /// Accumulated wall time of each stage: rebuild, p2g, grid update, g2p (seconds).
    pub stage_seconds: [f64; 4],
    pub(crate) pool: Option<rayon::ThreadPool>,
    pub(crate) max_speed: Real,
    pub(crate) bad: Option<BadParticle>,
    /// The rigid bodies coupled to the grid (`[[rigid_body]]`), if any.
    pub rigid: Option<rtmpm_rigid::RigidWorld>,
    /// What the grid gave each rigid body in the last step, and that step's dt (s).
    pub(crate) last_exchange: (Vec<rtmpm_rigid::Exchange>, f64),
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
        if !scene.rigid_bodies.is_empty() && scene.solver.transfer == Transfer::CkMpm {
            return Err(SimError::Backend(
                "rigid bodies are not coupled to CK-MPM's two grids yet: use [solver] transfer = \
                 \"mls\" (the default) with [[rigid_body]] tables"
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
            && (n == 0 || n > MAX_THREADS)
        {
            let what = if n == 0 {
                "0 CPU threads cannot step".to_string()
            } else {
                format!("{n} CPU threads is more than the {MAX_THREADS} allowed")
            };
            return Err(SimError::Backend(format!(
                "{what}; give --threads 1 to {MAX_THREADS} (or leave it out: one per core)"
            )));
        }
        let particles = physics::convert::particles(particles);
        let pool = match threads {
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
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
            grid_dual: Vec::new(),
            grid_aux: Vec::new(),
            colours: Default::default(),
            stage_seconds: [0.0; 4],
            pool,
            max_speed,
            bad: None,
            rigid: None,
            last_exchange: (Vec::new(), 0.0),
        })
    }

    /// Number of worker threads in use.
    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    /// Overwrite the columns `edit` gives (positions, velocities, APIC's C, F) of every
    /// particle, given in original order in the interface's f32 (widened exactly in f64),
    /// keeping the rest of each particle's state. The next step rebuilds the layout from new
    /// positions (the CPU rebuilds every step); the CFL speed is taken from new velocities.
    pub fn set_fields(&mut self, edit: &sim::ParticleEdit) -> Result<(), SimError> {
        edit.check_lengths(self.particles.len())?;
        let p = &mut self.particles;
        for (i, &id) in self.ids.iter().enumerate() {
            let id = id as usize;
            if let Some(x) = edit.x {
                p.x[i] = real::vec3(x[id]);
            }
            if let Some(v) = edit.v {
                p.v[i] = real::vec3(v[id]);
            }
            if let Some(c) = edit.c {
                p.c[i] = real::mat3(c[id]);
            }
            if let Some(f) = edit.f {
                p.f[i] = real::mat3(f[id]);
            }
        }
        // New positions: re-sort the storage at the next step.
        if edit.x.is_some() {
            self.since_sort = u32::MAX;
        }
        if edit.v.is_some() {
            self.max_speed = p.v.iter().map(|v| v.length()).fold(0.0, Real::max);
        }
        Ok(())
    }
}
