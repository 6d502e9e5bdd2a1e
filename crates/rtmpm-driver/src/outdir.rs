//! Output folders, protected: one run at a time (a lock), one run per folder (a marker naming
//! the scene; another run's files are refused unless `--overwrite` removes them first), stale
//! temporary files of a killed run removed, frames after a resumed checkpoint superseded.
//!
//! The lock is an advisory `flock` on `OUT/.rtmpm.lock`, held by the open file: the system
//! releases it when the process ends in any way (even SIGKILL), so a lock is never stale.

use anyhow::{Context, Result, bail};
use rtmpm_io::checkpoint::Fnv1a64;
use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Name of the lock file in an output folder.
pub const LOCK_FILE: &str = ".rtmpm.lock";
/// Name of the marker saying which scene's run a folder holds.
pub const RUN_FILE: &str = ".rtmpm-run";

/// A scene's identity: its name and a hash of its text (the text a checkpoint carries, so a
/// resumed run has the identity of the run it continues).
pub fn scene_identity(name: &str, text: &str) -> String {
    let mut h = Fnv1a64::default();
    h.update(text.as_bytes());
    format!("{name} {:016x}", h.finish())
}

/// What a run's file is, from its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunFile {
    /// `frame_NNNNN.EXT` (a frame format's extension, or `png`) or
    /// `surface_NNNNN.obj|ply|vtu|usda`, with its number.
    Frame(u64),
    /// `checkpoint_NNNNN.ckpt`.
    Checkpoint(u64),
    /// `frames.pvd`, `surface.pvd`, `movie.gif`, `movie.mp4`, the run marker.
    Other,
}

/// Classify a file name of an output folder; `None` for files rtmpm does not write.
pub fn classify(name: &str) -> Option<RunFile> {
    let number = |s: &str, prefix: &str, exts: &[&str]| -> Option<u64> {
        let rest = s.strip_prefix(prefix)?;
        let (num, ext) = rest.split_once('.')?;
        if !exts.contains(&ext) || num.is_empty() || !num.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        num.parse().ok()
    };
    let frame_exts: Vec<&str> = rtmpm_io::FRAME_FORMATS
        .iter()
        .map(|f| f.extension)
        .chain(["png"])
        .collect();
    if let Some(n) = number(name, "frame_", &frame_exts)
        .or_else(|| number(name, "surface_", &["obj", "ply", "vtu", "usda"]))
    {
        return Some(RunFile::Frame(n));
    }
    if let Some(n) = number(name, "checkpoint_", &["ckpt"]) {
        return Some(RunFile::Checkpoint(n));
    }
    match name {
        "frames.pvd" | "surface.pvd" | "movie.gif" | "movie.mp4" | "bodies.csv" | RUN_FILE => {
            Some(RunFile::Other)
        }
        _ => None,
    }
}

/// A temporary file of an atomic write (`.NAME.tmp-PID`, see `rtmpm_io::atomic`).
fn is_temp(name: &str) -> bool {
    name.starts_with('.')
        && name
            .rsplit_once(".tmp-")
            .is_some_and(|(_, pid)| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}

/// An output folder held by this process: the lock lasts as long as the value.
pub struct OutDir {
    pub dir: PathBuf,
    _lock: File,
}

impl OutDir {
    /// Create `dir` if needed and take its lock; a folder locked by another rtmpm process is
    /// an error naming it. Temporary files left by a killed run are removed (nothing else can
    /// be writing them while the lock is held).
    pub fn lock(dir: &Path, what: &str) -> Result<OutDir> {
        fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("cannot open the lock file {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(fs::TryLockError::WouldBlock) => {
                let holder = fs::read_to_string(&path).unwrap_or_default();
                bail!(
                    "output folder {} is in use by another rtmpm process ({}); wait for it to \
                     end, or choose another folder with --out",
                    dir.display(),
                    holder.trim()
                );
            }
            Err(fs::TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("cannot lock {}", path.display()));
            }
        }
        file.set_len(0)?;
        let _ = writeln!(file, "{what}, pid {}", std::process::id());
        let out = OutDir {
            dir: dir.to_path_buf(),
            _lock: file,
        };
        let stale = out.remove_where(is_temp)?;
        if stale > 0 {
            eprintln!(
                "removed {stale} temporary file(s) left in {} by an interrupted run",
                dir.display()
            );
        }
        Ok(out)
    }

    /// Names of the files of this folder that a run writes.
    fn run_files(&self) -> Result<Vec<(String, RunFile)>> {
        let mut v = Vec::new();
        for e in fs::read_dir(&self.dir)
            .with_context(|| format!("cannot list {}", self.dir.display()))?
        {
            let name = e?.file_name();
            if let Some(name) = name.to_str()
                && let Some(kind) = classify(name)
            {
                v.push((name.to_string(), kind));
            }
        }
        v.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(v)
    }

    /// Remove the files whose name satisfies `pred`; returns how many.
    fn remove_where(&self, pred: impl Fn(&str) -> bool) -> Result<usize> {
        let mut n = 0;
        for e in fs::read_dir(&self.dir)
            .with_context(|| format!("cannot list {}", self.dir.display()))?
        {
            let e = e?;
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            if pred(name) && e.file_type().is_ok_and(|t| t.is_file()) {
                fs::remove_file(e.path())
                    .with_context(|| format!("cannot remove {}", e.path().display()))?;
                n += 1;
            }
        }
        Ok(n)
    }

    fn marker(&self) -> Option<String> {
        rtmpm_io::read_text_bounded(&self.dir.join(RUN_FILE), 4096, "run marker")
            .ok()
            .map(|s| s.trim().to_string())
    }

    fn write_marker(&self, identity: &str) -> Result<()> {
        rtmpm_io::write_atomic(&self.dir.join(RUN_FILE), format!("{identity}\n").as_bytes())
            .with_context(|| format!("writing {}", self.dir.join(RUN_FILE).display()))
    }

    /// Prepare the folder for a fresh run of the scene `identity`: a folder holding another
    /// run's files is refused unless `overwrite`, which removes them (and only them) first.
    pub fn start_fresh(&self, identity: &str, overwrite: bool) -> Result<()> {
        let files = self.run_files()?;
        if !files.is_empty() {
            if !overwrite {
                bail!(
                    "output folder {} already holds the files of a run ({}: {} file(s), e.g. \
                     {}); they are kept.\n  fix: rerun with --overwrite to remove them first, \
                     choose another folder with --out, or continue that run with --resume \
                     {}/checkpoint_NNNNN.ckpt",
                    self.dir.display(),
                    self.marker().unwrap_or_else(|| "scene unknown".into()),
                    files.len(),
                    files[0].0,
                    self.dir.display()
                );
            }
            let n = self.remove_where(|name| classify(name).is_some())?;
            eprintln!(
                "--overwrite: removed {n} file(s) of the previous run in {}",
                self.dir.display()
            );
        }
        self.write_marker(identity)
    }

    /// Prepare the folder for resuming the run `identity` after frame `frame`: a folder
    /// holding another scene's run is refused unless `overwrite` (which removes its frames,
    /// not its checkpoints); frames after `frame` are removed (the resumed run writes them
    /// again).
    pub fn start_resume(&self, identity: &str, frame: u64, overwrite: bool) -> Result<()> {
        let files = self.run_files()?;
        let foreign = match self.marker() {
            Some(m) => m != identity,
            None => !files.is_empty(),
        };
        if foreign && !files.is_empty() {
            if !overwrite {
                bail!(
                    "output folder {} holds the files of another run ({}), not of the \
                     checkpoint's scene ({identity}); they are kept.\n  fix: choose another \
                     folder with --out, or rerun with --overwrite to remove its frames first",
                    self.dir.display(),
                    self.marker().unwrap_or_else(|| "scene unknown".into())
                );
            }
            let n = self.remove_where(|name| {
                matches!(classify(name), Some(RunFile::Frame(_) | RunFile::Other))
            })?;
            eprintln!(
                "--overwrite: removed {n} file(s) of the previous run in {}",
                self.dir.display()
            );
        } else {
            // frames.pvd and surface.pvd are continued by the run: one that cannot be read
            // stops the resume here, before anything is removed.
            for pvd in ["frames.pvd", "surface.pvd"].map(|n| self.dir.join(n)) {
                if !pvd.exists() {
                    continue;
                }
                let text = rtmpm_io::read_text_bounded(
                    &pvd,
                    rtmpm_io::limits::PVD_MAX_BYTES,
                    "ParaView collection",
                )
                .map_err(anyhow::Error::from)
                .and_then(|t| rtmpm_io::vtu::parse_pvd(&t).map_err(anyhow::Error::from));
                if let Err(e) = text {
                    bail!(
                        "cannot continue {}: {e:#} (the frames themselves are intact); move it \
                         away to start a new collection from the resumed frames",
                        pvd.display()
                    );
                }
            }
            let n = self.remove_where(
                |name| matches!(classify(name), Some(RunFile::Frame(f)) if f > frame),
            )?;
            if n > 0 {
                eprintln!(
                    "removed {n} frame file(s) after frame {frame} in {} (the resumed run \
                     writes them again)",
                    self.dir.display()
                );
            }
        }
        self.write_marker(identity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(classify("frame_00012.ply"), Some(RunFile::Frame(12)));
        assert_eq!(classify("frame_00012.png"), Some(RunFile::Frame(12)));
        assert_eq!(
            classify("checkpoint_00002.ckpt"),
            Some(RunFile::Checkpoint(2))
        );
        assert_eq!(classify("frames.pvd"), Some(RunFile::Other));
        assert_eq!(classify("surface.pvd"), Some(RunFile::Other));
        assert_eq!(classify("frame_00003.bgeo.gz"), Some(RunFile::Frame(3)));
        assert_eq!(classify("frame_00003.usda"), Some(RunFile::Frame(3)));
        assert_eq!(classify("surface_00004.obj"), Some(RunFile::Frame(4)));
        assert_eq!(classify("surface_00004.vtu"), Some(RunFile::Frame(4)));
        for other in [
            "frame_.ply",
            "frame_1.txt",
            "notes.md",
            "frame_1a.ply",
            "frame_1.gz",
            "surface_1.png",
            ".rtmpm.lock",
        ] {
            assert_eq!(classify(other), None, "{other}");
        }
        assert!(is_temp(".frame_00001.ply.tmp-1234"));
        assert!(!is_temp("frame_00001.ply") && !is_temp(".x.tmp-") && !is_temp(".rtmpm.lock"));
        assert_ne!(scene_identity("a", "x"), scene_identity("a", "y"));
    }
}
