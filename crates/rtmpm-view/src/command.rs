//! What a front-end asks of a live session ([`Command`]), and how far the simulation goes
//! between two displayed frames ([`Pace`]).

use glam::Vec3;
use rtmpm_geometry::ToolShape;
use rtmpm_scene::ColorBy;
use std::fmt;

/// How far the simulation advances between two displayed frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// This many time steps (slow motion, step by step).
    Steps(u32),
    /// This many of the scene's frames (1: every simulated frame is shown).
    Frames(u32),
}

/// Most steps or frames per displayed frame.
pub const MAX_PACE: u32 = 1024;

impl Default for Pace {
    fn default() -> Self {
        Pace::Frames(1)
    }
}

impl Pace {
    /// Twice as fast: twice the steps, a whole frame once the steps reach `steps_per_frame`
    /// (the steps of the last frame), then twice the frames.
    pub fn faster(self, steps_per_frame: u64) -> Pace {
        match self {
            Pace::Steps(n) if 2 * n as u64 >= steps_per_frame.max(1) => Pace::Frames(1),
            Pace::Steps(n) => Pace::Steps((2 * n).min(MAX_PACE)),
            Pace::Frames(k) => Pace::Frames((2 * k).min(MAX_PACE)),
        }
    }

    /// Half as fast: half the frames, then the largest power of two of steps below a frame,
    /// then half the steps (at least one).
    pub fn slower(self, steps_per_frame: u64) -> Pace {
        match self {
            Pace::Frames(k) if k > 1 => Pace::Frames(k / 2),
            Pace::Frames(_) => {
                let below = steps_per_frame.saturating_sub(1).max(1);
                let pow = 1u64 << (63 - below.leading_zeros());
                Pace::Steps(pow.min(MAX_PACE as u64) as u32)
            }
            Pace::Steps(n) => Pace::Steps((n / 2).max(1)),
        }
    }
}

impl fmt::Display for Pace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pace::Steps(1) => f.write_str("1 step"),
            Pace::Steps(n) => write!(f, "{n} steps"),
            Pace::Frames(1) => f.write_str("1 frame"),
            Pace::Frames(k) => write!(f, "{k} frames"),
        }
    }
}

/// A ball of material thrown into the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Throw {
    /// Pixel the ball is thrown through (x right, y down): it starts where that ray enters
    /// the domain and flies along it.
    pub x: f32,
    pub y: f32,
    /// The scene's material, by index (None: the first).
    pub material: Option<usize>,
    /// Ball radius (m); None: a tenth of the domain's smallest side, at least two cells.
    pub radius: Option<f32>,
    /// Speed (m/s); None: about a domain size per second.
    pub speed: Option<f32>,
}

/// What a front-end (a window, a browser) asks of a live session. Pixel coordinates are in
/// the session's image (x right, y down).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    Pause,
    Resume,
    TogglePause,
    /// One time step (pauses first).
    Step,
    /// Back to the initial state at t = 0 (camera, colours and pace kept).
    Reset,
    Slower,
    Faster,
    SetPace(Pace),
    ColorBy(ColorBy),
    /// The next colour mode.
    CycleColor,
    /// Turn the camera by a mouse motion (pixels).
    Orbit {
        dx: f32,
        dy: f32,
    },
    /// Move the camera sideways by a mouse motion (pixels).
    Pan {
        dx: f32,
        dy: f32,
    },
    /// Multiply the camera's distance by this (< 1: closer).
    Zoom(f32),
    CameraReset,
    /// The image size (pixels).
    Resize {
        width: u32,
        height: u32,
    },
    /// Grab the tool at this pixel: it appears on the cursor's ray at the depth of the
    /// material there (or of the camera's target).
    ToolStart {
        x: f32,
        y: f32,
    },
    /// Move the tool towards this pixel's ray, at the depth it was grabbed at.
    ToolMove {
        x: f32,
        y: f32,
    },
    /// Push the grabbed tool deeper (> 1) or pull it nearer (< 1) along the view.
    ToolDepth(f32),
    /// Let go of the tool: it leaves the simulation.
    ToolEnd,
    /// The tool's shape and size for the next grab.
    ToolShape(ToolShape),
    Throw(Throw),
    /// Gravity (m/s^2) from the next step on.
    Gravity(Vec3),
    /// End the session.
    Quit,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faster_and_slower_walk_a_ladder_of_steps_and_frames() {
        let spf = 20;
        let mut p = Pace::default();
        p = p.slower(spf);
        assert_eq!(p, Pace::Steps(16));
        p = p
            .slower(spf)
            .slower(spf)
            .slower(spf)
            .slower(spf)
            .slower(spf);
        assert_eq!(p, Pace::Steps(1));
        p = p.faster(spf);
        assert_eq!(p, Pace::Steps(2));
        p = Pace::Steps(16).faster(spf);
        assert_eq!(p, Pace::Frames(1));
        assert_eq!(p.faster(spf).faster(spf), Pace::Frames(4));
        assert_eq!(Pace::Frames(4).slower(spf), Pace::Frames(2));
        assert_eq!(Pace::Frames(MAX_PACE).faster(spf), Pace::Frames(MAX_PACE));
        // A frame of one step: slower still gives one step.
        assert_eq!(Pace::Frames(1).slower(1), Pace::Steps(1));
        assert_eq!(Pace::Steps(1).to_string(), "1 step");
        assert_eq!(Pace::Frames(2).to_string(), "2 frames");
    }
}
