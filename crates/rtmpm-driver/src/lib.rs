//! The run driver: what the command line, Python and a live view call to run a scene on a
//! backend.
//!
//! * [`Simulation`]: steps a backend through the frames of a scene (time steps, frame landing,
//!   emitters, blow-up reports).
//! * [`batch`]: the worlds of a scene's `[batch]` run together, each isolated, a world that
//!   blows up frozen while the others go on.
//! * [`run`]: a run to its last frame ([`run::RunStart`] from a scene file or a checkpoint,
//!   [`run::Run::execute`]): the steps in chunks, every frame written, checkpoints.
//! * [`output`]: the frame files of the scene's formats and fluid surfaces; [`stream`]: PLY and
//!   BGEO frames streamed from the backend in chunks and written in the background;
//!   [`outdir`]: the output folder (locked, holding one run); [`bodies_csv`]: the rigid
//!   bodies per frame; [`resume`]: a checkpoint read and checked to resume from.
//! * [`setup`]: sampling the scene's bodies with progress lines; [`progress`]: step chunks,
//!   progress lines, rates.
//! * [`checks`]: the measurements of the validation cases (floating, settling and colliding
//!   bodies, emitted mass).

pub mod batch;
pub mod bodies_csv;
pub mod checks;
pub mod outdir;
pub mod output;
pub mod progress;
pub mod resume;
pub mod run;
pub mod setup;
mod simulation;
pub mod stream;

pub use simulation::Simulation;
