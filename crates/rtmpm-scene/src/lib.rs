//! Scene files (TOML): schema, validation with precise error messages, and particle sampling.
//!
//! The schema is documented in `docs/scene-format.md`. [`Scene::from_file`] /
//! [`Scene::from_toml`] parse the text with serde into the raw structs of [`schema`] (unknown
//! fields rejected), then [`validate`] checks and resolves them. Every error names the field
//! path (e.g. `material[1].poisson_ratio`), its line and column, and a hint.

// `SceneError` is deliberately rich (position, field, hint); it is only built on failure.
#![allow(clippy::result_large_err)]

pub mod batch;
pub mod body;
pub mod budget;
pub mod contact;
pub mod deferred;
pub mod emitter;
pub mod error;
pub mod files;
mod fill;
mod load;
pub mod pcg;
mod render_settings;
pub mod sampling;
mod scene;
pub mod schema;
pub mod settings;
pub mod spans;
pub mod speeds;
#[cfg(test)]
mod tests;
mod validate;
mod walk;
mod warnings;

pub use batch::BatchScene;
pub use budget::Budget;
pub use error::SceneError;
pub use render_settings::{ColorBy, RenderSettings};
pub use sampling::Sampling;
pub use scene::{Body, Scene};
pub use settings::{
    Damping, MeshFormats, OutputSettings, ParticleState, Precision, StepMode, SurfaceSettings,
    TimeSettings,
};
pub use spans::span_of;
