//! Atomic file writes: every output goes to a temporary file in the destination folder, is
//! flushed and synced, then renamed over the destination. An interrupted run therefore never
//! leaves a half-written file under the final name.

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// Temporary path next to `path`: `.{name}.tmp-{pid}` in the same folder (same file system, so
/// the final rename is atomic).
fn temp_path(path: &Path) -> io::Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("not a file path: {}", path.display()),
        )
    })?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    Ok(path.with_file_name(tmp_name))
}

/// Create the parent folder of `path` if it has one and it does not exist yet.
fn create_parent(path: &Path) -> io::Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => fs::create_dir_all(dir),
        _ => Ok(()),
    }
}

/// Write `bytes` to `path` through a temporary file in the same folder and a rename, so that an
/// interrupted run never leaves a half-written file. Parent folders are created.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Streaming variant of [`write_atomic`]: `write` receives a buffered writer on the temporary
/// file, so large outputs need not be assembled in memory first. On success the buffer is
/// flushed, the data synced to disk and the file renamed to `path`; on any error the temporary
/// file is removed and the error returned.
pub fn write_atomic_with<F>(path: &Path, write: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    create_parent(path)?;
    let tmp = temp_path(path)?;
    let result = (|| {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_data()?;
        drop(file);
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// A file being written under a temporary name (see [`write_atomic_with`]) when the writing
/// cannot be one closure, e.g. a frame written chunk by chunk as the chunks arrive: `create`
/// opens the temporary file, [`AtomicFile::commit`] syncs it and renames it to the final name,
/// and dropping the guard uncommitted removes the temporary file.
pub struct AtomicFile {
    tmp: PathBuf,
    path: PathBuf,
    armed: bool,
}

impl AtomicFile {
    /// Create the temporary file for `path` (parent folders are created).
    pub fn create(path: &Path) -> io::Result<(AtomicFile, File)> {
        create_parent(path)?;
        let tmp = temp_path(path)?;
        let file = File::create(&tmp)?;
        let guard = AtomicFile {
            tmp,
            path: path.to_path_buf(),
            armed: true,
        };
        Ok((guard, file))
    }

    /// The final name.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sync `file` (the one [`AtomicFile::create`] returned, all data written) and rename it to
    /// the final name; on error the temporary file is removed.
    pub fn commit(mut self, file: File) -> io::Result<()> {
        file.sync_data()?;
        drop(file);
        fs::rename(&self.tmp, &self.path)?;
        self.armed = false;
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.armed {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::TestDir;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_and_replaces() {
        let d = TestDir::new("atomic");
        let p = d.path("sub/dir/a.txt");
        write_atomic(&p, b"hello").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"hello");
        write_atomic(&p, b"bye").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"bye");
        assert_eq!(entries(&d.path("sub/dir")), vec!["a.txt".to_string()]);
    }

    #[test]
    fn error_removes_temp_and_keeps_old_file() {
        let d = TestDir::new("atomic-err");
        let p = d.path("b.txt");
        write_atomic(&p, b"old").unwrap();
        let err = write_atomic_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "boom");
        assert_eq!(fs::read(&p).unwrap(), b"old");
        assert_eq!(entries(&d.0), vec!["b.txt".to_string()]);
    }

    #[test]
    fn streaming_write() {
        let d = TestDir::new("atomic-stream");
        let p = d.path("c.bin");
        write_atomic_with(&p, |w| {
            for i in 0u32..1000 {
                w.write_all(&i.to_le_bytes())?;
            }
            Ok(())
        })
        .unwrap();
        let data = fs::read(&p).unwrap();
        assert_eq!(data.len(), 4000);
        assert_eq!(&data[4..8], &1u32.to_le_bytes());
    }
}
