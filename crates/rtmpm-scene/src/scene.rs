//! A validated scene ([`Scene`]) and its bodies.

use crate::emitter::Emitter;
use crate::render_settings::RenderSettings;
use crate::settings::{OutputSettings, ParticleState, Precision, Sampling, TimeSettings};
use rtmpm_geometry::Collider;
use rtmpm_physics::boundary::Walls;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use rtmpm_physics::transfer::SolverSettings;
use std::path::PathBuf;

/// A body of material to be filled with particles (kept for `rtmpm check` summaries).
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    pub material: u32,
    pub shape: rtmpm_geometry::Shape,
    /// Requested particles per cell (regular/jittered use `round(cbrt(ppc))^3`).
    pub particles_per_cell: u32,
    /// True for jittered sampling (kept for compatibility; see `sampling`).
    pub jitter: bool,
    pub sampling: Sampling,
    /// Exact particle count for random sampling (else `ppc * volume / dx^3`).
    pub count: Option<u64>,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    /// A body made of a file's particles keeps the file's velocities (it gives neither
    /// `velocity` nor `angular_velocity`).
    pub file_velocity: bool,
}

/// A validated scene, identical for every backend.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    /// The file it came from, if any.
    pub source: Option<PathBuf>,
    pub domain_min: Vec3,
    pub domain_max: Vec3,
    /// Grid spacing (m).
    pub dx: f32,
    pub gravity: Vec3,
    pub time: TimeSettings,
    pub materials: Vec<Material>,
    pub bodies: Vec<Body>,
    pub colliders: Vec<Collider>,
    /// Particles that appear while the run goes on (`[[emitter]]`).
    pub emitters: Vec<Emitter>,
    /// Rigid bodies coupled two ways to the material (`[[rigid_body]]`).
    pub rigid_bodies: Vec<rtmpm_rigid::RigidBodySpec>,
    /// Joints holding rigid bodies to the world or to each other (`[[joint]]`).
    pub joints: Vec<rtmpm_rigid::JointSpec>,
    pub walls: Walls,
    pub output: OutputSettings,
    /// `[render]` table (camera, image size, colouring).
    pub render: RenderSettings,
    /// Seed of the jittered sampling.
    pub seed: u64,
    /// `[solver]` table: particle-grid transfer, stress update, FLIP fraction.
    pub solver: SolverSettings,
    /// Floating-point precision of the step (`[solver] precision`).
    pub precision: Precision,
    /// The CUDA backend's particle state format (`[solver] particle_state`).
    pub particle_state: ParticleState,
    /// The files the scene read (meshes, particle files) and their hashes.
    pub files: Vec<crate::files::SceneFile>,
}

impl Scene {
    /// The files the scene read with their hashes, as a checkpoint stores them.
    pub fn file_hashes(&self) -> Vec<rtmpm_io::checkpoint::FileHash> {
        self.files
            .iter()
            .filter_map(|f| {
                Some(rtmpm_io::checkpoint::FileHash {
                    field: f.field.clone(),
                    path: f.path.display().to_string(),
                    hash: f.hash?,
                })
            })
            .collect()
    }

    /// Check a checkpoint's state against this scene before resuming it (see
    /// `Checkpoint::check_fits`).
    pub fn check_checkpoint(
        &self,
        ckpt: &rtmpm_io::checkpoint::Checkpoint,
    ) -> Result<(), rtmpm_io::checkpoint::CheckpointError> {
        ckpt.check_fits(&rtmpm_io::checkpoint::ResumedScene {
            domain_min: self.domain_min,
            domain_max: self.domain_max,
            dx: self.dx,
            materials: self.materials.len(),
            rigid_bodies: self.rigid_bodies.iter().map(|b| b.name.clone()).collect(),
        })
    }

    /// Number of cells along each axis.
    pub fn n_cells(&self) -> [u32; 3] {
        let n = (self.domain_max - self.domain_min) / self.dx;
        [n.x.round() as u32, n.y.round() as u32, n.z.round() as u32]
    }

    /// The box bodies must lie in: the domain minus the walls.
    pub fn interior(&self) -> (Vec3, Vec3) {
        let w = self.walls.thickness as f32 * self.dx;
        (self.domain_min + w, self.domain_max - w)
    }
}
