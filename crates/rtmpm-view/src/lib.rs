//! Watch and steer a running rtmpm simulation live.
//!
//! * [`session`]: a [`Session`] steps a [`rtmpm_driver::Simulation`] on its own thread,
//!   takes [`Command`]s (pause, step, reset, pace, colour mode, camera, the tool dragged
//!   through the material, thrown balls, gravity) and publishes [`Frame`]s (a picture and a
//!   [`Status`]) in a [`FrameSlot`] that keeps only the latest: front-ends never slow it down.
//! * [`camera`]: the orbit camera; [`steer`]: the tool's motion, picking, thrown balls;
//!   [`draw`]: the picture (the backend's own, or the CPU renderer's), heads-up line and
//!   blow-up message; [`record`]: GIF/MP4 recording of what was shown; [`jpeg`]: encoding.
//! * `window` (feature `window`, default): the native window front-end (winit + softbuffer).
//! * [`serve`]: the browser front-end: an HTTP server with the page and a WebSocket that
//!   streams the frames as JPEG and takes the controls back.
//!
//! The pictures are the CPU renderer's (`rtmpm_render`) unless the backend draws them
//! itself ([`rtmpm_sim::Backend::render_view`]).

pub mod camera;
pub mod command;
pub mod draw;
pub mod frame;
pub mod jpeg;
pub mod record;
pub mod serve;
pub mod session;
pub mod steer;
#[cfg(feature = "window")]
pub mod window;

pub use command::{Command, Pace, Throw};
pub use frame::{Frame, FrameSlot, Status};
pub use record::Recorder;
pub use session::{Commands, SceneInfo, Session, SessionOptions, SimFactory, Summary, Timing};
