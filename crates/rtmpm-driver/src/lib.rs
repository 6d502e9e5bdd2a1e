//! The run driver: what the command line, Python and a live view call to run a scene on a
//! backend.
//!
//! * [`Simulation`]: steps a backend through the frames of a scene (time steps, frame landing,
//!   emitters, blow-up reports).
//! * [`checks`]: the measurements of the validation cases (floating, settling and colliding
//!   bodies, emitted mass).

pub mod checks;
mod simulation;

pub use simulation::Simulation;
