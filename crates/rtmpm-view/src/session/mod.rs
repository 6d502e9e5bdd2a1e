//! A live session: a simulation stepping on its own thread, commands in ([`Command`]) and
//! frames out ([`FrameSlot`]), independent of the front-end (the browser stream, a window, a
//! recording without either).
//!
//! The thread owns the [`Simulation`] (built there by the caller's factory, again on reset),
//! so a backend that must stay on one thread may be used. Each turn of its loop takes the
//! commands that came, advances the simulation by the [`Pace`] unless paused, draws the frame
//! ([`crate::draw`]), publishes it (the slot keeps only the latest: a slow reader misses
//! frames, the simulation never waits for one) and hands it to the recorder, which does get
//! every frame. A blow-up stops the stepping and shows its message in the picture; reset
//! starts again.

mod live;
mod options;
mod present;
mod rates;
#[cfg(test)]
mod tests;

use crate::command::Command;
use crate::frame::FrameSlot;
use crate::record::Recorder;
pub use options::{SceneInfo, SessionOptions, SimFactory, Summary, Timing};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;

/// Commands waiting for the session at most; more are refused ([`SendError::Busy`]).
pub const COMMAND_QUEUE: usize = 256;

/// Why a command was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SendError {
    /// [`COMMAND_QUEUE`] commands are waiting.
    Busy,
    /// The session has ended.
    Ended,
}

impl std::fmt::Display for SendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SendError::Busy => "the session is busy: command dropped (too many at once)",
            SendError::Ended => "the session has ended",
        })
    }
}

/// Where a front-end sends commands; cheap to clone.
#[derive(Clone)]
pub struct Commands(SyncSender<Command>);

impl Commands {
    /// Queue a command without waiting.
    pub fn send(&self, c: Command) -> Result<(), SendError> {
        self.0.try_send(c).map_err(|e| match e {
            TrySendError::Full(_) => SendError::Busy,
            TrySendError::Disconnected(_) => SendError::Ended,
        })
    }
}

/// A running live session.
pub struct Session {
    commands: Commands,
    frames: Arc<FrameSlot>,
    thread: Option<JoinHandle<Summary>>,
    /// What the front-ends show about the scene (name, materials).
    pub info: SceneInfo,
}

impl Session {
    /// Start a session: the thread builds the simulation with `factory` and draws the first
    /// frame before this returns (an error of the factory is returned). `recorder` gets every
    /// displayed frame.
    pub fn start(
        factory: SimFactory,
        options: SessionOptions,
        recorder: Option<Recorder>,
    ) -> Result<Session, String> {
        let (tx, rx) = sync_channel(COMMAND_QUEUE);
        let frames = Arc::new(FrameSlot::default());
        let (ready_tx, ready_rx) = sync_channel::<Result<SceneInfo, String>>(1);
        let slot = frames.clone();
        let thread = std::thread::Builder::new()
            .name("live session".into())
            .spawn(move || run(factory, options, recorder, rx, slot, ready_tx))
            .map_err(|e| format!("cannot start the session's thread: {e}"))?;
        match ready_rx.recv() {
            Ok(Ok(info)) => Ok(Session {
                commands: Commands(tx),
                frames,
                thread: Some(thread),
                info,
            }),
            Ok(Err(e)) => {
                let _ = thread.join();
                Err(e)
            }
            Err(_) => Err(match thread.join() {
                Err(_) => "the session's thread panicked while starting".into(),
                Ok(_) => "the session's thread ended while starting".into(),
            }),
        }
    }

    /// Where to send commands.
    pub fn commands(&self) -> Commands {
        self.commands.clone()
    }

    /// Queue a command without waiting.
    pub fn send(&self, c: Command) -> Result<(), SendError> {
        self.commands.send(c)
    }

    /// The frames: the latest one, or wait for a newer one.
    pub fn frames(&self) -> Arc<FrameSlot> {
        self.frames.clone()
    }

    /// True once the session's thread has ended (Quit, the frame limit, a panic).
    pub fn ended(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// End the session (if still running) and wait for it: the recording is written then.
    pub fn finish(mut self) -> Result<Summary, String> {
        let _ = self.commands.0.send(Command::Quit);
        self.join()
    }

    fn join(&mut self) -> Result<Summary, String> {
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(s)) => Ok(s),
            Some(Err(_)) => Err("the session's thread panicked".into()),
            None => Err("the session was already finished".into()),
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if self.thread.is_some() {
            let _ = self.commands.0.send(Command::Quit);
            let _ = self.join();
        }
    }
}

/// The session's thread.
fn run(
    mut factory: SimFactory,
    options: SessionOptions,
    recorder: Option<Recorder>,
    rx: Receiver<Command>,
    slot: Arc<FrameSlot>,
    ready: SyncSender<Result<SceneInfo, String>>,
) -> Summary {
    let sim = match factory() {
        Ok(s) => s,
        Err(e) => {
            slot.close();
            let _ = ready.send(Err(e));
            return Summary::default();
        }
    };
    let mut live = match live::Live::new(sim, factory, options, recorder, slot.clone()) {
        Ok(l) => l,
        Err(e) => {
            slot.close();
            let _ = ready.send(Err(e));
            return Summary::default();
        }
    };
    // The first picture is published before the session starts.
    live.publish();
    live.collect();
    let _ = ready.send(Ok(live.info()));
    drop(ready);
    let summary = live.run(&rx);
    slot.close();
    summary
}
