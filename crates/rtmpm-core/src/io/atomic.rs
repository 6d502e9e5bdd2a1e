//! Atomic file writes (stub).

use std::io;
use std::path::Path;

/// Write `bytes` to `path` through a temporary file in the same folder and a rename, so that an
/// interrupted run never leaves a half-written file.
pub fn write_atomic(_path: &Path, _bytes: &[u8]) -> io::Result<()> {
    todo!()
}
