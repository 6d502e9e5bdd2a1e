//! Bounded reads of input files: the size of a file is checked before anything is allocated,
//! and no more than a limit per kind of file is ever read; a device such as `/dev/zero`, a
//! named pipe or a socket is refused at once (it has no size, and a pipe blocks).
//!
//! Every reader of rtmpm (scene, OBJ mesh, PLY, VTU/PVD, BGEO, particle files, checkpoint)
//! goes through
//! [`read_bounded`], so a wrong path (a folder, a device, a 100 GB file) is a clear error naming
//! the file, its size and the limit, never a long read or a huge allocation.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Largest scene file (TOML text).
pub const SCENE_MAX_BYTES: u64 = 16 << 20;
/// Largest OBJ mesh file.
pub const MESH_MAX_BYTES: u64 = 1 << 30;
/// Largest `.pvd` collection (one short line per frame).
pub const PVD_MAX_BYTES: u64 = 256 << 20;
/// Largest particle data file (PLY, VTU, checkpoint); reads are also bounded by the memory
/// available (see [`read_bounded`]).
pub const DATA_MAX_BYTES: u64 = 1 << 40;

/// Human-readable byte count: `1.50 GiB`.
pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.2} {}", UNITS[u])
    }
}

/// Memory this process could get now: the system's `MemAvailable` (`/proc/meminfo`), lowered
/// to the process's address-space limit (`ulimit -v`) and its cgroup's `memory.max` where
/// those are set; `None` where nothing is known.
pub fn host_memory_available() -> Option<u64> {
    [
        meminfo_field("MemAvailable:"),
        address_space_limit(),
        cgroup_memory_left(),
    ]
    .into_iter()
    .flatten()
    .min()
}

/// `Max address space` of `/proc/self/limits` (soft limit), when set.
fn address_space_limit() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// `memory.max - memory.current` of this process's cgroup (v2), when a limit is set.
fn cgroup_memory_left() -> Option<u64> {
    let cg = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = cg.lines().find_map(|l| l.strip_prefix("0::"))?.trim();
    let dir = Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |f: &str| -> Option<u64> {
        std::fs::read_to_string(dir.join(f))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    let max = read("memory.max")?;
    Some(max.saturating_sub(read("memory.current").unwrap_or(0)))
}

/// Total memory of the machine (`MemTotal`), or `None` where that is not known.
pub fn host_memory_total() -> Option<u64> {
    meminfo_field("MemTotal:")
}

fn meminfo_field(key: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    kib.checked_mul(1024)
}

fn too_large(what: &str, path: &Path, size: String, limit: u64, why: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "{what} {} is {size}, more than {} ({why}); is this the right file?",
            path.display(),
            human_bytes(limit)
        ),
    )
}

/// Read the whole file at `path`, refusing (before reading) a regular file larger than
/// `limit` bytes or than the memory available; a folder, a device, a pipe or a socket is an
/// error. `what` names the kind of file in messages ("scene file", "PLY file", ...).
pub fn read_bounded(path: &Path, limit: u64, what: &str) -> io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    if meta.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{what} {} is a folder, not a file; give the path of the file",
                path.display()
            ),
        ));
    }
    if !meta.is_file() {
        // A device (/dev/zero), a named pipe or a socket: no size to check, and opening a pipe
        // waits for a writer. rtmpm reads files.
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{what} {} is not a regular file (a device, a pipe or a socket); give the \
                 path of a file",
                path.display()
            ),
        ));
    }
    let size = meta.len();
    if size > limit {
        return Err(too_large(
            what,
            path,
            human_bytes(size),
            limit,
            "the limit for this kind of file",
        ));
    }
    if let Some(avail) = host_memory_available()
        && size > avail
    {
        return Err(too_large(
            what,
            path,
            human_bytes(size),
            avail,
            "the memory available now",
        ));
    }
    let (cap, expected) = (size, size as usize);
    let file = File::open(path)?;
    let mut bytes = Vec::with_capacity(expected);
    // One byte more than allowed tells a stream that is too long from one that fits exactly.
    file.take(cap.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{what} {} grew while it was read", path.display()),
        ));
    }
    Ok(bytes)
}

/// Most bytes that `compressed` bytes of deflate (zlib, gzip) data may expand to: deflate
/// expands at most about 1032:1, and never more than [`DATA_MAX_BYTES`] or the memory available
/// now. Readers of compressed data (BGEO `.gz`, compressed VTU) stop or refuse there, so a
/// damaged header or a "zip bomb" is an error, not an allocation that kills the process.
pub fn decompressed_limit(compressed: u64) -> u64 {
    let ratio = compressed.saturating_mul(1032).saturating_add(1 << 16);
    let limit = ratio.min(DATA_MAX_BYTES);
    match host_memory_available() {
        Some(avail) => limit.min(avail),
        None => limit,
    }
}

/// [`read_bounded`], then decode UTF-8; invalid UTF-8 is an error naming the line and column
/// of the first bad byte.
pub fn read_text_bounded(path: &Path, limit: u64, what: &str) -> io::Result<String> {
    let bytes = read_bounded(path, limit, what)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let b = e.as_bytes();
        let line = b[..at].iter().filter(|&&c| c == b'\n').count() + 1;
        let col = at
            - b[..at]
                .iter()
                .rposition(|&c| c == b'\n')
                .map_or(0, |i| i + 1)
            + 1;
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "{what} {} is not UTF-8 text (bad byte {:#04x} at line {line}, column {col}); \
                 is this the right file? Save it as UTF-8",
                path.display(),
                b[at]
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::TestDir;

    #[test]
    fn limits_refuse_before_reading() {
        let d = TestDir::new("limits");
        let p = d.path("a.txt");
        std::fs::write(&p, vec![b'a'; 1000]).unwrap();
        assert_eq!(read_bounded(&p, 1000, "test file").unwrap().len(), 1000);
        let e = read_bounded(&p, 999, "test file").unwrap_err();
        assert!(e.to_string().contains("more than 999 B"), "{e}");
        let e = read_bounded(&d.0, 10, "scene file").unwrap_err();
        assert!(e.to_string().contains("is a folder"), "{e}");
        let e = read_bounded(&d.path("missing"), 10, "scene file").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
    }

    #[test]
    fn devices_and_pipes_are_refused_at_once() {
        let t = std::time::Instant::now();
        for dev in ["/dev/zero", "/dev/null", "/dev/urandom"] {
            if Path::new(dev).exists() {
                let e = read_bounded(Path::new(dev), u64::MAX, "mesh file").unwrap_err();
                assert!(e.to_string().contains("not a regular file"), "{e}");
            }
        }
        // A named pipe without a writer: opening it would block.
        let d = TestDir::new("limits-fifo");
        let fifo = d.path("pipe");
        if std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success())
        {
            let e = read_bounded(&fifo, 100, "scene file").unwrap_err();
            assert!(e.to_string().contains("a pipe"), "{e}");
        }
        assert!(t.elapsed().as_secs_f64() < 5.0);
        assert!(host_memory_available().is_none_or(|m| m > 0));
    }

    #[test]
    fn decompressed_data_is_bounded() {
        let small = decompressed_limit(0);
        assert!(small <= 1 << 16 && small > 0);
        assert!(decompressed_limit(1000) <= 1000 * 1032 + (1 << 16));
        assert!(decompressed_limit(u64::MAX) <= DATA_MAX_BYTES);
        if let Some(avail) = host_memory_available() {
            assert!(decompressed_limit(u64::MAX) <= avail);
        }
    }

    #[test]
    fn non_utf8_names_the_position() {
        let d = TestDir::new("limits-utf8");
        let p = d.path("s.toml");
        std::fs::write(&p, b"name = 1\nab\xffc\n").unwrap();
        let e = read_text_bounded(&p, 100, "scene file").unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("not UTF-8") && m.contains("line 2, column 3"),
            "{m}"
        );
        assert_eq!(human_bytes(1536), "1.50 KiB");
    }
}
