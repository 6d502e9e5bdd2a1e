//! Output folders, protected: one run at a time (a lock), one run per folder (a marker naming
//! the scene; another run's files are refused unless `--overwrite` removes them first), stale
//! temporary files of a killed run removed, frames after a resumed checkpoint superseded.
//!
//! The lock is an advisory `flock` on `OUT/.rtmpm.lock`, held by the open file: the system
//! releases it when the process ends in any way (even SIGKILL), so a lock is never stale.

use anyhow::{Context, Result, bail};
use rtmpm_io::checkpoint::Fnv1a64;
use rtmpm_io::signature::{Signature, signature_of_file};
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

    /// The files of this folder with rtmpm's names, split into those rtmpm can prove it wrote
    /// (see [`OutDir::proven`]) and the others.
    fn sort_files(&self, pick: impl Fn(RunFile) -> bool) -> Result<(Vec<String>, Vec<String>)> {
        let has_marker = self.dir.join(RUN_FILE).is_file();
        let (mut ours, mut others) = (Vec::new(), Vec::new());
        for (name, kind) in self.run_files()? {
            if !pick(kind) {
                continue;
            }
            if self.proven(&name, has_marker) {
                ours.push(name);
            } else {
                others.push(name);
            }
        }
        Ok((ours, others))
    }

    /// True when rtmpm can prove it wrote `name`: the run marker itself, a regular file
    /// carrying rtmpm's signature (`rtmpm_io::signature`), or a file of a format that
    /// carries none (BGEO, MP4) in a folder holding a run marker (`has_marker`).
    fn proven(&self, name: &str, has_marker: bool) -> bool {
        let path = self.dir.join(name);
        let is_file = fs::symlink_metadata(&path).is_ok_and(|m| m.is_file());
        if !is_file {
            return false;
        }
        if name == RUN_FILE {
            return true;
        }
        match signature_of_file(&path) {
            Ok(Signature::Rtmpm) => true,
            Ok(Signature::Unsigned) => has_marker,
            Ok(Signature::Absent) | Err(_) => false,
        }
    }

    /// Remove the files `names` of this folder.
    fn remove(&self, names: &[String]) -> Result<usize> {
        for name in names {
            let path = self.dir.join(name);
            fs::remove_file(&path).with_context(|| format!("cannot remove {}", path.display()))?;
        }
        Ok(names.len())
    }

    /// Prepare the folder for a fresh run of the scene `identity`: a folder holding another
    /// run's files is refused unless `overwrite`, which removes them first, and only those rtmpm
    /// can prove it wrote; files with rtmpm's names that it cannot prove it wrote are never
    /// removed (the run is refused while they are there).
    pub fn start_fresh(&self, identity: &str, overwrite: bool) -> Result<()> {
        let (ours, others) = self.sort_files(|_| true)?;
        if !others.is_empty() {
            bail!(
                "output folder {} holds {} with rtmpm's names that rtmpm cannot prove it wrote \
                 (no rtmpm signature in them): {}; they are kept, and a run here would replace \
                 them.\n  fix: move them away or remove them yourself, or choose another folder \
                 with --out",
                self.dir.display(),
                files(others.len()),
                list_names(&others)
            );
        }
        if !ours.is_empty() {
            if !overwrite {
                // Resuming is advice only where there is a checkpoint to resume from.
                let resume = if ours.iter().any(|n| n.starts_with("checkpoint_")) {
                    format!(
                        ", or continue that run with --resume {}/checkpoint_NNNNN.ckpt",
                        self.dir.display()
                    )
                } else {
                    String::new()
                };
                bail!(
                    "output folder {} already holds the files of a run ({}): {}: {}; they are \
                     kept.\n  fix: rerun with --overwrite to remove them first, or choose \
                     another folder with --out{resume}",
                    self.dir.display(),
                    self.marker().unwrap_or_else(|| "scene unknown".into()),
                    files(ours.len()),
                    list_names(&ours),
                );
            }
            let n = self.remove(&ours)?;
            eprintln!(
                "--overwrite: removed {} of the previous run in {}: {}",
                files(n),
                self.dir.display(),
                list_names(&ours)
            );
        }
        self.write_marker(identity)
    }

    /// Prepare the folder for resuming the run `identity` after frame `frame`: a folder
    /// holding another scene's run is refused unless `overwrite` (which removes its frames,
    /// not its checkpoints, and only files rtmpm can prove it wrote); frames after `frame` are
    /// removed (the resumed run writes them again). Files with rtmpm's names it cannot prove
    /// it wrote, among those it would remove or write, refuse the resume.
    pub fn start_resume(&self, identity: &str, frame: u64, overwrite: bool) -> Result<()> {
        let files_here = self.run_files()?;
        let foreign = match self.marker() {
            Some(m) => m != identity,
            None => !files_here.is_empty(),
        };
        if foreign && !files_here.is_empty() {
            let (ours, others) =
                self.sort_files(|k| matches!(k, RunFile::Frame(_) | RunFile::Other))?;
            if !overwrite {
                bail!(
                    "output folder {} holds the files of another run ({}), not of the \
                     checkpoint's scene ({identity}); they are kept.\n  fix: choose another \
                     folder with --out, or rerun with --overwrite to remove its frames first \
                     ({}: {})",
                    self.dir.display(),
                    self.marker().unwrap_or_else(|| "scene unknown".into()),
                    files(ours.len()),
                    list_names(&ours)
                );
            }
            if !others.is_empty() {
                bail!(
                    "output folder {} holds {} with rtmpm's names that rtmpm cannot prove it \
                     wrote: {}; they are kept.\n  fix: move them away, or choose another folder \
                     with --out",
                    self.dir.display(),
                    files(others.len()),
                    list_names(&others)
                );
            }
            let n = self.remove(&ours)?;
            eprintln!(
                "--overwrite: removed {} of the previous run in {}: {}",
                files(n),
                self.dir.display(),
                list_names(&ours)
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
            let (later, others) =
                self.sort_files(|k| matches!(k, RunFile::Frame(f) if f > frame))?;
            if !others.is_empty() {
                bail!(
                    "output folder {} holds {} after frame {frame} with rtmpm's names that \
                     rtmpm cannot prove it wrote: {}; the resumed run would replace them, so \
                     they are kept and the run is refused.\n  fix: move them away, or choose \
                     another folder with --out",
                    self.dir.display(),
                    files(others.len()),
                    list_names(&others)
                );
            }
            let n = self.remove(&later)?;
            if n > 0 {
                eprintln!(
                    "removed {} after frame {frame} in {} (the resumed run writes them again): \
                     {}",
                    files(n),
                    self.dir.display(),
                    list_names(&later)
                );
            }
        }
        self.write_marker(identity)
    }
}

/// "1 file" or "N files".
fn files(n: usize) -> String {
    if n == 1 {
        "1 file".into()
    } else {
        format!("{n} files")
    }
}

/// Every name of `names` (rtmpm's names), runs of consecutive frame numbers written as one
/// range: `frame_00000.ply .. frame_00120.ply (121 files), checkpoint_00010.ckpt, frames.pvd`.
pub fn list_names(names: &[String]) -> String {
    // (prefix, extension) -> numbers; the other names as they are.
    let mut numbered: Vec<((String, String), Vec<u64>)> = Vec::new();
    let mut plain = Vec::new();
    for name in names {
        let split = name.split_once('.').and_then(|(stem, ext)| {
            let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
            let (prefix, num) = stem.split_at(stem.len() - digits);
            (digits == 5 && prefix.ends_with('_'))
                .then(|| num.parse::<u64>().ok().map(|n| (prefix, ext, n)))
                .flatten()
        });
        match split {
            Some((prefix, ext, n)) => {
                let key = (prefix.to_string(), ext.to_string());
                match numbered.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, v)) => v.push(n),
                    None => numbered.push((key, vec![n])),
                }
            }
            None => plain.push(name.clone()),
        }
    }
    let mut parts = Vec::new();
    for ((prefix, ext), mut nums) in numbered {
        nums.sort_unstable();
        let name = |n: u64| format!("{prefix}{n:05}.{ext}");
        let mut i = 0;
        while i < nums.len() {
            let mut j = i;
            while j + 1 < nums.len() && nums[j + 1] == nums[j] + 1 {
                j += 1;
            }
            parts.push(match j - i {
                0 => name(nums[i]),
                1 => format!("{}, {}", name(nums[i]), name(nums[j])),
                k => format!("{} .. {} ({} files)", name(nums[i]), name(nums[j]), k + 1),
            });
            i = j + 1;
        }
    }
    parts.extend(plain);
    parts.join(", ")
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
