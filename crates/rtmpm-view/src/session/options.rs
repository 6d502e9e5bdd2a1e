//! What a session is given and what it gives back: the simulation's factory, the options it
//! starts with, the scene as front-ends describe it, and the summary at its end.

use crate::command::Pace;
use rtmpm_driver::Simulation;
use rtmpm_geometry::ToolShape;
use rtmpm_render::Camera;
use rtmpm_scene::ColorBy;

/// Builds the simulation at its initial state: at the start and on every reset (called on the
/// session's thread). Errors are messages for the user.
pub type SimFactory = Box<dyn FnMut() -> Result<Simulation, String> + Send>;

/// How a session starts.
#[derive(Clone, Debug)]
pub struct SessionOptions {
    /// Image size (pixels).
    pub width: u32,
    pub height: u32,
    pub color_by: ColorBy,
    /// Fixed colour range of the field (None: per frame).
    pub range: Option<(f32, f32)>,
    /// Particle radius on screen (m); None: 0.6 of the particle spacing of the first body.
    pub radius: Option<f32>,
    /// The first camera; None: framing the domain.
    pub camera: Option<Camera>,
    pub pace: Pace,
    /// Start paused.
    pub paused: bool,
    /// The tool's shape; None: a ball of an eighth of the domain's smallest side, at least
    /// two cells.
    pub tool: Option<ToolShape>,
    /// End the session after this many simulated frames (a recording without a front-end).
    pub max_frames: Option<u64>,
    /// Draw the heads-up line into the picture.
    pub hud: bool,
    pub shadows: bool,
}

impl Default for SessionOptions {
    fn default() -> Self {
        SessionOptions {
            width: 1280,
            height: 720,
            color_by: ColorBy::Material,
            range: None,
            radius: None,
            camera: None,
            pace: Pace::default(),
            paused: false,
            tool: None,
            max_frames: None,
            hud: true,
            shadows: true,
        }
    }
}

/// The scene as front-ends describe it.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SceneInfo {
    pub name: String,
    pub materials: Vec<String>,
    pub backend: String,
    pub fps: f32,
    pub duration: f32,
}

/// What a session did, when it ended.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Pictures published.
    pub displayed: u64,
    /// Simulated frames and steps at the end (since the last reset).
    pub frames: u64,
    pub steps: u64,
    /// Simulated time at the end (s).
    pub time: f64,
    /// The recording's summary line, or why it failed.
    pub recording: Option<Result<String, String>>,
    /// The blow-up the session ended with, if any.
    pub error: Option<String>,
}
