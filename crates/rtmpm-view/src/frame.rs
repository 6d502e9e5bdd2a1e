//! What a live session shows: a picture and its [`Status`], handed out through a
//! [`FrameSlot`] that keeps only the latest one (a slow reader misses frames; the session
//! never waits for it).

use rtmpm_render::Image;
use serde::Serialize;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

/// The state of a live session as a front-end shows it (the heads-up line) and a test reads
/// it (the browser stream sends it as JSON with every frame).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Status {
    /// Number of this displayed frame (from 1, counting every picture published).
    pub seq: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Simulated frames completed.
    pub frame: u64,
    /// Time steps taken.
    pub step: u64,
    /// Particles in the simulation.
    pub particles: u64,
    /// Time steps per second of wall-clock time over the last second.
    pub steps_per_s: f64,
    /// Particles times steps per second.
    pub particle_steps_per_s: f64,
    /// Pictures published per second over the last second.
    pub fps: f64,
    /// Milliseconds to draw this picture (render or read-back and CPU render).
    pub render_ms: f64,
    pub paused: bool,
    /// Steps or frames per displayed frame, e.g. "1 frame".
    pub pace: String,
    /// The colour mode.
    pub color_by: String,
    /// Gravity (m/s^2).
    pub gravity: [f32; 3],
    /// Centre of mass of the particles (m), when they were read for this picture (the CPU
    /// renderer reads them; a backend that draws itself does not).
    pub center_of_mass: Option<[f64; 3]>,
    /// The tool's centre while it is held.
    pub tool: Option<[f32; 3]>,
    /// The backend's name.
    pub backend: String,
    /// Image size.
    pub width: u32,
    pub height: u32,
    /// Why the simulation stopped (a blow-up), shown in the picture too; reset clears it.
    pub error: Option<String>,
    /// The last thing the session did or refused (e.g. "threw 1234 particles of `sand`").
    pub message: Option<String>,
}

/// One displayed frame.
#[derive(Clone, Debug)]
pub struct Frame {
    pub image: Image,
    pub status: Status,
}

#[derive(Default)]
struct Latest {
    frame: Option<Arc<Frame>>,
    closed: bool,
}

/// The latest frame of a session: the session publishes, any number of readers take the
/// newest they have not seen. Holds one frame.
#[derive(Default)]
pub struct FrameSlot {
    latest: Mutex<Latest>,
    changed: Condvar,
}

impl FrameSlot {
    /// Replace the frame and wake the readers.
    pub fn publish(&self, frame: Arc<Frame>) {
        let mut l = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        l.frame = Some(frame);
        drop(l);
        self.changed.notify_all();
    }

    /// No more frames will come (the session ended); readers stop waiting.
    pub fn close(&self) {
        self.latest.lock().unwrap_or_else(|e| e.into_inner()).closed = true;
        self.changed.notify_all();
    }

    /// The newest frame, if any.
    pub fn latest(&self) -> Option<Arc<Frame>> {
        self.latest
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .frame
            .clone()
    }

    /// Wait up to `timeout` for a frame newer than `seen` (a [`Status::seq`]); `Err` once the
    /// session has ended and every frame was seen.
    pub fn wait_newer(&self, seen: u64, timeout: Duration) -> Result<Option<Arc<Frame>>, Ended> {
        let l = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        let newer = |l: &Latest| l.frame.as_ref().is_some_and(|f| f.status.seq > seen);
        let (l, _) = self
            .changed
            .wait_timeout_while(l, timeout, |l| !newer(l) && !l.closed)
            .unwrap_or_else(|e| e.into_inner());
        if newer(&l) {
            Ok(l.frame.clone())
        } else if l.closed {
            Err(Ended)
        } else {
            Ok(None)
        }
    }
}

/// The session has ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ended;

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(seq: u64) -> Arc<Frame> {
        Arc::new(Frame {
            image: Image::new(2, 2, [0; 3]),
            status: Status {
                seq,
                ..Default::default()
            },
        })
    }

    #[test]
    fn readers_get_the_newest_frame_only_and_learn_of_the_end() {
        let slot = Arc::new(FrameSlot::default());
        assert!(slot.latest().is_none());
        let t = Duration::from_millis(10);
        assert_eq!(slot.wait_newer(0, t).map(|f| f.is_none()), Ok(true));
        for s in 1..=5 {
            slot.publish(frame(s));
        }
        // A slow reader skips to the newest.
        let f = slot.wait_newer(0, t).unwrap().unwrap();
        assert_eq!(f.status.seq, 5);
        assert!(slot.wait_newer(5, t).unwrap().is_none());
        let reader = {
            let slot = slot.clone();
            std::thread::spawn(move || slot.wait_newer(5, Duration::from_secs(10)))
        };
        std::thread::sleep(Duration::from_millis(20));
        slot.publish(frame(6));
        assert_eq!(reader.join().unwrap().unwrap().unwrap().status.seq, 6);
        slot.close();
        assert_eq!(
            slot.wait_newer(6, Duration::from_secs(10)).unwrap_err(),
            Ended
        );
        // A frame not yet seen is still handed out after the end.
        assert_eq!(slot.wait_newer(2, t).unwrap().unwrap().status.seq, 6);
    }
}
