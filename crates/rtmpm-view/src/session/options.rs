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
    /// Collect a picture drawn on a device while the next frame's steps run
    /// ([`rtmpm_sim::Backend::begin_view`]); false: draw and publish each picture before the
    /// next step (the A/B of the view's cost).
    pub overlap: bool,
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
            overlap: true,
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
    /// Where the time went after the first simulated frame.
    pub timing: Timing,
}

/// Where a session's wall-clock time went (host clocks), counted from the end of its first
/// simulated frame (which builds the backend's first mapping) to its end.
#[derive(Clone, Debug, Default)]
pub struct Timing {
    /// Wall-clock seconds.
    pub wall_s: f64,
    /// Steps taken and the seconds of the calls that took them: queueing the steps, waiting
    /// for them at each frame's end, and the pictures collected meanwhile (`finish_s` of those).
    pub steps: u64,
    pub step_s: f64,
    /// Simulated frames completed.
    pub frames: u64,
    /// Pictures published; seconds beginning pictures on the backend (queueing them), drawing
    /// pictures at once (the CPU renderer, or without overlap), collecting begun pictures (the
    /// wait for the picture and its copy, the copy into the image), and the heads-up line,
    /// slot and recorder.
    pub pictures: u64,
    pub begin_s: f64,
    pub draw_s: f64,
    pub finish_s: f64,
    pub present_s: f64,
    /// Pictures collected while the next steps ran on the device.
    pub overlapped: u64,
}

impl Timing {
    /// Milliseconds per step of the whole loop (the simulation with the view on).
    pub fn ms_per_step(&self) -> f64 {
        1e3 * self.wall_s / self.steps.max(1) as f64
    }

    /// One line for logs and benchmarks: `view_timing key=value ...` (times in ms, per step or
    /// per picture).
    pub fn line(&self) -> String {
        let per = |s: f64, n: u64| 1e3 * s / n.max(1) as f64;
        format!(
            "view_timing wall_s={:.3} steps={} frames={} pictures={} overlapped={} \
             ms_per_step={:.4} step_ms_per_step={:.4} begin_ms={:.3} draw_ms={:.3} \
             finish_ms={:.3} present_ms={:.3}",
            self.wall_s,
            self.steps,
            self.frames,
            self.pictures,
            self.overlapped,
            self.ms_per_step(),
            per(self.step_s, self.steps),
            per(self.begin_s, self.pictures),
            per(self.draw_s, self.pictures),
            per(self.finish_s, self.pictures),
            per(self.present_s, self.pictures),
        )
    }
}
