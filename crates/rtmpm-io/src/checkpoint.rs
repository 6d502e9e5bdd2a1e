//! Checkpoints: the full particle state plus the scene, bit-exact, so a run can resume.
//!
//! File layout (all integers little endian):
//!
//! ```text
//! offset  size  content
//! 0       8     magic b"RTMPMCKP"
//! 8       4     format version (u32, currently 3; versions 1 and 2 are read too)
//! 12      4     reserved (0)
//! 16      8     payload length P in bytes (u64)
//! 24      P     payload
//! 24+P    8     FNV-1a 64 checksum of bytes [0, 24+P)
//! ```
//!
//! Payload: `scene_toml` (u64 length + UTF-8), `scene_origin` (u64 length + UTF-8), `time`
//! (f64 bits), `step` (u64), `frame` (u64), (version 2 and later) the rigid-body count `b` (u64)
//! and `b` times 13 f32 (position 3, rotation quaternion x y z w 4, velocity 3, angular velocity
//! 3: [`BodyPose`], the bits rapier holds), (version 3) the count `k` (u64) of the files the
//! scene read and `k` times [`FileHash`] (its field and path, each a u64 length + UTF-8, and the
//! FNV-1a 64 hash of its bytes, u64), then the particle count `n` (u64) and the arrays in
//! this order as raw little-endian f32/u32 bits: `x` (3n), `v` (3n), `c` (9n, column-major),
//! `f` (9n, column-major), `plastic` (n), `mass` (n), `vol0` (n), `material` (n, u32).
//!
//! The rigid bodies' poses and velocities are restored exactly; what the rigid-body engine
//! keeps besides them (the contacts' cached impulses that warm-start its solver) is not
//! stored, so bodies in contact with each other or the walls at the checkpoint continue
//! slightly differently from an uninterrupted run ([`rtmpm_rigid::RigidWorld::set_poses`]).

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use super::contents::{check_particle_values, check_particles_in_domain};
use super::limits::{DATA_MAX_BYTES, read_bounded};
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_rigid::BodyPose;

/// Magic bytes at the start of every checkpoint.
pub const MAGIC: [u8; 8] = *b"RTMPMCKP";
/// Current format version.
pub const VERSION: u32 = 3;
/// Words (f32) per rigid body in the payload.
const WORDS_PER_BODY: usize = 13;
const HEADER_LEN: usize = 24;
const CHECKSUM_LEN: usize = 8;
/// Bytes per particle in the payload: 3 + 3 + 9 + 9 + 4 four-byte words.
const BYTES_PER_PARTICLE: u64 = 28 * 4;

/// A saved simulation state.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    /// The scene file's text, so a resumed run uses exactly the same scene.
    pub scene_toml: String,
    /// Where the scene came from (its path, for messages and relative asset paths).
    pub scene_origin: String,
    /// Simulation time (s).
    pub time: f64,
    /// Number of substeps done.
    pub step: u64,
    /// Number of output frames written.
    pub frame: u64,
    /// The rigid bodies' poses and velocities, one per `[[rigid_body]]` in the scene's order
    /// (empty without rigid bodies, and in version-1 files).
    pub bodies: Vec<BodyPose>,
    /// The files the scene read and their hashes when the run started (empty in files of
    /// versions 1 and 2).
    pub files: Vec<FileHash>,
    /// The particle state.
    pub particles: Particles,
}

/// A file a checkpoint's scene read (a mesh, a particle file), as the run found it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileHash {
    /// The scene field naming it, e.g. `collider[0].file`.
    pub field: String,
    /// Its path as the scene resolved it.
    pub path: String,
    /// FNV-1a 64 of its bytes.
    pub hash: u64,
}

/// A body's 13 words in the file's order.
fn body_words(b: &BodyPose) -> [f32; WORDS_PER_BODY] {
    let mut w = [0.0; WORDS_PER_BODY];
    w[0..3].copy_from_slice(&b.position.to_array());
    w[3..7].copy_from_slice(&b.rotation.to_array());
    w[7..10].copy_from_slice(&b.velocity.to_array());
    w[10..13].copy_from_slice(&b.angular_velocity.to_array());
    w
}

/// What of the scene a checkpoint resumes its state must fit ([`Checkpoint::check_fits`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ResumedScene {
    /// The domain's min corner (m).
    pub domain_min: Vec3,
    /// The domain's max corner (m).
    pub domain_max: Vec3,
    /// Cell size (m).
    pub dx: f32,
    /// Number of materials.
    pub materials: usize,
    /// The names of the rigid bodies, in the scene's order.
    pub rigid_bodies: Vec<String>,
}

/// Errors of [`Checkpoint::load`] and [`Checkpoint::save`].
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// The file could not be read or written.
    #[error("checkpoint I/O error: {0}")]
    Io(#[from] io::Error),
    /// The file does not start with the checkpoint magic.
    #[error("not an rtmpm checkpoint (bad magic bytes)")]
    BadMagic,
    /// The file was written by an incompatible version.
    #[error("unsupported checkpoint version {found} (this build reads versions 1 to {expected})")]
    UnsupportedVersion {
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        expected: u32,
    },
    /// The file is shorter (or longer) than its header announces.
    #[error("checkpoint is truncated or has trailing data: {found} bytes, expected {expected}")]
    Truncated {
        /// Size announced by the header.
        expected: u64,
        /// Actual file size.
        found: u64,
    },
    /// The checksum does not match: the file is corrupt.
    #[error(
        "checkpoint is corrupt: checksum {computed:#018x} does not match stored {stored:#018x}"
    )]
    ChecksumMismatch {
        /// Checksum stored in the file.
        stored: u64,
        /// Checksum of the content.
        computed: u64,
    },
    /// The payload is inconsistent (should not happen when the checksum matches).
    #[error("checkpoint is malformed: {0}")]
    Malformed(String),
    /// The bytes are intact but a value cannot be simulated (a NaN mass, a material index out
    /// of range, a particle far outside the domain, a negative time).
    #[error("checkpoint holds a value that cannot be simulated: {0}")]
    BadValue(String),
}

/// FNV-1a 64-bit hash, updated incrementally.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a64(u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Fnv1a64(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a64 {
    /// Feed `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The hash of everything fed so far.
    pub fn finish(self) -> u64 {
        self.0
    }
}

/// A writer that hashes everything written through it.
struct HashingWriter<'a, W: Write> {
    inner: &'a mut W,
    hash: Fnv1a64,
}

impl<W: Write> Write for HashingWriter<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

fn write_f32s<W: Write>(w: &mut W, values: impl Iterator<Item = f32>) -> io::Result<()> {
    let mut buf = Vec::with_capacity(64 * 1024);
    for v in values {
        buf.extend_from_slice(&v.to_bits().to_le_bytes());
        if buf.len() >= 60 * 1024 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)
}

impl Checkpoint {
    fn payload_len(&self) -> u64 {
        8 + self.scene_toml.len() as u64
            + 8
            + self.scene_origin.len() as u64
            + 8 * 4
            + 8
            + (4 * WORDS_PER_BODY * self.bodies.len()) as u64
            + 8
            + self
                .files
                .iter()
                .map(|f| 8 + f.field.len() as u64 + 8 + f.path.len() as u64 + 8)
                .sum::<u64>()
            + BYTES_PER_PARTICLE * self.particles.len() as u64
    }

    /// Write the checkpoint to `path` atomically (temporary file + rename).
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        crate::contents::check_particles(&self.particles)?;
        if let Some((i, why)) = self
            .bodies
            .iter()
            .enumerate()
            .find_map(|(i, b)| b.problem().map(|w| (i, w)))
        {
            return Err(CheckpointError::BadValue(format!(
                "rigid body {i} (rigid_body[{i}] of the scene): {why}"
            )));
        }
        let p = &self.particles;
        write_atomic_with(path, |out| {
            let mut w = HashingWriter {
                inner: out,
                hash: Fnv1a64::default(),
            };
            w.write_all(&MAGIC)?;
            w.write_all(&VERSION.to_le_bytes())?;
            w.write_all(&0u32.to_le_bytes())?;
            w.write_all(&self.payload_len().to_le_bytes())?;
            for s in [&self.scene_toml, &self.scene_origin] {
                w.write_all(&(s.len() as u64).to_le_bytes())?;
                w.write_all(s.as_bytes())?;
            }
            w.write_all(&self.time.to_bits().to_le_bytes())?;
            w.write_all(&self.step.to_le_bytes())?;
            w.write_all(&self.frame.to_le_bytes())?;
            w.write_all(&(self.bodies.len() as u64).to_le_bytes())?;
            write_f32s(&mut w, self.bodies.iter().flat_map(body_words))?;
            w.write_all(&(self.files.len() as u64).to_le_bytes())?;
            for f in &self.files {
                for s in [&f.field, &f.path] {
                    w.write_all(&(s.len() as u64).to_le_bytes())?;
                    w.write_all(s.as_bytes())?;
                }
                w.write_all(&f.hash.to_le_bytes())?;
            }
            w.write_all(&(p.len() as u64).to_le_bytes())?;
            write_f32s(&mut w, p.x.iter().flat_map(|x| x.to_array()))?;
            write_f32s(&mut w, p.v.iter().flat_map(|v| v.to_array()))?;
            write_f32s(&mut w, p.c.iter().flat_map(|m| m.to_cols_array()))?;
            write_f32s(&mut w, p.f.iter().flat_map(|m| m.to_cols_array()))?;
            write_f32s(&mut w, p.plastic.iter().copied())?;
            write_f32s(&mut w, p.mass.iter().copied())?;
            write_f32s(&mut w, p.vol0.iter().copied())?;
            write_f32s(&mut w, p.material.iter().map(|&m| f32::from_bits(m)))?;
            let sum = w.hash.finish();
            out.write_all(&sum.to_le_bytes())
        })?;
        Ok(())
    }

    /// Read a checkpoint written by [`save`](Checkpoint::save). Truncated, corrupt or foreign
    /// files give an error, never a panic.
    pub fn load(path: &Path) -> Result<Checkpoint, CheckpointError> {
        let bytes = read_bounded(path, DATA_MAX_BYTES, "checkpoint")?;
        Self::from_bytes(&bytes)
    }

    /// Check the values against the scene the checkpoint resumes: as many rigid bodies,
    /// material indices in range, positions inside the domain (within one cell).
    /// [`Checkpoint::from_bytes`] has already checked what does not depend on the scene.
    pub fn check_fits(&self, scene: &ResumedScene) -> Result<(), CheckpointError> {
        if self.bodies.len() != scene.rigid_bodies.len() {
            return Err(CheckpointError::BadValue(format!(
                "the checkpoint holds {} rigid bodies, the scene has {} [[rigid_body]] tables",
                self.bodies.len(),
                scene.rigid_bodies.len()
            )));
        }
        // A body's centre within a cell of the domain (the walls keep bodies inside it).
        let (lo, hi) = (scene.domain_min - scene.dx, scene.domain_max + scene.dx);
        for (i, (b, spec)) in self.bodies.iter().zip(&scene.rigid_bodies).enumerate() {
            let p = b.position;
            if p.cmplt(lo).any() || p.cmpgt(hi).any() {
                return Err(CheckpointError::BadValue(format!(
                    "rigid_body[{i}] `{spec}` is at ({}, {}, {}), outside the scene's domain \
                     ({}, {}, {}) .. ({}, {}, {})",
                    p.x,
                    p.y,
                    p.z,
                    scene.domain_min.x,
                    scene.domain_min.y,
                    scene.domain_min.z,
                    scene.domain_max.x,
                    scene.domain_max.y,
                    scene.domain_max.z
                )));
            }
        }
        check_particles_in_domain(
            &self.particles,
            scene.domain_min,
            scene.domain_max,
            scene.dx,
            scene.materials,
        )
        .map_err(|e| CheckpointError::BadValue(e.to_string()))
    }

    /// Decode a checkpoint from its file content.
    pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, CheckpointError> {
        let (version, payload) = verified_payload(bytes)?;
        let mut r = Reader {
            bytes: payload,
            pos: 0,
        };
        let scene_toml = r.string("scene_toml")?;
        let scene_origin = r.string("scene_origin")?;
        let time = f64::from_bits(r.u64()?);
        let step = r.u64()?;
        let frame = r.u64()?;
        let bodies = if version >= 2 {
            r.bodies()?
        } else {
            Vec::new()
        };
        let files = if version >= 3 {
            r.file_hashes()?
        } else {
            Vec::new()
        };
        let particles = r.particles()?;
        if !(time.is_finite() && time >= 0.0) {
            return Err(CheckpointError::BadValue(format!(
                "the time {time} is not a finite number >= 0"
            )));
        }
        if frame > step {
            return Err(CheckpointError::BadValue(format!(
                "frame {frame} is after step {step} (every frame takes at least one step)"
            )));
        }
        check_particle_values(&particles).map_err(|e| CheckpointError::BadValue(e.to_string()))?;
        Ok(Checkpoint {
            scene_toml,
            scene_origin,
            time,
            step,
            frame,
            bodies,
            files,
            particles,
        })
    }
}

/// The version and the payload of a checkpoint file's content, after its framing is checked:
/// the magic bytes, a version this build reads, the length the header gives and the checksum.
fn verified_payload(bytes: &[u8]) -> Result<(u32, &[u8]), CheckpointError> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(CheckpointError::BadMagic);
    }
    if bytes.len() < HEADER_LEN {
        return Err(CheckpointError::Truncated {
            expected: (HEADER_LEN + CHECKSUM_LEN) as u64,
            found: bytes.len() as u64,
        });
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    if !(1..=VERSION).contains(&version) {
        return Err(CheckpointError::UnsupportedVersion {
            found: version,
            expected: VERSION,
        });
    }
    let payload_len = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
    let expected = payload_len.saturating_add((HEADER_LEN + CHECKSUM_LEN) as u64);
    if bytes.len() as u64 != expected {
        return Err(CheckpointError::Truncated {
            expected,
            found: bytes.len() as u64,
        });
    }
    let body_end = bytes.len() - CHECKSUM_LEN;
    let stored = u64::from_le_bytes(bytes[body_end..].try_into().unwrap());
    let mut h = Fnv1a64::default();
    h.update(&bytes[..body_end]);
    let computed = h.finish();
    if stored != computed {
        return Err(CheckpointError::ChecksumMismatch { stored, computed });
    }
    Ok((version, &bytes[HEADER_LEN..body_end]))
}

/// Bounds-checked little-endian reader over the payload.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, len: usize) -> Result<&[u8], CheckpointError> {
        let end = self
            .pos
            .checked_add(len)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| CheckpointError::Malformed("payload ends early".into()))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u64(&mut self) -> Result<u64, CheckpointError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }

    fn string(&mut self, what: &str) -> Result<String, CheckpointError> {
        let len = usize::try_from(self.u64()?)
            .map_err(|_| CheckpointError::Malformed(format!("{what} length overflows")))?;
        let b = self.take(len)?;
        String::from_utf8(b.to_vec())
            .map_err(|_| CheckpointError::Malformed(format!("{what} is not UTF-8")))
    }

    fn words(&mut self, count: usize) -> Result<Vec<u32>, CheckpointError> {
        let b = self.take(count * 4)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    /// The rigid bodies' poses (version 2 on): a count, then [`WORDS_PER_BODY`] words each;
    /// every pose checked.
    fn bodies(&mut self) -> Result<Vec<BodyPose>, CheckpointError> {
        let count = self.u64()?;
        let left = (self.bytes.len() - self.pos) as u64;
        if count.saturating_mul((4 * WORDS_PER_BODY) as u64) > left {
            return Err(CheckpointError::Malformed(format!(
                "{count} rigid bodies do not fit the {left} bytes left"
            )));
        }
        let words = self.words(WORDS_PER_BODY * count as usize)?;
        let mut bodies = Vec::new();
        for (i, w) in words.chunks_exact(WORDS_PER_BODY).enumerate() {
            let f = |k: usize| f32::from_bits(w[k]);
            let b = BodyPose {
                position: Vec3::new(f(0), f(1), f(2)),
                rotation: glam::Quat::from_xyzw(f(3), f(4), f(5), f(6)),
                velocity: Vec3::new(f(7), f(8), f(9)),
                angular_velocity: Vec3::new(f(10), f(11), f(12)),
            };
            if let Some(why) = b.problem() {
                return Err(CheckpointError::BadValue(format!(
                    "rigid body {i} (rigid_body[{i}] of the scene): {why}"
                )));
            }
            bodies.push(b);
        }
        Ok(bodies)
    }

    /// The hashes of the files the scene read (version 3 on): a count, then the field, the path
    /// and the hash of each.
    fn file_hashes(&mut self) -> Result<Vec<FileHash>, CheckpointError> {
        let count = self.u64()?;
        // At least 24 bytes each (two lengths and the hash).
        let left = (self.bytes.len() - self.pos) as u64;
        if count.saturating_mul(24) > left {
            return Err(CheckpointError::Malformed(format!(
                "{count} file hashes do not fit the {left} bytes left"
            )));
        }
        let mut files = Vec::new();
        for _ in 0..count {
            let field = self.string("file field")?;
            let path = self.string("file path")?;
            let hash = self.u64()?;
            files.push(FileHash { field, path, hash });
        }
        Ok(files)
    }

    /// The particles, which fill the rest of the payload: a count, then each field's column
    /// (x, v, C, F, plastic, mass, vol0, material) as f32 bits or integers.
    fn particles(&mut self) -> Result<Particles, CheckpointError> {
        let n = self.u64()?;
        let remaining = (self.bytes.len() - self.pos) as u64;
        if n.checked_mul(BYTES_PER_PARTICLE) != Some(remaining) {
            return Err(CheckpointError::Malformed(format!(
                "{n} particles do not match the {remaining} bytes of particle data"
            )));
        }
        let n = n as usize;
        let vec3 = |w: Vec<u32>| -> Vec<Vec3> {
            w.chunks_exact(3)
                .map(|c| {
                    Vec3::new(
                        f32::from_bits(c[0]),
                        f32::from_bits(c[1]),
                        f32::from_bits(c[2]),
                    )
                })
                .collect()
        };
        let mat3 = |w: Vec<u32>| -> Vec<Mat3> {
            w.chunks_exact(9)
                .map(|c| {
                    let mut a = [0f32; 9];
                    for (d, s) in a.iter_mut().zip(c) {
                        *d = f32::from_bits(*s);
                    }
                    Mat3::from_cols_array(&a)
                })
                .collect()
        };
        let floats = |w: Vec<u32>| -> Vec<f32> { w.into_iter().map(f32::from_bits).collect() };
        Ok(Particles {
            x: vec3(self.words(3 * n)?),
            v: vec3(self.words(3 * n)?),
            c: mat3(self.words(9 * n)?),
            f: mat3(self.words(9 * n)?),
            plastic: floats(self.words(n)?),
            mass: floats(self.words(n)?),
            vol0: floats(self.words(n)?),
            material: self.words(n)?,
        })
    }
}

#[cfg(test)]
mod tests;
