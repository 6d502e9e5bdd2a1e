//! The presenting half of a session: a picture's status, heads-up line and message, the slot
//! and the recorder, where the time went; and a picture in flight on the backend.
//!
//! A backend that draws on a device begins a picture after a frame's steps
//! ([`Backend::begin_view`]: queued, not waited for); the session then queues the next frame's
//! steps and, once they are queued ([`RunHooks::steps_queued`]), collects the picture
//! ([`Backend::finish_view`], which waits for the picture only) and publishes it while the
//! device steps. The device then waits for the host only for the picture's own kernels and
//! copy, not for the heads-up line, the publishing or the recording.

use super::options::Timing;
use super::rates::Rates;
use crate::draw::{draw_hud, draw_message};
use crate::frame::{Frame, FrameSlot, Status};
use crate::record::Recorder;
use rtmpm_driver::run::RunHooks;
use rtmpm_render::Image;
use rtmpm_sim::Backend;
use std::sync::Arc;
use std::time::Instant;

/// A picture begun on the backend, with the status of the state it shows.
struct InFlight {
    status: Status,
    /// Milliseconds spent beginning it.
    begin_ms: f64,
}

/// What a session publishes and how.
pub(super) struct Present {
    slot: Arc<FrameSlot>,
    pub(super) seq: u64,
    pub(super) rates: Rates,
    recorder: Option<Recorder>,
    recording_error: Option<String>,
    hud: bool,
    in_flight: Option<InFlight>,
    /// Why the last picture could not be collected (the session shows it as its error).
    pub(super) failed: Option<String>,
    pub(super) timing: Timing,
}

impl Present {
    pub(super) fn new(slot: Arc<FrameSlot>, recorder: Option<Recorder>, hud: bool) -> Present {
        Present {
            slot,
            seq: 0,
            rates: Rates::default(),
            recorder,
            recording_error: None,
            hud,
            in_flight: None,
            failed: None,
            timing: Timing::default(),
        }
    }

    /// The status of the next picture: its number and the rates now.
    pub(super) fn next_status(&mut self, mut status: Status) -> Status {
        self.seq += 1;
        let (steps_per_s, particle_steps_per_s, fps) = self.rates.sample(Instant::now(), self.seq);
        status.seq = self.seq;
        status.steps_per_s = steps_per_s;
        status.particle_steps_per_s = particle_steps_per_s;
        status.fps = fps;
        status
    }

    /// A picture of `status`'s state was begun on the backend in `begin_ms`.
    pub(super) fn began(&mut self, status: Status, begin_ms: f64) {
        self.in_flight = Some(InFlight { status, begin_ms });
    }

    /// A picture is in flight.
    pub(super) fn pending(&self) -> bool {
        self.in_flight.is_some()
    }

    /// Collect the picture in flight, if any, and publish it.
    pub(super) fn finish(&mut self, backend: &mut dyn Backend) {
        let Some(f) = self.in_flight.take() else {
            return;
        };
        let t0 = Instant::now();
        let mut image = Image::new(0, 0, [0; 3]);
        let mut status = f.status;
        if let Err(e) = backend.finish_view(&mut image) {
            let e = format!("cannot draw the view: {e}");
            status.error.get_or_insert(e.clone());
            self.failed = Some(e);
            image = Image::new(status.width, status.height, [30, 30, 36]);
        }
        let finish_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.timing.finish_s += finish_ms * 1e-3;
        status.render_ms = f.begin_ms + finish_ms;
        self.show(image, status);
    }

    /// Publish `image` of `status` now: the heads-up line, the message of an error, the slot,
    /// the recorder.
    pub(super) fn show(&mut self, mut image: Image, status: Status) {
        let t0 = Instant::now();
        if self.hud {
            draw_hud(&mut image, &hud_line(&status));
        }
        if let Some(e) = &status.error {
            draw_message(&mut image, e);
        }
        let frame = Arc::new(Frame { image, status });
        self.slot.publish(frame.clone());
        if let Some(r) = &self.recorder
            && let Err(e) = r.add(frame)
        {
            self.recording_error = Some(e);
            self.recorder = None;
        }
        self.timing.pictures += 1;
        self.timing.present_s += t0.elapsed().as_secs_f64();
    }

    /// The recording's summary line, or why it failed.
    pub(super) fn finish_recording(self) -> Option<Result<String, String>> {
        match (self.recorder, self.recording_error) {
            (_, Some(e)) => Some(Err(e)),
            (Some(r), None) => Some(r.finish()),
            (None, None) => None,
        }
    }
}

/// The run's hooks of a live session: the picture in flight is collected once the next steps
/// are queued.
impl RunHooks for Present {
    fn steps_queued(&mut self, backend: &mut dyn Backend) {
        if self.in_flight.is_some() {
            self.finish(backend);
            self.timing.overlapped += 1;
        }
    }
}

/// The heads-up line: time, frame, particles, rates (parts separated by two spaces).
pub(crate) fn hud_line(s: &Status) -> String {
    let mut parts = vec![
        format!("T {:.3} S", s.time),
        format!("FRAME {}", s.frame),
        format!("{} PARTICLES", s.particles),
        format!("{:.0} STEPS/S", s.steps_per_s),
        format!("{:.2E} PARTICLE-STEPS/S", s.particle_steps_per_s),
        format!("{:.1} FPS", s.fps),
        format!("PACE {}", s.pace.to_uppercase()),
    ];
    if s.paused {
        parts.push("PAUSED".into());
    }
    parts.join("  ")
}
