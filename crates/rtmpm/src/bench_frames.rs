//! `rtmpm bench --frame-write DIR`: the cost of writing frames ([`rtmpm_driver::stream`]): the rate of
//! the chunked copy of a frame's columns out of the backend (device to host on a GPU), the
//! rate of encoding and writing the files (disk, synced), and the step time with and without a
//! frame being written in the background. The files are removed after each timing.

use anyhow::{Result, bail};
use rtmpm_driver::stream::{FrameStreamer, StreamSettings, StreamStats};
use rtmpm_io::chunks::{FrameChunk, FrameColumns};
use rtmpm_io::stream::{Derived, FrameFiles, StreamFormat};
use rtmpm_sim::{Backend, ChunkSink, SimError};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The formats of `--frame-formats`, comma separated: frame formats that can be streamed
/// (`ply`, `bgeo`, `bgeo.gz`).
pub fn parse_formats(list: &str) -> Result<Vec<(String, StreamFormat)>> {
    let mut out = Vec::new();
    for f in list.split(',').map(str::trim).filter(|f| !f.is_empty()) {
        let streamable = || {
            let names: Vec<&str> = rtmpm_io::FRAME_FORMATS
                .iter()
                .filter(|f| f.streamable())
                .map(|f| f.name)
                .collect();
            names.join(", ")
        };
        let Some(fmt) = rtmpm_io::frame_format(f).and_then(|f| StreamFormat::new(f, vec![])) else {
            bail!("unknown frame format `{f}`: use {}", streamable())
        };
        out.push((f.to_string(), fmt));
    }
    if out.is_empty() {
        bail!("--frame-formats names no format");
    }
    Ok(out)
}

/// Takes the chunks and gives them straight back: the copy alone.
struct Discard {
    cols: FrameColumns,
    free: Vec<FrameChunk>,
}

impl ChunkSink for Discard {
    fn columns(&self) -> FrameColumns {
        self.cols
    }
    fn take(&mut self) -> Result<FrameChunk, SimError> {
        self.free
            .pop()
            .ok_or_else(|| SimError::Backend("no free chunk".into()))
    }
    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError> {
        self.free.push(chunk);
        Ok(())
    }
}

/// Run the frame-writing benchmark on `backend` (already warmed up) at time step `dt`: `steps`
/// steps per timing, files into `dir`. Its parts: the copy out alone ([`copy_out`]), the
/// streamed write with the step waiting ([`FrameBench::streamed`]), the whole-frame path for
/// comparison ([`FrameBench::whole_frame`], with `whole`), the steps alone and with a frame
/// written in the background ([`FrameBench::steps_beside_a_frame`]).
pub fn frame_write_bench(
    backend: &mut dyn Backend,
    dt: f32,
    steps: u64,
    dir: &Path,
    formats: &str,
    chunk: usize,
    whole: bool,
) -> Result<()> {
    let formats = parse_formats(formats)?;
    std::fs::create_dir_all(dir)?;
    let n = backend.num_particles();
    let bench = FrameBench {
        dir,
        formats: formats.iter().map(|f| f.1.clone()).collect(),
        chunk,
    };
    let cols = FrameFiles::columns(&bench.formats, Derived::default());
    let frame_bytes = (n * cols.words() * 4) as f64;
    let names: Vec<&str> = formats.iter().map(|f| f.0.as_str()).collect();
    println!(
        "  frame write  {} into {}: {n} particles, {} words each ({:.3} GB of columns), \
         chunks of {chunk}",
        names.join(" + "),
        dir.display(),
        cols.words(),
        frame_bytes / 1e9
    );
    copy_out(backend, cols, chunk.max(1).min(n.max(1)), frame_bytes)?;
    let written = bench.streamed(backend)?;
    if whole {
        bench.whole_frame(backend, written)?;
    }
    bench.steps_beside_a_frame(backend, dt, steps)
}

/// The copy alone, through two chunk buffers of `cap` particles: best of 3.
fn copy_out(
    backend: &mut dyn Backend,
    cols: FrameColumns,
    cap: usize,
    frame_bytes: f64,
) -> Result<()> {
    let mut sink = Discard {
        cols,
        free: Vec::new(),
    };
    for _ in 0..2 {
        sink.free.push(FrameChunk {
            start: 0,
            len: 0,
            cap,
            cols,
            buf: backend.chunk_memory(cap * cols.words())?,
        });
    }
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        backend.export_frame(&mut sink)?;
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "    copy out   {:.2} GB/s ({:.1} ms a frame, best of 3; device to host on a GPU)",
        frame_bytes / best / 1e9,
        best * 1e3
    );
    Ok(())
}

/// The formats and files of the frame-writing benchmark.
struct FrameBench<'a> {
    dir: &'a Path,
    formats: Vec<StreamFormat>,
    chunk: usize,
}

impl FrameBench<'_> {
    /// The files of frame `frame`, one per format.
    fn files(&self, frame: u64) -> Vec<(PathBuf, StreamFormat)> {
        (self.formats.iter())
            .map(|f| (self.dir.join(f.format.file_name(frame)), f.clone()))
            .collect()
    }

    /// The streamer's settings with `in_flight` frames written in the background.
    fn settings(&self, in_flight: usize) -> StreamSettings {
        StreamSettings {
            chunk: self.chunk,
            frames_in_flight: in_flight,
            derived: Derived::default(),
            models: Vec::new(),
        }
    }

    /// The streamed write: copy, encode and write, the step waiting for the files (two chunk buffers). Returns
    /// the bytes written.
    fn streamed(&self, backend: &mut dyn Backend) -> Result<u64> {
        let mut s = FrameStreamer::new(self.settings(0), &self.formats)?;
        let t = Instant::now();
        s.write_frame(backend, self.files(0), 0)?;
        let sync_wall = t.elapsed().as_secs_f64();
        let st = s.finish()?;
        // The files are not kept (a frame of 500M particles is 16 GB of PLY).
        remove(&self.files(0));
        println!(
            "    write      {:.0} MB/s of file bytes before gzip ({:.3} GB in {:.2} s, encoded and \
             written by the writer thread, synced); whole frame {:.2} s with the step waiting",
            st.written_bytes as f64 / st.write_seconds.max(1e-9) / 1e6,
            st.written_bytes as f64 / 1e9,
            st.write_seconds,
            sync_wall
        );
        Ok(st.written_bytes)
    }

    /// The whole-frame path, for comparison: every field of every particle to the host,
    /// then each file written from it, in this thread (`written`: the streamed files' bytes).
    fn whole_frame(&self, backend: &mut dyn Backend, written: u64) -> Result<()> {
        let t = Instant::now();
        let mut p = rtmpm_physics::Particles::default();
        backend.read_particles(&mut p)?;
        let read = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let frame = rtmpm_io::frame::Frame {
            particles: &p,
            fields: rtmpm_io::FrameFields::default(),
            comments: &[],
            bodies: &[],
            compress: true,
        };
        for f in &self.formats {
            let path = self.dir.join(format!("whole_00000.{}", f.format.extension));
            (f.format.write)(&path, &frame)?;
            let _ = std::fs::remove_file(&path);
        }
        let write = t.elapsed().as_secs_f64();
        println!(
            "    whole      before streaming: read_particles {:.1} ms (every field), files {:.2} s \
             ({:.0} MB/s of the same bytes before gzip), {:.2} s with the step waiting",
            read * 1e3,
            write,
            written as f64 / write.max(1e-9) / 1e6,
            read + write
        );
        Ok(())
    }

    /// The steps: `steps` steps of `dt` alone, then with a frame written in the background.
    fn steps_beside_a_frame(&self, backend: &mut dyn Backend, dt: f32, steps: u64) -> Result<()> {
        let mut t_sim = 0.0f32;
        let mut run = |b: &mut dyn Backend| -> Result<f64> {
            let t = Instant::now();
            for _ in 0..steps {
                b.step(dt, t_sim)?;
                t_sim += dt;
            }
            if let Some(bad) = b.check()? {
                bail!("the benchmark blew up (particle {})", bad.index);
            }
            Ok(t.elapsed().as_secs_f64())
        };
        let alone = run(backend)?;
        let mut s = FrameStreamer::new(self.settings(1), &self.formats)?;
        let t = Instant::now();
        s.write_frame(backend, self.files(1), 1)?;
        let boundary = t.elapsed().as_secs_f64();
        let with = run(backend)?;
        let t = Instant::now();
        let st: StreamStats = s.finish()?;
        let tail = t.elapsed().as_secs_f64();
        remove(&self.files(1));
        let ms = |s: f64| 1e3 * s / steps.max(1) as f64;
        println!(
            "    steps      {:.3} ms/step alone, {:.3} ms/step while a frame is written in the \
             background ({:+.1} %); the frame boundary took {:.1} ms (copy), the writer {:.2} s, \
             of which {:.2} s after the {steps} steps",
            ms(alone),
            ms(with),
            100.0 * (with / alone.max(1e-12) - 1.0),
            boundary * 1e3,
            st.write_seconds,
            tail
        );
        Ok(())
    }
}

fn remove(files: &[(PathBuf, StreamFormat)]) {
    for (path, _) in files {
        let _ = std::fs::remove_file(path);
    }
}
