//! Why a run stopped ([`SimError`]), and the particle health a backend reports ([`BadParticle`]).

use rtmpm_physics::math::Vec3;
use std::fmt;

/// Why a simulation stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// A particle's state became non-finite or its speed exploded.
    Blowup(Box<Blowup>),
    /// The CFL time step fell below `time.min_dt`: the run would crawl without end. The
    /// [`Blowup`] names the fastest particle.
    Stall(Box<Blowup>),
    /// The backend failed (device error, out of capacity, ...).
    Backend(String),
}

/// Where and why a simulation blew up.
#[derive(Debug, Clone, PartialEq)]
pub struct Blowup {
    pub step: u64,
    pub time: f64,
    pub particle: usize,
    pub position: Vec3,
    pub velocity: Vec3,
    /// Name of the particle's material.
    pub material: String,
    /// What was detected, e.g. "velocity is NaN".
    pub reason: String,
    /// The time step in use.
    pub dt: f32,
    /// What to change when the cause is known (a collider, rigid body, emitter or gravity
    /// beyond what the step follows); `None`: the generic advice.
    pub advice: Option<String>,
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Backend(m) => write!(f, "backend error: {m}"),
            SimError::Stall(b) => write!(
                f,
                "the time step collapsed at step {} (t = {:.6} s): {}\n  \
                 fastest: particle {} of material `{}` at ({:.4}, {:.4}, {:.4}), velocity \
                 ({:.4e}, {:.4e}, {:.4e})\n  \
                 advice: {}",
                b.step,
                b.time,
                b.reason,
                b.particle,
                b.material,
                b.position.x,
                b.position.y,
                b.position.z,
                b.velocity.x,
                b.velocity.y,
                b.velocity.z,
                b.advice.as_deref().unwrap_or(
                    "this speed is far above the material's sound speed (a blow-up under way, \
                     or an initial velocity too large): lower the body's velocity, use a fixed \
                     `time.dt` or a softer material; or, if the speed is intended, lower \
                     `time.min_dt`"
                )
            ),
            SimError::Blowup(b) => write!(
                f,
                "simulation blew up at step {} (t = {:.6} s, dt = {:.3e} s): particle {} of material `{}`: {}\n  \
                 position ({:.4}, {:.4}, {:.4}), velocity ({:.4e}, {:.4e}, {:.4e})\n  \
                 advice: {}",
                b.step,
                b.time,
                b.dt,
                b.particle,
                b.material,
                b.reason,
                b.position.x,
                b.position.y,
                b.position.z,
                b.velocity.x,
                b.velocity.y,
                b.velocity.z,
                b.advice.as_deref().unwrap_or(
                    "use a smaller time step (lower `time.dt`, or `time.cfl` / `time.max_dt`), \
                     or a softer material (lower stiffness) at this resolution"
                )
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// A particle whose state is not sane after a step: non-finite, or faster than
/// [`MAX_CELLS_PER_STEP`] cells per step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadParticle {
    /// Its original index.
    pub index: usize,
    pub reason: BadReason,
    /// The position and velocity the health check saw, before the step clamped the position to
    /// the domain (a NaN position is stored clamped): `None` when the backend does not keep
    /// them (the state read afterwards is reported then).
    pub seen: Option<(Vec3, Vec3)>,
}

/// A particle moving more than this many cells in one step is taken as a blow-up
/// ([`BadReason::TooFast`]).
pub const MAX_CELLS_PER_STEP: f32 = 2.0;

/// What was wrong with a [`BadParticle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadReason {
    /// A position, velocity or deformation gradient that is NaN or infinite.
    NonFinite,
    TooFast,
}
