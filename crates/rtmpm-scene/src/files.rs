//! The files a scene reads besides itself (meshes of colliders, bodies and rigid bodies, the
//! particle files of bodies), each with a hash of its bytes as they were read. A checkpoint
//! stores them, and a resumed run checks that the files it needs are still those bytes
//! ([`check_resumed`]): a mesh edited since the checkpoint would continue another scene.

use rtmpm_io::checkpoint::{FileHash, Fnv1a64};
use std::io::Read;
use std::path::{Path, PathBuf};

/// A file a scene read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneFile {
    /// The field naming it, e.g. `collider[0].file`.
    pub field: String,
    /// Its path as the scene resolved it (relative to the scene's folder).
    pub path: PathBuf,
    /// FNV-1a 64 of its bytes; `None` for a body's file not read (absent when a checkpoint
    /// was resumed: its particles are in the checkpoint).
    pub hash: Option<u64>,
}

impl SceneFile {
    /// True for the files a resumed run still uses: colliders' and rigid bodies' meshes. A
    /// body's mesh or particle file only seeds its particles, which a checkpoint holds.
    pub fn needed_on_resume(&self) -> bool {
        !self.field.starts_with("body[")
    }
}

/// FNV-1a 64 of the file's bytes, read in blocks.
pub fn hash_file(path: &Path) -> std::io::Result<u64> {
    let mut f = std::fs::File::open(path)?;
    let mut h = Fnv1a64::default();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            return Ok(h.finish());
        }
        h.update(&buf[..n]);
    }
}

/// What a resumed run makes of the files of its checkpoint (`stored`, empty in checkpoints of
/// format versions 1 and 2) against those of the scene as parsed now (`now`, whose hashes are
/// the files' bytes today): an error naming the first file the run needs that changed or is
/// gone; otherwise the notes to print (a body's file gone or changed: its particles come from
/// the checkpoint).
pub fn check_resumed(stored: &[FileHash], now: &[SceneFile]) -> Result<Vec<String>, String> {
    let mut notes = Vec::new();
    for s in stored {
        let Some(f) = now.iter().find(|f| f.field == s.field) else {
            continue;
        };
        let path = f.path.display();
        match f.hash {
            Some(h) if h == s.hash => {}
            None => notes.push(format!(
                "{path} (`{}`) is gone; its body's particles come from the checkpoint",
                s.field
            )),
            Some(_) if !f.needed_on_resume() => notes.push(format!(
                "{path} (`{}`) changed since the checkpoint was written; its body's particles \
                 come from the checkpoint, not from the file",
                s.field
            )),
            Some(h) => {
                return Err(format!(
                    "{path} (`{}`) changed since the checkpoint was written (FNV-1a hash \
                     {:016x} then, {h:016x} now): the resumed run would continue another \
                     scene\n  fix: restore the file as it was, or start the run again from the \
                     scene",
                    s.field, s.hash
                ));
            }
        }
    }
    Ok(notes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(field: &str, hash: Option<u64>) -> SceneFile {
        SceneFile {
            field: field.into(),
            path: PathBuf::from(format!("{field}.obj")),
            hash,
        }
    }

    fn stored(field: &str, hash: u64) -> FileHash {
        FileHash {
            field: field.into(),
            path: format!("{field}.obj"),
            hash,
        }
    }

    #[test]
    fn a_changed_mesh_refuses_a_changed_seed_is_noted() {
        let s = [stored("collider[0].file", 1), stored("body[0].file", 2)];
        assert_eq!(
            check_resumed(
                &s,
                &[
                    file("collider[0].file", Some(1)),
                    file("body[0].file", Some(2))
                ]
            ),
            Ok(vec![])
        );
        let e = check_resumed(&s, &[file("collider[0].file", Some(9))]).unwrap_err();
        assert!(
            e.contains("collider[0].file") && e.contains("changed"),
            "{e}"
        );
        let n = check_resumed(
            &s,
            &[
                file("collider[0].file", Some(1)),
                file("body[0].file", None),
            ],
        )
        .unwrap();
        assert!(n.len() == 1 && n[0].contains("gone"), "{n:?}");
        let n = check_resumed(&s, &[file("body[0].file", Some(3))]).unwrap();
        assert!(n[0].contains("changed"), "{n:?}");
    }

    #[test]
    fn hashes_are_of_the_bytes() {
        let dir = std::env::temp_dir().join(format!("rtmpm-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a");
        std::fs::write(&p, b"abc").unwrap();
        let mut h = Fnv1a64::default();
        h.update(b"abc");
        assert_eq!(hash_file(&p).unwrap(), h.finish());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
