//! The interface every compute backend implements: [`Backend`] advances the particle state by
//! explicit steps and hands it out (whole, or in chunks: [`chunks`]); [`SimError`] says why a run
//! stopped. The particles at the interface are f32 ([`Particles`]) whatever precision a backend
//! computes in. The driver that steps a backend through the frames of a scene is
//! `rtmpm_driver::Simulation`.

pub mod backend;
pub mod chunks;
pub mod edit;
pub mod error;
pub mod timing;
pub mod worlds;

pub use backend::Backend;
pub use chunks::{ChunkSink, export_particles, fill_chunks, invert_ids};
pub use edit::ParticleEdit;
pub use error::{BadParticle, BadReason, Blowup, MAX_CELLS_PER_STEP, SimError};
/// The particles of the backend interface: f32 whatever precision a backend computes in.
pub use rtmpm_physics::Particles;
pub use worlds::Worlds;
