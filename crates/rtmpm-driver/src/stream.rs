//! Frames written in the background: at a frame boundary the backend copies the columns the
//! formats need into host chunks ([`rtmpm_io::chunks`]; page-locked memory on a GPU), in
//! original particle order, and a writer thread encodes and writes them
//! ([`rtmpm_io::stream`]) while the simulation goes on.
//!
//! Memory is bounded by a pool of chunk buffers: with `frames_in_flight = 0` two buffers (the
//! copy of chunk k + 1 overlaps the writing of chunk k, and the step waits for the frame's
//! files), with `frames_in_flight = F >= 1` the chunks of F frames (a frame's copy returns at
//! once and the next steps run while it is written; a frame boundary waits while F frames are
//! still being written). A writer error surfaces, naming the file, at the next frame or at
//! [`FrameStreamer::finish`]; the file is then absent (temporary names, removed on error).

use anyhow::{Context, Result, anyhow};
use rtmpm_io::chunks::{FrameChunk, FrameColumns};
use rtmpm_io::stream::{Derived, FrameFiles, StreamFormat};
use rtmpm_physics::material::Model;
use rtmpm_sim::{Backend, ChunkSink, SimError};
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;
use std::time::Instant;

/// Default particles per chunk (16M: 512 MB of PLY columns).
pub const DEFAULT_CHUNK: usize = 1 << 24;

/// How frames are written.
#[derive(Clone, Debug)]
pub struct StreamSettings {
    /// Particles per chunk.
    pub chunk: usize,
    /// Frames being written while the simulation steps on (0: wait for each frame).
    pub frames_in_flight: usize,
    /// `J` and stress fields.
    pub derived: Derived,
    /// The scene's material models (for the stress).
    pub models: Vec<Model>,
}

/// Totals of the frames written so far.
#[derive(Clone, Copy, Debug, Default)]
pub struct StreamStats {
    /// Frames completed.
    pub frames: u64,
    /// Bytes of the columns copied from the backend.
    pub copied_bytes: u64,
    /// Seconds of the main thread in the copies (export).
    pub copy_seconds: f64,
    /// Bytes written to the files (before gzip).
    pub written_bytes: u64,
    /// Seconds of the writer thread creating, encoding, writing, syncing and renaming the files
    /// (not its waits for chunks).
    pub write_seconds: f64,
    /// Seconds of the main thread waiting for the writer (frames or buffers in flight).
    pub wait_seconds: f64,
}

enum Msg {
    Begin(Vec<(PathBuf, StreamFormat)>, usize),
    Chunk(FrameChunk),
    End,
    Abort,
}

/// A frame's outcome: (bytes, seconds) or the error naming the file.
type Done = Result<(u64, f64), anyhow::Error>;

/// The background frame writer of a run.
pub struct FrameStreamer {
    settings: StreamSettings,
    to_writer: Option<Sender<Msg>>,
    free_rx: Receiver<FrameChunk>,
    done_rx: Receiver<Done>,
    thread: Option<JoinHandle<()>>,
    /// Buffers owned by the main thread now.
    free: Vec<FrameChunk>,
    /// Buffers allocated in all, and their capacity in particles.
    allocated: usize,
    cap: usize,
    cols: FrameColumns,
    in_flight: usize,
    stats: StreamStats,
    /// Page-locked memory was refused once (said once).
    warned: bool,
}

impl FrameStreamer {
    /// Start the writer thread for frames of the columns `cols`.
    pub fn new(settings: StreamSettings, formats: &[StreamFormat]) -> Result<FrameStreamer> {
        let cols = FrameFiles::columns(formats, settings.derived);
        let (to_writer, rx) = channel::<Msg>();
        let (free_tx, free_rx) = channel::<FrameChunk>();
        let (done_tx, done_rx) = channel::<Done>();
        let (derived, models) = (settings.derived, settings.models.clone());
        let thread = std::thread::Builder::new()
            .name("rtmpm-frame-writer".into())
            .spawn(move || writer(rx, free_tx, done_tx, derived, models))
            .context("cannot start the frame writer thread")?;
        Ok(FrameStreamer {
            settings,
            to_writer: Some(to_writer),
            free_rx,
            done_rx,
            thread: Some(thread),
            free: Vec::new(),
            allocated: 0,
            cap: 0,
            cols,
            in_flight: 0,
            stats: StreamStats::default(),
            warned: false,
        })
    }

    /// Wait for one frame in flight; its error, if any.
    fn wait_one(&mut self) -> Result<()> {
        let t = Instant::now();
        let done = self
            .done_rx
            .recv()
            .map_err(|_| anyhow!("the frame writer thread stopped"));
        self.stats.wait_seconds += t.elapsed().as_secs_f64();
        self.in_flight -= 1;
        let (bytes, secs) = done??;
        self.stats.frames += 1;
        self.stats.written_bytes += bytes;
        self.stats.write_seconds += secs;
        Ok(())
    }

    /// The errors of frames completed since the last call, without waiting.
    pub fn poll(&mut self) -> Result<()> {
        while self.in_flight > 0 {
            match self.done_rx.try_recv() {
                Ok(done) => {
                    self.in_flight -= 1;
                    let (bytes, secs) = done?;
                    self.stats.frames += 1;
                    self.stats.written_bytes += bytes;
                    self.stats.write_seconds += secs;
                }
                Err(_) => break,
            }
        }
        Ok(())
    }

    /// Wait until no frame is in flight (every file written and renamed).
    pub fn flush(&mut self) -> Result<()> {
        while self.in_flight > 0 {
            self.wait_one()?;
        }
        Ok(())
    }

    /// Buffers for frames of `n` particles: reallocated when `n` outgrows their capacity.
    fn ensure_pool(&mut self, backend: &dyn Backend, n: usize) -> Result<()> {
        // Grown geometrically (emitters add particles every frame): few reallocations.
        let chunk = self.settings.chunk.max(1);
        let cap = chunk.min(n.max(1));
        if cap > self.cap {
            let cap = chunk.min(cap.max(2 * self.cap));
            self.flush()?;
            while self.free_rx.try_recv().is_ok() {}
            self.free.clear();
            self.allocated = 0;
            self.cap = cap;
        }
        let per_frame = n.div_ceil(self.cap).max(1);
        let want = (self.settings.frames_in_flight * per_frame).max(2);
        let words = self.cap * self.cols.words();
        while self.allocated < want {
            // Page-locked memory may be refused (hundreds of GB asked, or a limit): then plain
            // memory, which a GPU copies into at a lower rate.
            let buf = match backend.chunk_memory(words) {
                Ok(b) => b,
                Err(e) => {
                    if !self.warned {
                        eprintln!(
                            "warning: frame chunks in plain memory ({e}): the copies from the \
                             device are slower; --frame-chunk or --frames-in-flight 0 ask for less"
                        );
                        self.warned = true;
                    }
                    let mut v: Vec<u32> = Vec::new();
                    v.try_reserve_exact(words).map_err(|_| {
                        anyhow!(
                            "cannot allocate {:.1} MB of frame chunk memory: lower \
                             --frame-chunk or --frames-in-flight",
                            words as f64 * 4e-6
                        )
                    })?;
                    v.resize(words, 0);
                    Box::new(v)
                }
            };
            self.free.push(FrameChunk {
                start: 0,
                len: 0,
                cap: self.cap,
                cols: self.cols,
                buf,
            });
            self.allocated += 1;
        }
        Ok(())
    }

    /// Write frame `frame`, `files` (final paths and formats), from the backend's current state.
    /// Returns once the columns are copied (or, with `frames_in_flight = 0`, the files
    /// written); reports the error of an earlier frame.
    pub fn write_frame(
        &mut self,
        backend: &mut dyn Backend,
        files: Vec<(PathBuf, StreamFormat)>,
        frame: u64,
    ) -> Result<()> {
        self.poll()?;
        while self.in_flight >= self.settings.frames_in_flight.max(1) {
            self.wait_one()?;
        }
        let n = backend.num_particles();
        self.ensure_pool(backend, n)?;
        let tx = self
            .to_writer
            .as_ref()
            .ok_or_else(|| anyhow!("the frame writer is closed"))?;
        tx.send(Msg::Begin(files, n))
            .map_err(|_| anyhow!("the frame writer thread stopped"))?;
        self.in_flight += 1;
        let t = Instant::now();
        let mut sink = Sink {
            tx,
            free: &mut self.free,
            free_rx: &self.free_rx,
            cols: self.cols,
            wait: 0.0,
        };
        let exported = backend.export_frame(&mut sink);
        let wait = sink.wait;
        self.stats.wait_seconds += wait;
        self.stats.copy_seconds += t.elapsed().as_secs_f64() - wait;
        self.stats.copied_bytes += (n * self.cols.words() * 4) as u64;
        match exported {
            Ok(()) => tx.send(Msg::End),
            Err(_) => tx.send(Msg::Abort),
        }
        .map_err(|_| anyhow!("the frame writer thread stopped"))?;
        if let Err(e) = exported {
            // The frame is abandoned (its temporary files removed); an earlier writer error,
            // which may be the cause ("the writer stopped"), comes first.
            let mut first = None;
            while self.in_flight > 0 {
                if let Err(w) = self.wait_one() {
                    first = first.or(Some(w));
                }
            }
            let e = anyhow!("cannot read frame {frame} from the backend: {e}");
            return Err(match first {
                Some(w) if !w.to_string().contains("frame abandoned") => w.context(e),
                _ => e,
            });
        }
        if self.settings.frames_in_flight == 0 {
            self.flush()?;
        }
        Ok(())
    }

    /// Wait for every frame in flight and stop the writer; the totals.
    pub fn finish(mut self) -> Result<StreamStats> {
        self.flush()?;
        self.stop();
        Ok(self.stats)
    }

    fn stop(&mut self) {
        self.to_writer = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Stops the writer (after an error elsewhere): the frame being written is dropped, its
/// temporary files removed.
impl Drop for FrameStreamer {
    fn drop(&mut self) {
        if let Some(tx) = &self.to_writer {
            let _ = tx.send(Msg::Abort);
        }
        self.stop();
    }
}

/// The chunk sink of one export: free buffers out, filled ones to the writer.
struct Sink<'a> {
    tx: &'a Sender<Msg>,
    free: &'a mut Vec<FrameChunk>,
    free_rx: &'a Receiver<FrameChunk>,
    cols: FrameColumns,
    wait: f64,
}

impl ChunkSink for Sink<'_> {
    fn columns(&self) -> FrameColumns {
        self.cols
    }

    fn take(&mut self) -> Result<FrameChunk, SimError> {
        while let Ok(c) = self.free_rx.try_recv() {
            self.free.push(c);
        }
        if let Some(c) = self.free.pop() {
            return Ok(c);
        }
        let t = Instant::now();
        let c = self
            .free_rx
            .recv()
            .map_err(|_| SimError::Backend("the frame writer thread stopped".into()));
        self.wait += t.elapsed().as_secs_f64();
        c
    }

    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError> {
        self.tx
            .send(Msg::Chunk(chunk))
            .map_err(|_| SimError::Backend("the frame writer thread stopped".into()))
    }
}

/// The writer thread: files of one frame at a time; every chunk goes back to the pool, also
/// after an error (the main thread never waits forever for a buffer).
fn writer(
    rx: Receiver<Msg>,
    free: Sender<FrameChunk>,
    done: Sender<Done>,
    derived: Derived,
    models: Vec<Model>,
) {
    // The frame's files and the seconds spent on them (encoding, writing, syncing; not the
    // waits for chunks).
    let mut current: Option<(Result<FrameFiles>, f64)> = None;
    let named = |(path, e): (PathBuf, std::io::Error)| {
        anyhow!(e).context(format!("writing {}", path.display()))
    };
    for msg in rx {
        let t = Instant::now();
        let busy = || t.elapsed().as_secs_f64();
        match msg {
            Msg::Begin(files, n) => {
                let ff = FrameFiles::create(&files, n, derived, models.clone()).map_err(named);
                current = Some((ff, busy()));
            }
            Msg::Chunk(chunk) => {
                // After an error the frame's chunks are only given back.
                current = match current.take() {
                    Some((Ok(ff), s)) => {
                        let r = ff_write(ff, &chunk).map_err(named);
                        Some((r, s + busy()))
                    }
                    other => other,
                };
                let _ = free.send(chunk);
            }
            Msg::End => {
                if let Some((ff, s)) = current.take() {
                    let r = ff.and_then(|ff| ff.finish().map_err(named));
                    let _ = done.send(r.map(|bytes| (bytes, s + busy())));
                }
            }
            Msg::Abort => {
                // Dropping the files removes their temporary names.
                if current.take().is_some() {
                    let _ = done.send(Err(anyhow!("frame abandoned")));
                }
            }
        }
    }
}

/// Append `chunk` to the files (consumed and dropped on error: temporary files removed).
fn ff_write(
    mut ff: FrameFiles,
    chunk: &FrameChunk,
) -> Result<FrameFiles, (PathBuf, std::io::Error)> {
    ff.write_chunk(chunk)?;
    Ok(ff)
}

/// One line of totals: bytes, copy rate, write rate, time waited.
pub fn describe(s: &StreamStats) -> String {
    let rate = |b: u64, t: f64| b as f64 / t.max(1e-9);
    format!(
        "{} frames, {:.3} GB written at {:.0} MB/s (writer thread, {:.2} s), columns copied \
         at {:.2} GB/s ({:.3} GB in {:.2} s), steps waited {:.2} s for the writer",
        s.frames,
        s.written_bytes as f64 / 1e9,
        rate(s.written_bytes, s.write_seconds) / 1e6,
        s.write_seconds,
        rate(s.copied_bytes, s.copy_seconds) / 1e9,
        s.copied_bytes as f64 / 1e9,
        s.copy_seconds,
        s.wait_seconds,
    )
}
