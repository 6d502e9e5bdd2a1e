//! Many worlds from one scene file: `[batch] count = N` and `[batch.sweep]`.
//!
//! ```toml
//! [batch]
//! count = 16
//! [batch.sweep]
//! "material[0].yield_stress" = { from = 50, to = 500 }   # linear (or spacing = "log")
//! "gravity[1]" = [-9.81, -1.62, ...]                      # one value per world
//! "body[0].velocity" = { from = [0, 0, 0], to = [1, 0, 0] } # vectors component by component
//! ```
//!
//! A sweep sets one numeric value of the scene (any field path the scene file could hold, as
//! the validation names them) to a different value in each world. [`Batch::parse`] reads the
//! table, [`Batch::expand`] writes each world's scene table (a pure function of the file's table),
//! and [`BatchScene`] validates every world's scene, naming the sweep and the world of a value the
//! scene refuses.

pub mod path;
mod scene;
mod sweep;
#[cfg(test)]
mod tests;

pub use scene::{BatchScene, memory_refusal, scaled_budget};
pub use sweep::{Batch, BatchIssue, MAX_BATCH_TEXT_BYTES, MAX_WORLDS, Sweep};
