//! Scene files (TOML): schema, validation with precise error messages, and particle sampling.
//!
//! The schema is documented in `docs/scene-format.md`. (Parser: stub, to be implemented.)

pub mod error;
pub mod sampling;

pub use error::SceneError;

use crate::boundary::{Collider, Walls};
use crate::material::Material;
use crate::math::Vec3;
use std::path::{Path, PathBuf};

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepMode {
    /// Fixed dt (s).
    Fixed { dt: f32 },
    /// `dt = min(max_dt, cfl * dx / (max particle speed + max sound speed))`.
    Cfl { cfl: f32, max_dt: f32 },
}

/// Simulated time and frame rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSettings {
    /// Simulated duration (s).
    pub duration: f32,
    /// Output frames per second of simulated time.
    pub fps: f32,
    pub step: StepMode,
}

impl TimeSettings {
    /// Number of frames the duration holds (rounded to the nearest whole frame, at least 1).
    pub fn frames(&self) -> u64 {
        ((self.duration * self.fps).round() as u64).max(1)
    }
}

/// What is written per frame.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputSettings {
    /// Output folder (relative paths are relative to the working directory).
    pub dir: PathBuf,
    pub ply: bool,
    pub vtu: bool,
    /// Also write the Cauchy stress (6 components) per particle.
    pub stress: bool,
    /// Also write the volume ratio J per particle.
    pub jacobian: bool,
}

/// A body of material to be filled with particles (kept for `rtmpm check` summaries).
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    pub material: u32,
    pub shape: sampling::BodyShape,
    pub particles_per_cell: u32,
    pub jitter: bool,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
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
    pub walls: Walls,
    pub output: OutputSettings,
    /// Seed of the jittered sampling.
    pub seed: u64,
}

impl Scene {
    /// Read and validate a scene file.
    pub fn from_file(_path: &Path) -> Result<Scene, SceneError> {
        todo!()
    }

    /// Parse and validate scene text; `origin` names it in error messages.
    pub fn from_toml(_text: &str, _origin: &str) -> Result<Scene, SceneError> {
        todo!()
    }

    /// Number of cells along each axis.
    pub fn n_cells(&self) -> [u32; 3] {
        let n = (self.domain_max - self.domain_min) / self.dx;
        [n.x.round() as u32, n.y.round() as u32, n.z.round() as u32]
    }

    /// Fill the bodies with particles (deterministic for a given seed).
    pub fn sample_particles(&self) -> Result<crate::Particles, SceneError> {
        sampling::sample_scene(self)
    }
}
