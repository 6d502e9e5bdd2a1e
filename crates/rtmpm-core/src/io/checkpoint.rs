//! Checkpoints: the full particle state plus the scene, bit-exact, so a run can resume.
//!
//! File layout (all integers little endian):
//!
//! ```text
//! offset  size  content
//! 0       8     magic b"RTMPMCKP"
//! 8       4     format version (u32, currently 1)
//! 12      4     reserved (0)
//! 16      8     payload length P in bytes (u64)
//! 24      P     payload
//! 24+P    8     FNV-1a 64 checksum of bytes [0, 24+P)
//! ```
//!
//! Payload: `scene_toml` (u64 length + UTF-8), `scene_origin` (u64 length + UTF-8), `time`
//! (f64 bits), `step` (u64), `frame` (u64), particle count `n` (u64), then the arrays in this
//! order as raw little-endian f32/u32 bits: `x` (3n), `v` (3n), `c` (9n, column-major), `f`
//! (9n, column-major), `plastic` (n), `mass` (n), `vol0` (n), `material` (n, u32).

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use super::contents::{check_particle_values, check_particles_in_domain};
use super::limits::{DATA_MAX_BYTES, read_bounded};
use crate::Particles;
use crate::math::{Mat3, Vec3};

/// Magic bytes at the start of every checkpoint.
pub const MAGIC: [u8; 8] = *b"RTMPMCKP";
/// Current format version.
pub const VERSION: u32 = 1;
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
    /// The particle state.
    pub particles: Particles,
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
    #[error("unsupported checkpoint version {found} (this build reads version {expected})")]
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
            + BYTES_PER_PARTICLE * self.particles.len() as u64
    }

    /// Write the checkpoint to `path` atomically (temporary file + rename).
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        super::check_particles(&self.particles)?;
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

    /// Check the values against the scene the checkpoint resumes: material indices in range,
    /// positions inside the domain (within one cell). [`Checkpoint::from_bytes`] has already
    /// checked what does not depend on the scene.
    pub fn check_scene(&self, scene: &crate::Scene) -> Result<(), CheckpointError> {
        check_particles_in_domain(
            &self.particles,
            scene.domain_min,
            scene.domain_max,
            scene.dx,
            scene.materials.len(),
        )
        .map_err(|e| CheckpointError::BadValue(e.to_string()))
    }

    /// Decode a checkpoint from its file content.
    pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, CheckpointError> {
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
        if version != VERSION {
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

        let mut r = Reader {
            bytes: &bytes[HEADER_LEN..body_end],
            pos: 0,
        };
        let scene_toml = r.string("scene_toml")?;
        let scene_origin = r.string("scene_origin")?;
        let time = f64::from_bits(r.u64()?);
        let step = r.u64()?;
        let frame = r.u64()?;
        let n = r.u64()?;
        let remaining = (r.bytes.len() - r.pos) as u64;
        if n.checked_mul(BYTES_PER_PARTICLE) != Some(remaining) {
            return Err(CheckpointError::Malformed(format!(
                "{n} particles do not match the {remaining} bytes of particle data"
            )));
        }
        let n = n as usize;
        let x = r.words(3 * n)?;
        let v = r.words(3 * n)?;
        let c = r.words(9 * n)?;
        let f = r.words(9 * n)?;
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
        let particles = Particles {
            x: vec3(x),
            v: vec3(v),
            c: mat3(c),
            f: mat3(f),
            plastic: floats(r.words(n)?),
            mass: floats(r.words(n)?),
            vol0: floats(r.words(n)?),
            material: r.words(n)?,
        };
        check_particle_values(&particles).map_err(|e| CheckpointError::BadValue(e.to_string()))?;
        Ok(Checkpoint {
            scene_toml,
            scene_origin,
            time,
            step,
            frame,
            particles,
        })
    }
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::atomic::tests::TestDir;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;
    use std::fs;

    fn random_checkpoint(n: usize, seed: u64) -> Checkpoint {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut r = || rng.random_range(-1e3f32..1e3);
        let mut p = Particles::default();
        for _ in 0..n {
            p.x.push(Vec3::new(r(), r(), r()));
            p.v.push(Vec3::new(r(), r(), r()));
            let mut m = [0f32; 9];
            m.iter_mut().for_each(|a| *a = r());
            p.c.push(Mat3::from_cols_array(&m));
            m.iter_mut().for_each(|a| *a = r());
            p.f.push(Mat3::from_cols_array(&m));
            p.plastic.push(r());
            p.mass.push(r().abs() + 1e-30);
            p.vol0.push(r().abs() * 1e-9);
            p.material.push((r().abs() * 1e6) as u32);
        }
        // A few special values that must survive bit-exactly.
        if n > 2 {
            p.x[0].x = -0.0;
            p.v[1].y = f32::MIN_POSITIVE / 4.0; // subnormal
            p.plastic[2] = f32::MAX;
            p.material[2] = u32::MAX;
        }
        Checkpoint {
            scene_toml: "[sim]\ndt = 1e-4 # é ünïcode\n".into(),
            scene_origin: "/scenes/snow.toml".into(),
            time: 0.1 + 0.2,
            step: 123_456_789_012,
            frame: 42,
            particles: p,
        }
    }

    #[test]
    fn round_trip_bit_identical() {
        let d = TestDir::new("ckpt");
        let ck = random_checkpoint(1000, 7);
        let path = d.path("ckpt/state.ckpt");
        ck.save(&path).unwrap();
        let back = Checkpoint::load(&path).unwrap();
        assert_eq!(back, ck);
        assert_eq!(back.time.to_bits(), ck.time.to_bits());
        assert_eq!(back.particles.x[0].x.to_bits(), (-0.0f32).to_bits());
        let bits = |p: &Particles| -> Vec<u32> {
            p.c.iter()
                .chain(&p.f)
                .flat_map(|m| m.to_cols_array())
                .map(f32::to_bits)
                .collect()
        };
        assert_eq!(bits(&back.particles), bits(&ck.particles));
        let size = fs::metadata(&path).unwrap().len();
        assert_eq!(size, 32 + ck.payload_len());
    }

    #[test]
    fn empty_round_trip() {
        let d = TestDir::new("ckpt-empty");
        let ck = Checkpoint {
            scene_toml: String::new(),
            scene_origin: String::new(),
            time: 0.0,
            step: 0,
            frame: 0,
            particles: Particles::default(),
        };
        let path = d.path("e.ckpt");
        ck.save(&path).unwrap();
        assert_eq!(Checkpoint::load(&path).unwrap(), ck);
    }

    #[test]
    fn truncated_file_is_an_error() {
        let d = TestDir::new("ckpt-trunc");
        let path = d.path("t.ckpt");
        random_checkpoint(50, 1).save(&path).unwrap();
        let bytes = fs::read(&path).unwrap();
        for len in [0, 4, 8, 20, 24, 100, bytes.len() / 2, bytes.len() - 1] {
            let err = Checkpoint::from_bytes(&bytes[..len]).unwrap_err();
            match (len, &err) {
                (0..8, CheckpointError::BadMagic) => {}
                (8.., CheckpointError::Truncated { found, .. }) => {
                    assert_eq!(*found, len as u64)
                }
                _ => panic!("len {len}: unexpected {err:?}"),
            }
        }
        fs::write(&path, &bytes[..bytes.len() - 9]).unwrap();
        let err = Checkpoint::load(&path).unwrap_err();
        assert!(err.to_string().contains("truncated"), "{err}");
    }

    #[test]
    fn corrupt_and_foreign_files_are_errors() {
        let d = TestDir::new("ckpt-bad");
        let path = d.path("c.ckpt");
        random_checkpoint(20, 2).save(&path).unwrap();
        let bytes = fs::read(&path).unwrap();

        // Flip one bit anywhere in the payload.
        for at in [HEADER_LEN, HEADER_LEN + 50, bytes.len() - 20] {
            let mut b = bytes.clone();
            b[at] ^= 0x10;
            assert!(matches!(
                Checkpoint::from_bytes(&b),
                Err(CheckpointError::ChecksumMismatch { .. })
            ));
        }

        let mut b = bytes.clone();
        b[..8].copy_from_slice(b"PLYPLYPL");
        let err = Checkpoint::from_bytes(&b).unwrap_err();
        assert!(matches!(err, CheckpointError::BadMagic));
        assert!(err.to_string().contains("not an rtmpm checkpoint"));

        let mut b = bytes.clone();
        b[8..12].copy_from_slice(&99u32.to_le_bytes());
        assert!(matches!(
            Checkpoint::from_bytes(&b),
            Err(CheckpointError::UnsupportedVersion { found: 99, .. })
        ));

        let mut b = bytes.clone();
        b.push(0);
        assert!(matches!(
            Checkpoint::from_bytes(&b),
            Err(CheckpointError::Truncated { .. })
        ));

        // A huge announced payload length must not allocate or panic.
        let mut b = bytes.clone();
        b[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(
            Checkpoint::from_bytes(&b),
            Err(CheckpointError::Truncated { .. })
        ));

        assert!(matches!(
            Checkpoint::load(&d.path("missing.ckpt")),
            Err(CheckpointError::Io(_))
        ));
    }

    /// Intact bytes (a valid checksum) around values that cannot be simulated are refused
    /// with the particle and the value, never run.
    #[test]
    fn valid_checksum_bad_values_are_refused() {
        let mut good = random_checkpoint(5, 3);
        good.particles.material.iter_mut().for_each(|m| *m = 0);
        good.particles.plastic[2] = 0.0;
        let scene = crate::Scene::from_toml(
            "[domain]\nmin = [-1000, -1000, -1000]\nmax = [1000, 1000, 1000]\ndx = 10\n\
             [time]\nduration = 1\n[[material]]\nname = \"w\"\ntype = \"fluid\"\n\
             density = 1000\nbulk_modulus = 1e5\n",
            "<test>",
        )
        .unwrap();
        let round = |ck: &Checkpoint| {
            let d = TestDir::new("ckpt-values");
            let path = d.path("v.ckpt");
            ck.save(&path).unwrap();
            Checkpoint::load(&path)
        };
        let back = round(&good).unwrap();
        back.check_scene(&scene).unwrap();

        type Edit = fn(&mut Checkpoint);
        let cases: [(Edit, &str); 7] = [
            (|c| c.particles.mass[1] = f32::NAN, "mass NaN"),
            (|c| c.particles.mass[3] = -2.0, "mass -2"),
            (
                |c| c.particles.vol0[0] = f32::INFINITY,
                "initial volume inf",
            ),
            (|c| c.particles.v[4].x = f32::NAN, "velocity"),
            (|c| c.time = -1.0, "time -1"),
            (|c| c.time = f64::INFINITY, "time inf"),
            (|c| c.frame = c.step + 1, "frame"),
        ];
        for (edit, expect) in cases {
            let mut ck = good.clone();
            edit(&mut ck);
            let e = round(&ck).unwrap_err();
            assert!(matches!(e, CheckpointError::BadValue(_)), "{e:?}");
            assert!(e.to_string().contains(expect), "{e} (expected {expect})");
        }
        // Scene-dependent values: checked by check_scene.
        let mut ck = good.clone();
        ck.particles.material[2] = 7;
        let e = round(&ck).unwrap().check_scene(&scene).unwrap_err();
        assert!(
            e.to_string().contains("particle 2: material index 7"),
            "{e}"
        );
        let mut ck = good.clone();
        ck.particles.x[1].y = 1e9;
        let e = round(&ck).unwrap().check_scene(&scene).unwrap_err();
        assert!(e.to_string().contains("particle 1: position"), "{e}");
    }

    #[test]
    fn fnv1a_reference_values() {
        let h = |s: &[u8]| {
            let mut f = Fnv1a64::default();
            f.update(s);
            f.finish()
        };
        assert_eq!(h(b""), 0xcbf29ce484222325);
        assert_eq!(h(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(h(b"foobar"), 0x85944171f73967e8);
    }
}
