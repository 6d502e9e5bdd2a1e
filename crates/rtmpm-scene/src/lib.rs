//! Scene files (TOML): schema, validation with precise error messages, and particle sampling.
//!
//! The schema is documented in `docs/scene-format.md`. [`Scene::from_file`] /
//! [`Scene::from_toml`] parse the text with serde into the raw structs of [`schema`] (unknown
//! fields rejected), then [`validate`] checks and resolves them. Every error names the field
//! path (e.g. `material[1].poisson_ratio`), its line and column, and a hint.

// `SceneError` is deliberately rich (position, field, hint); it is only built on failure.
#![allow(clippy::result_large_err)]

pub mod budget;
pub mod deferred;
pub mod emitter;
pub mod error;
mod fill;
pub mod pcg;
mod render_settings;
pub mod sampling;
pub mod schema;
pub mod spans;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_io;
#[cfg(test)]
mod tests_motion;
#[cfg(test)]
mod tests_rigid_mesh;
#[cfg(test)]
mod tests_sampling;
mod validate;
mod walk;

pub use budget::Budget;
pub use error::SceneError;
pub use render_settings::{ColorBy, RenderSettings};
pub use sampling::Sampling;
pub use spans::span_of;

use rtmpm_geometry::Collider;
use rtmpm_physics::boundary::Walls;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use rtmpm_physics::transfer::SolverSettings;
use std::path::{Path, PathBuf};

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepMode {
    /// Fixed dt (s).
    Fixed { dt: f32 },
    /// `dt = min(max_dt, cfl * dx / (max particle speed + max sound speed))`; a step below
    /// `min_dt` stops the run (the CFL step collapsed: a particle far faster than sound).
    Cfl { cfl: f32, max_dt: f32, min_dt: f32 },
}

/// Simulated time and frame rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSettings {
    /// Simulated duration (s).
    pub duration: f32,
    /// Output frames per second of simulated time.
    pub fps: f32,
    pub step: StepMode,
    /// Velocity damping for settling a scene into equilibrium (off by default).
    pub damping: Damping,
}

/// Global velocity damping for settling: every step, while `t < until`, the grid velocities are
/// multiplied by `max(0, 1 - rate dt)` (a viscous drag `-rate v` per unit mass). At rest it
/// exerts no force, so a static equilibrium reached under it is the undamped one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Damping {
    /// Damping rate (1/s); 0 = off.
    pub rate: f32,
    /// Damping acts while the step starts before this time (s).
    pub until: f32,
}

impl Default for Damping {
    fn default() -> Self {
        Damping {
            rate: 0.0,
            until: f32::INFINITY,
        }
    }
}

impl Damping {
    /// Factor on the grid velocities of the step of length `dt` starting at time `t`.
    pub fn factor(&self, dt: f32, t: f32) -> f32 {
        if self.rate > 0.0 && t < self.until {
            (1.0 - self.rate * dt).max(0.0)
        } else {
            1.0
        }
    }
}

impl TimeSettings {
    /// Number of frames the duration holds (rounded to the nearest whole frame, at least 1).
    pub fn frames(&self) -> u64 {
        ((self.duration * self.fps).round() as u64).max(1)
    }
}

/// What is written per frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OutputSettings {
    /// Output folder (relative paths are relative to the working directory).
    pub dir: PathBuf,
    pub ply: bool,
    pub vtu: bool,
    /// Houdini's classic `.bgeo` per frame.
    pub bgeo: bool,
    /// The same, gzip-compressed (`.bgeo.gz`).
    pub bgeo_gz: bool,
    /// USD text (`.usda`) per frame.
    pub usda: bool,
    /// Also write the Cauchy stress per particle.
    pub stress: bool,
    /// Also write the volume ratio J per particle.
    pub jacobian: bool,
    /// zlib-compress the arrays of `.vtu` files (default on).
    pub compress: bool,
    /// Surface mesh files per frame (`[output] surface`); all false: none.
    pub surface_formats: MeshFormats,
    /// How surfaces are reconstructed (`[surface]`).
    pub surface: SurfaceSettings,
}

/// Which surface mesh files are written per frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshFormats {
    pub obj: bool,
    pub ply: bool,
    pub vtu: bool,
    pub usda: bool,
}

impl MeshFormats {
    /// True when any format is on.
    pub fn any(&self) -> bool {
        self.obj || self.ply || self.vtu || self.usda
    }
}

/// `[surface]`: which materials form the surface and how it is reconstructed (see
/// [`rtmpm_geometry::surface::SurfaceParams`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceSettings {
    /// Material indices whose particles are meshed (default: every fluid).
    pub materials: Vec<u32>,
    /// SPH smoothing length, in particle radii.
    pub smoothing_length: f32,
    /// Marching-cubes cell edge, in particle radii.
    pub cube_size: f32,
    /// Iso-surface as a fraction of the rest density.
    pub threshold: f32,
    /// Laplacian smoothing iterations of the vertices.
    pub smoothing_iters: u32,
    /// Smoothing iterations of the normals.
    pub normal_smoothing_iters: u32,
}

impl Default for SurfaceSettings {
    fn default() -> Self {
        let p = rtmpm_geometry::surface::SurfaceParams::for_volume(1.0);
        SurfaceSettings {
            materials: Vec::new(),
            smoothing_length: p.smoothing_length,
            cube_size: p.cube_size,
            threshold: p.threshold,
            smoothing_iters: p.smoothing_iters,
            normal_smoothing_iters: p.normal_smoothing_iters,
        }
    }
}

impl SurfaceSettings {
    /// The reconstruction parameters for particles of mean volume `volume` (m^3).
    pub fn params(&self, volume: f32) -> rtmpm_geometry::surface::SurfaceParams {
        rtmpm_geometry::surface::SurfaceParams {
            particle_radius: rtmpm_geometry::surface::radius_of_volume(volume),
            smoothing_length: self.smoothing_length,
            cube_size: self.cube_size,
            threshold: self.threshold,
            smoothing_iters: self.smoothing_iters,
            normal_smoothing_iters: self.normal_smoothing_iters,
        }
    }

    /// Positions and mean initial volume of the particles that form the surface.
    pub fn select(&self, p: &rtmpm_physics::Particles) -> (Vec<Vec3>, f32) {
        let mut vol = 0.0f64;
        let xs: Vec<Vec3> = (0..p.len())
            .filter(|&i| self.materials.contains(&p.material[i]))
            .map(|i| {
                vol += p.vol0[i] as f64;
                p.x[i]
            })
            .collect();
        let mean = (vol / xs.len().max(1) as f64) as f32;
        (xs, mean)
    }
}

/// A body of material to be filled with particles (kept for `rtmpm check` summaries).
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    pub material: u32,
    pub shape: rtmpm_geometry::BodyShape,
    /// Requested particles per cell (regular/jittered use `round(cbrt(ppc))^3`).
    pub particles_per_cell: u32,
    /// True for jittered sampling (kept for compatibility; see `sampling`).
    pub jitter: bool,
    pub sampling: Sampling,
    /// Exact particle count for random sampling (else `ppc * volume / dx^3`).
    pub count: Option<u64>,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
}

/// Floating-point precision of the whole step (`[solver] precision`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Single precision (the default).
    #[default]
    F32,
    /// Double precision: particle state, grid and every quantity of the step in f64.
    F64,
}

impl Precision {
    /// The name written in scene files: "f32" or "f64".
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            _ => Err(format!("unknown precision `{s}`: expected f32 or f64")),
        }
    }
}

/// How the CUDA backend stores the particle state (`[solver] particle_state`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ParticleState {
    /// Every field in f32 (or f64) words (the default).
    #[default]
    F32,
    /// APIC C in shared-exponent words (`rtmpm-cuda` `codec`: 5 words instead of 9; the
    /// velocity stays f32; single precision only). The CUDA backend's option; the CPU backend
    /// keeps its f32 state and ignores it.
    Compact,
}

impl std::str::FromStr for ParticleState {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "f32" => Ok(ParticleState::F32),
            "compact" => Ok(ParticleState::Compact),
            _ => Err(format!(
                "unknown particle state `{s}`: expected f32 or compact"
            )),
        }
    }
}

impl ParticleState {
    /// The name written in scene files: "f32" or "compact".
    pub fn name(self) -> &'static str {
        match self {
            ParticleState::F32 => "f32",
            ParticleState::Compact => "compact",
        }
    }
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
    pub emitters: Vec<crate::emitter::Emitter>,
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
}

impl Scene {
    /// Read and validate a scene file; mesh paths are relative to the file's folder.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let origin = path.display().to_string();
        let text = rtmpm_io::limits::read_text_bounded(
            path,
            rtmpm_io::limits::SCENE_MAX_BYTES,
            "scene file",
        )
        .map_err(|e| {
            let hint = match e.kind() {
                std::io::ErrorKind::NotFound => {
                    "check the path (it is relative to the current folder)"
                }
                std::io::ErrorKind::PermissionDenied => "check the file's permissions",
                _ => "give a scene file: TOML text as in scenes/ and docs/scene-format.md",
            };
            SceneError {
                origin: origin.clone(),
                line: None,
                column: None,
                field: None,
                message: format!("cannot read the scene file: {e}"),
                hint: Some(hint.into()),
            }
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut scene = validate::parse(
            &text,
            &origin,
            &base,
            path.file_stem().and_then(|s| s.to_str()),
        )?;
        scene.source = Some(path.to_path_buf());
        Ok(scene)
    }

    /// Parse and validate scene text; `origin` names it in error messages. Mesh paths are
    /// relative to the current directory.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        validate::parse(text, origin, Path::new(""), None)
    }

    /// Like [`Scene::from_toml`], with mesh paths relative to `base_dir`.
    pub fn from_toml_in(text: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        validate::parse(text, origin, base_dir, None)
    }

    /// What this scene allows but probably gets wrong, one line each, for `rtmpm check` and
    /// `rtmpm run` to print: today dynamic rigid bodies that can hang in a fluid they are
    /// denser than ([`rtmpm_rigid::resolution_warnings`]).
    // `Real` is f64 in the f64 build of this crate.
    #[allow(clippy::unnecessary_cast)]
    pub fn warnings(&self) -> Vec<String> {
        let fluids: Vec<(&str, f32)> = self
            .materials
            .iter()
            .filter(|m| matches!(m.model, rtmpm_physics::material::Model::Fluid(_)))
            .map(|m| (m.name.as_str(), m.density as f32))
            .collect();
        rtmpm_rigid::resolution_warnings(&self.rigid_bodies, &fluids, self.dx)
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
            rigid_bodies: self.rigid_bodies.len(),
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

    /// Fill the bodies with particles (deterministic for a given seed, the same for any number of
    /// threads).
    pub fn sample_particles(&self) -> Result<rtmpm_physics::Particles, SceneError> {
        self.sample_particles_with(&|_| {})
    }

    /// [`Scene::sample_particles`], telling `progress` how far it is (see
    /// [`sampling::sample_scene_with`]).
    pub fn sample_particles_with(
        &self,
        progress: &(dyn Fn(sampling::SampleProgress) + Sync),
    ) -> Result<rtmpm_physics::Particles, SceneError> {
        sampling::sample_scene_with(self, progress).map_err(|mut e| {
            // Sampling errors name the body; the scene file names where it is.
            if e.origin.is_empty()
                && let Some(src) = &self.source
            {
                e.origin = src.display().to_string();
            }
            e
        })
    }
}
