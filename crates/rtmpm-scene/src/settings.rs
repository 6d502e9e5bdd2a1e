//! The settings of a scene: time stepping, output, surfaces, precision and particle state.

use rtmpm_io::frame::{Derived, FrameFormat};
use rtmpm_physics::math::Vec3;
use std::path::PathBuf;

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
    /// The particle frame files written per frame, in the order of
    /// [`rtmpm_io::FRAME_FORMATS`] (`[output] formats`); empty: none.
    pub formats: Vec<&'static FrameFormat>,
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

impl OutputSettings {
    /// True when frames are written in the format named `name`.
    pub fn writes(&self, name: &str) -> bool {
        self.formats.iter().any(|f| f.name == name)
    }

    /// The derived fields the frames hold.
    pub fn derived(&self) -> Derived {
        Derived {
            jacobian: self.jacobian,
            stress: self.stress,
        }
    }
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

/// How a body is filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sampling {
    /// Sub-cell centres of the global grid.
    Regular,
    /// Sub-cell centres plus uniform jitter within the sub-cell.
    #[default]
    Jittered,
    /// Uniformly random positions.
    Random,
}
