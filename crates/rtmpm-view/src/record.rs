//! Recording what a session shows: every displayed frame into an animated GIF (the CPU
//! renderer's writer) or an MP4 (through `ffmpeg` on the PATH), encoded on a thread of its own.
//! The session waits for the recorder when it falls [`QUEUE`] frames behind: a recording
//! keeps every frame.
//!
//! The file is written under a temporary name beside the target and renamed when complete;
//! an existing file is not replaced unless asked.

use crate::frame::Frame;
use rtmpm_render::{GifMovie, Image};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

/// Frames waiting for the encoder at most.
pub const QUEUE: usize = 4;

/// Largest side of a GIF recording (pixels): GIF frames are quantised, slow and large.
pub const GIF_MAX_WIDTH: u32 = 640;

/// The kind of movie, from the file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Gif,
    Mp4,
}

impl Format {
    /// `.gif` or `.mp4` (any case); anything else is refused with the choices.
    pub fn of(path: &Path) -> Result<Format, String> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("gif") => Ok(Format::Gif),
            Some("mp4") => Ok(Format::Mp4),
            _ => Err(format!(
                "cannot record to `{}`: give a file ending in .gif or .mp4",
                path.display()
            )),
        }
    }
}

/// True when `ffmpeg -version` runs.
pub fn ffmpeg_available() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Records the frames it is given; [`Recorder::finish`] writes the file.
pub struct Recorder {
    tx: SyncSender<Arc<Frame>>,
    handle: JoinHandle<Result<String, String>>,
}

impl Recorder {
    /// A recorder into `path` at `fps` frames per second. Checks first: the extension, that
    /// the folder exists, that `path` does not (unless `overwrite`), ffmpeg for MP4.
    pub fn start(path: &Path, fps: f32, overwrite: bool) -> Result<Recorder, String> {
        let format = Format::of(path)?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !dir.is_dir() {
            return Err(format!(
                "cannot record to `{}`: the folder `{}` does not exist",
                path.display(),
                dir.display()
            ));
        }
        // Only a file is replaced: a folder, a device or a pipe of that name is refused before
        // the run (its recording could not be moved there at the end).
        if let Ok(meta) = std::fs::metadata(path)
            && !meta.is_file()
        {
            return Err(format!(
                "cannot record to `{}`: it is a {}, not a file: give a new file's name",
                path.display(),
                if meta.is_dir() {
                    "folder"
                } else {
                    "device, pipe or other special file"
                }
            ));
        }
        if path.exists() && !overwrite {
            return Err(format!(
                "`{}` exists: choose another file for --record, or add --overwrite to replace it",
                path.display()
            ));
        }
        if format == Format::Mp4 && !ffmpeg_available() {
            return Err(format!(
                "recording `{}` needs ffmpeg on the PATH, which was not found: install it \
                 (e.g. `apt-get install ffmpeg`) or record a GIF (--record {})",
                path.display(),
                path.with_extension("gif").display()
            ));
        }
        let fps = if fps.is_finite() && fps > 0.0 {
            fps.min(120.0)
        } else {
            30.0
        };
        let (tx, rx) = sync_channel::<Arc<Frame>>(QUEUE);
        let path = path.to_path_buf();
        let handle = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || encode(rx, &path, format, fps))
            .map_err(|e| format!("cannot start the recorder's thread: {e}"))?;
        Ok(Recorder { tx, handle })
    }

    /// Queue a frame (waits while [`QUEUE`] frames are waiting); an error when the encoder
    /// has failed (its message).
    pub fn add(&self, frame: Arc<Frame>) -> Result<(), String> {
        self.tx
            .send(frame)
            .map_err(|_| "the recorder stopped (its error follows at the end)".to_string())
    }

    /// Encode what is queued and write the file; returns a summary line.
    pub fn finish(self) -> Result<String, String> {
        drop(self.tx);
        self.handle
            .join()
            .unwrap_or_else(|_| Err("the recorder's thread panicked".into()))
    }
}

/// The temporary file beside `path` that becomes it when complete.
fn partial(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.partial"))
}

/// The encoder's thread: every frame into the movie, then the file.
fn encode(
    rx: Receiver<Arc<Frame>>,
    path: &Path,
    format: Format,
    fps: f32,
) -> Result<String, String> {
    let Ok(first) = rx.recv() else {
        return Err(format!(
            "no frame to record: `{}` not written",
            path.display()
        ));
    };
    let (w, h) = (first.image.width, first.image.height);
    let tmp = partial(path);
    let frames = match format {
        Format::Gif => gif(&first, rx, &tmp, fps),
        Format::Mp4 => mp4(&first, rx, &tmp, fps),
    };
    let frames = match frames {
        Ok(n) => n,
        Err(e) => {
            // Ours: the temporary file this thread wrote.
            let _ = std::fs::remove_file(&tmp);
            return Err(format!("recording `{}` failed: {e}", path.display()));
        }
    };
    std::fs::rename(&tmp, path).map_err(|e| {
        format!(
            "cannot move the recording {} to {}: {e}",
            tmp.display(),
            path.display()
        )
    })?;
    Ok(format!(
        "{} ({frames} frames of {w}x{h} at {fps} frames/s)",
        path.display()
    ))
}

fn gif(first: &Frame, rx: Receiver<Arc<Frame>>, tmp: &Path, fps: f32) -> Result<usize, String> {
    let (w, h) = (first.image.width, first.image.height);
    let gw = w.min(GIF_MAX_WIDTH);
    let gh = ((h as u64 * gw as u64) / w.max(1) as u64).max(1) as u32;
    let mut movie = GifMovie::new(gw, gh, fps).map_err(|e| e.to_string())?;
    movie.add(&first.image).map_err(|e| e.to_string())?;
    for f in rx {
        movie.add(&f.image).map_err(|e| e.to_string())?;
    }
    movie.finish(tmp).map_err(|e| e.to_string())
}

/// An ffmpeg process reading raw RGB frames on its standard input.
struct Ffmpeg {
    child: Child,
    stdin: Option<ChildStdin>,
}

impl Ffmpeg {
    fn start(w: u32, h: u32, fps: f32, out: &Path) -> Result<Ffmpeg, String> {
        let mut child = Command::new("ffmpeg")
            .args([
                "-y",
                "-loglevel",
                "error",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
            ])
            .args([
                "-s",
                &format!("{w}x{h}"),
                "-r",
                &format!("{fps}"),
                "-i",
                "-",
            ])
            .args([
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                "-pix_fmt",
                "yuv420p",
            ])
            .args(["-f", "mp4"])
            .arg(out)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start ffmpeg: {e}"))?;
        let stdin = child.stdin.take();
        Ok(Ffmpeg { child, stdin })
    }

    fn write(&mut self, img: &Image) -> Result<(), String> {
        match self.stdin.as_mut() {
            Some(s) => s
                .write_all(&img.rgb)
                .map_err(|e| format!("ffmpeg stopped reading frames: {e}")),
            None => Err("ffmpeg has no input".into()),
        }
    }

    fn finish(mut self) -> Result<(), String> {
        drop(self.stdin.take());
        let out = self
            .child
            .wait_with_output()
            .map_err(|e| format!("waiting for ffmpeg: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "ffmpeg failed ({}): {}",
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            ))
        }
    }
}

fn mp4(first: &Frame, rx: Receiver<Arc<Frame>>, tmp: &Path, fps: f32) -> Result<usize, String> {
    let (w, h) = (first.image.width, first.image.height);
    let mut ff = Ffmpeg::start(w, h, fps, tmp)?;
    let mut n = 0;
    let mut write = |ff: &mut Ffmpeg, img: &Image| -> Result<(), String> {
        n += 1;
        if img.width == w && img.height == h {
            ff.write(img)
        } else {
            // The view was resized: the movie keeps its first size.
            ff.write(&img.resize(w, h))
        }
    };
    let mut result = write(&mut ff, &first.image);
    for f in rx {
        if result.is_ok() {
            result = write(&mut ff, &f.image);
        }
    }
    let done = ff.finish();
    result.and(done).map(|_| n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Status;

    fn frame(v: u8) -> Arc<Frame> {
        Arc::new(Frame {
            image: Image::new(64, 36, [v, 255 - v, 40]),
            status: Status::default(),
        })
    }

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("rtmpm-view-record-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_folder_of_the_recordings_name_is_refused_before_the_run_even_with_overwrite() {
        let d = scratch("folder");
        let path = d.join("movie.gif");
        std::fs::create_dir_all(&path).unwrap();
        for overwrite in [false, true] {
            let e = Recorder::start(&path, 10.0, overwrite).err().unwrap();
            assert!(e.contains("it is a folder"), "{e}");
        }
        assert!(path.is_dir());
    }

    #[test]
    fn a_gif_recording_has_every_frame_and_refuses_to_replace_a_file() {
        let d = scratch("gif");
        let path = d.join("movie.gif");
        let _ = std::fs::remove_file(&path);
        let r = Recorder::start(&path, 10.0, false).unwrap();
        for v in 0..7 {
            r.add(frame(v * 30)).unwrap();
        }
        let line = r.finish().unwrap();
        assert!(line.contains("7 frames of 64x36"), "{line}");
        let bytes = std::fs::read(&path).unwrap();
        let mut dec = gif::DecodeOptions::new()
            .read_info(std::io::Cursor::new(bytes))
            .unwrap();
        let mut n = 0;
        while dec.read_next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, 7);
        assert!(!partial(&path).exists());
        let e = Recorder::start(&path, 10.0, false).err().unwrap();
        assert!(e.contains("exists") && e.contains("--overwrite"), "{e}");
        assert!(Recorder::start(&path, 10.0, true).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn bad_recording_targets_are_refused_with_the_fix() {
        let e = Recorder::start(Path::new("movie.avi"), 10.0, false)
            .err()
            .unwrap();
        assert!(e.contains(".gif or .mp4"), "{e}");
        let e = Recorder::start(Path::new("/nonexistent-folder/m.gif"), 10.0, false)
            .err()
            .unwrap();
        assert!(e.contains("does not exist"), "{e}");
        if !ffmpeg_available() {
            let d = scratch("mp4");
            let e = Recorder::start(&d.join("m.mp4"), 10.0, false)
                .err()
                .unwrap();
            assert!(e.contains("ffmpeg") && e.contains(".gif"), "{e}");
        }
    }

    #[test]
    fn an_mp4_recording_is_written_when_ffmpeg_is_there() {
        if !ffmpeg_available() {
            eprintln!("no ffmpeg on the PATH: the MP4 path is not exercised here");
            return;
        }
        let d = scratch("mp4ok");
        let path = d.join("movie.mp4");
        let r = Recorder::start(&path, 10.0, true).unwrap();
        for v in 0..5 {
            r.add(frame(v * 40)).unwrap();
        }
        let line = r.finish().unwrap();
        assert!(line.contains("5 frames"), "{line}");
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[4..8], b"ftyp", "an MP4 file");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn no_frame_means_no_file() {
        let d = scratch("none");
        let path = d.join("empty.gif");
        let r = Recorder::start(&path, 10.0, true).unwrap();
        assert!(r.finish().unwrap_err().contains("no frame"));
        assert!(!path.exists());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
