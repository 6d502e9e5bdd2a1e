//! Particle frames written chunk by chunk ([`super::chunks`]): PLY and BGEO (plain or gzip)
//! files byte for byte the same as [`super::ply::write_ply_with_comments`] and
//! [`super::bgeo::write_bgeo`] write for the same particles, without the whole frame in memory.
//! Each file is written under a temporary name and renamed when complete
//! ([`super::atomic::AtomicFile`]): an error or a crash leaves no partial file.
//!
//! The derived fields (`J = det F`, the Cauchy stress) are computed per chunk from the columns
//! `F`, `C`, `plastic` and `material`, with the same f32 arithmetic as the whole-frame writers.

use super::atomic::AtomicFile;
use super::bgeo::{BgeoType, symmetric_to_full};
use super::chunks::{Column, FrameChunk, FrameColumns};
use rayon::prelude::*;
use rtmpm_physics::material::Model;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A particle file format that can be written in chunks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StreamFormat {
    /// Binary PLY with these extra `comment` lines (see [`super::ply`]).
    Ply {
        /// One-line comments of the header.
        comments: Vec<String>,
    },
    /// Classic BGEO (see [`super::bgeo`]), gzip-compressed when `gzip`.
    Bgeo {
        /// `.bgeo.gz`.
        gzip: bool,
    },
}

/// The optional derived fields of a frame (the `[output]` switches `jacobian` and `stress`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Derived {
    /// `J = det F` per particle.
    pub jacobian: bool,
    /// Cauchy stress per particle.
    pub stress: bool,
}

impl StreamFormat {
    /// The columns this format needs (with `derived`).
    pub fn columns(&self, derived: Derived) -> FrameColumns {
        let mut c = FrameColumns {
            v: true,
            material: true,
            plastic: true,
            ..FrameColumns::default()
        };
        if matches!(self, StreamFormat::Bgeo { .. }) {
            c.mass = true;
            c.vol0 = true;
        }
        if derived.jacobian || derived.stress {
            c.f = true;
        }
        if derived.stress {
            c.c = true;
        }
        c
    }
}

/// The derived fields of one chunk, computed once for all the files of a frame.
#[derive(Default)]
pub struct ChunkFields {
    /// `det F` per particle of the chunk.
    pub jacobian: Option<Vec<f32>>,
    /// Cauchy stress per particle, `[xx, yy, zz, xy, yz, xz]`.
    pub stress: Option<Vec<[f32; 6]>>,
}

impl ChunkFields {
    /// Compute the fields `derived` asks for from the chunk's columns; `models`: the scene's
    /// material models, by index (for the stress).
    pub fn compute(chunk: &FrameChunk, derived: Derived, models: &[Model]) -> io::Result<Self> {
        let missing = |what: &str| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("frame chunk without the column {what}"),
            )
        };
        let mut out = ChunkFields::default();
        if !(derived.jacobian || derived.stress) {
            return Ok(out);
        }
        let f = chunk.column(Column::F).ok_or_else(|| missing("F"))?;
        if derived.jacobian {
            out.jacobian = Some(
                (0..chunk.len)
                    .into_par_iter()
                    .map(|j| FrameChunk::mat3(&f, j).determinant())
                    .collect(),
            );
        }
        if derived.stress {
            let c = chunk.column(Column::C).ok_or_else(|| missing("C"))?;
            let plastic = chunk
                .column(Column::Plastic)
                .ok_or_else(|| missing("plastic"))?;
            let mat = chunk
                .cols
                .row(Column::Material)
                .ok_or_else(|| missing("material"))?;
            let mat = chunk.row(mat);
            if let Some(&m) = mat.iter().find(|&&m| m as usize >= models.len()) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "material index {m} out of range ({} materials)",
                        models.len()
                    ),
                ));
            }
            out.stress = Some(
                (0..chunk.len)
                    .into_par_iter()
                    .map(|j| {
                        rtmpm_physics::material::cauchy_stress_of(
                            &models[mat[j] as usize],
                            FrameChunk::mat3(&f, j),
                            plastic[0][j],
                            FrameChunk::mat3(&c, j),
                        )
                    })
                    .collect(),
            );
        }
        Ok(out)
    }
}

/// Where the bytes go: the temporary file, through gzip or not.
enum Sink {
    Plain(BufWriter<File>),
    Gz(flate2::write::GzEncoder<BufWriter<File>>),
}

impl Sink {
    fn writer(&mut self) -> &mut dyn Write {
        match self {
            Sink::Plain(w) => w,
            Sink::Gz(g) => g,
        }
    }
}

/// One frame file being written chunk by chunk.
pub struct StreamFile {
    guard: AtomicFile,
    sink: Sink,
    format: StreamFormat,
    derived: Derived,
    n: usize,
    written: usize,
    encoded: Vec<u8>,
    bytes: u64,
}

/// Particles encoded per parallel task.
const TASK: usize = 1 << 14;
/// Particles encoded before a write (4 MB of PLY records; the tests write chunks of several
/// blocks).
pub const BLOCK: usize = 1 << 17;

impl StreamFile {
    /// Start the file at `path` (temporary name) for `n` particles: writes the header.
    pub fn create(
        path: &Path,
        format: StreamFormat,
        n: usize,
        derived: Derived,
    ) -> io::Result<StreamFile> {
        let header = match &format {
            StreamFormat::Ply { comments } => {
                if let Some(c) = comments.iter().find(|c| c.contains(['\n', '\r'])) {
                    return Err(invalid(format!("PLY comment {c:?} spans several lines")));
                }
                let comments: Vec<&str> = comments.iter().map(String::as_str).collect();
                super::ply::frame_header(n, &comments, derived.jacobian, derived.stress)
                    .into_bytes()
            }
            StreamFormat::Bgeo { .. } => {
                let too_big = |what: &str| {
                    invalid(format!(
                        "{what} does not fit the BGEO format's 32-bit integers"
                    ))
                };
                let n_i32 = i32::try_from(n).map_err(|_| too_big("the particle count"))?;
                super::bgeo::frame_header(n_i32, &bgeo_attributes(derived))
            }
        };
        let (guard, file) = AtomicFile::create(path)?;
        let w = BufWriter::with_capacity(1 << 20, file);
        let mut sink = match format {
            StreamFormat::Bgeo { gzip: true } => Sink::Gz(flate2::write::GzEncoder::new(
                w,
                flate2::Compression::fast(),
            )),
            _ => Sink::Plain(w),
        };
        sink.writer().write_all(&header)?;
        Ok(StreamFile {
            guard,
            sink,
            format,
            derived,
            n,
            written: 0,
            encoded: Vec::new(),
            bytes: header.len() as u64,
        })
    }

    /// The final name of the file.
    pub fn path(&self) -> &Path {
        self.guard.path()
    }

    /// Bytes written so far (before compression).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Append the next chunk (chunks come in order: `chunk.start` is the count written so far);
    /// `fields`: its derived fields ([`ChunkFields::compute`]).
    pub fn write_chunk(&mut self, chunk: &FrameChunk, fields: &ChunkFields) -> io::Result<()> {
        if chunk.start != self.written || chunk.start + chunk.len > self.n {
            return Err(invalid(format!(
                "chunk of particles {}..{} out of order ({} of {} written)",
                chunk.start,
                chunk.start + chunk.len,
                self.written,
                self.n
            )));
        }
        let cols = |c: Column| {
            chunk
                .column(c)
                .ok_or_else(|| invalid(format!("frame chunk without the column {c:?}")))
        };
        let (x, v, plastic) = (cols(Column::X)?, cols(Column::V)?, cols(Column::Plastic)?);
        let mat_row = chunk
            .cols
            .row(Column::Material)
            .ok_or_else(|| invalid("frame chunk without materials".into()))?;
        let mat = chunk.row(mat_row);
        if let Some(m) = mat.iter().find(|&&m| m > i32::MAX as u32) {
            return Err(invalid(format!(
                "material index {m} does not fit the file's 32-bit int"
            )));
        }
        let jac = match (self.derived.jacobian, &fields.jacobian) {
            (false, _) => None,
            (true, Some(j)) if j.len() == chunk.len => Some(j.as_slice()),
            _ => return Err(invalid("J missing for the chunk".into())),
        };
        let stress = match (self.derived.stress, &fields.stress) {
            (false, _) => None,
            (true, Some(s)) if s.len() == chunk.len => Some(s.as_slice()),
            _ => return Err(invalid("stress missing for the chunk".into())),
        };
        let rec = self.record_bytes();
        let start = chunk.start;
        let (mass, vol0) = match self.format {
            StreamFormat::Bgeo { .. } => (cols(Column::Mass)?, cols(Column::Vol0)?),
            StreamFormat::Ply { .. } => (vec![], vec![]),
        };
        // Encoded a block at a time into a buffer reused for the whole file (a few MB, not
        // the chunk's size), in parallel, then written.
        let block = BLOCK.min(chunk.len);
        if self.encoded.len() < block * rec {
            self.encoded.resize(block * rec, 0);
        }
        for lo in (0..chunk.len).step_by(BLOCK.max(1)) {
            let hi = (lo + BLOCK).min(chunk.len);
            let buf = &mut self.encoded[..(hi - lo) * rec];
            let ply = matches!(self.format, StreamFormat::Ply { .. });
            buf.par_chunks_mut(rec * TASK)
                .enumerate()
                .for_each(|(t, out)| {
                    let first = lo + t * TASK;
                    let count = out.len() / rec;
                    let mut o = Cursor(out);
                    for j in first..first + count {
                        if ply {
                            for row in x.iter().chain(&v) {
                                o.put(row[j].to_le_bytes());
                            }
                            o.put((mat[j] as i32).to_le_bytes());
                            o.put(plastic[0][j].to_le_bytes());
                            if let Some(jac) = jac {
                                o.put(jac[j].to_le_bytes());
                            }
                            if let Some(s) = stress {
                                for c in s[j] {
                                    o.put(c.to_le_bytes());
                                }
                            }
                        } else {
                            for row in &x {
                                o.put(row[j].to_be_bytes());
                            }
                            o.put(1.0f32.to_be_bytes());
                            for row in &v {
                                o.put(row[j].to_be_bytes());
                            }
                            o.put(((start + j) as i32).to_be_bytes());
                            o.put((mat[j] as i32).to_be_bytes());
                            o.put(plastic[0][j].to_be_bytes());
                            o.put(mass[0][j].to_be_bytes());
                            o.put((0.5 * vol0[0][j].max(0.0).cbrt()).to_be_bytes());
                            if let Some(jac) = jac {
                                o.put(jac[j].to_be_bytes());
                            }
                            if let Some(s) = stress {
                                for c in symmetric_to_full(s[j]) {
                                    o.put(c.to_be_bytes());
                                }
                            }
                        }
                    }
                });
            self.sink.writer().write_all(buf)?;
            self.bytes += buf.len() as u64;
        }
        self.written += chunk.len;
        Ok(())
    }

    /// Bytes of one particle's record.
    fn record_bytes(&self) -> usize {
        let d = self.derived;
        let extra = 4 * (d.jacobian as usize + if d.stress { 6 } else { 0 });
        match self.format {
            StreamFormat::Ply { .. } => 32 + extra,
            // P (4), v (3), id, material, plastic, mass, pscale; the stress is a full 3x3.
            StreamFormat::Bgeo { .. } => 48 + extra + if d.stress { 12 } else { 0 },
        }
    }

    /// Complete the file: every particle must have been written; syncs and renames it.
    /// Returns the bytes written (before compression).
    pub fn finish(mut self) -> io::Result<u64> {
        if self.written != self.n {
            return Err(invalid(format!(
                "{} of {} particles written",
                self.written, self.n
            )));
        }
        if matches!(self.format, StreamFormat::Bgeo { .. }) {
            self.sink.writer().write_all(&[0x00, 0xff])?;
            self.bytes += 2;
        }
        let w = match self.sink {
            Sink::Plain(w) => w,
            Sink::Gz(g) => g.finish()?,
        };
        let file = w.into_inner().map_err(|e| e.into_error())?;
        self.guard.commit(file)?;
        Ok(self.bytes)
    }
}

/// The point attributes of a BGEO frame after `P` (as [`super::bgeo::write_bgeo`] writes them).
fn bgeo_attributes(d: Derived) -> Vec<(&'static str, BgeoType, usize)> {
    let mut a = vec![
        ("v", BgeoType::Vector, 3),
        ("id", BgeoType::Int, 1),
        ("material", BgeoType::Int, 1),
        ("plastic", BgeoType::Float, 1),
        ("mass", BgeoType::Float, 1),
        ("pscale", BgeoType::Float, 1),
    ];
    if d.jacobian {
        a.push(("J", BgeoType::Float, 1));
    }
    if d.stress {
        a.push(("stress", BgeoType::Float, 9));
    }
    a
}

/// Appends bytes to a pre-sized slice.
struct Cursor<'a>(&'a mut [u8]);

impl Cursor<'_> {
    /// One 32-bit value (a fixed size, so the copy is a single store).
    #[inline(always)]
    fn put(&mut self, b: [u8; 4]) {
        let (head, tail) = std::mem::take(&mut self.0).split_at_mut(4);
        head.copy_from_slice(&b);
        self.0 = tail;
    }
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// The files of one frame, written together chunk by chunk.
pub struct FrameFiles {
    files: Vec<StreamFile>,
    derived: Derived,
    models: Vec<Model>,
}

impl FrameFiles {
    /// Start the files `(path, format)` of a frame of `n` particles; `models`: the scene's
    /// material models (for the stress). An error names the file.
    pub fn create(
        files: &[(PathBuf, StreamFormat)],
        n: usize,
        derived: Derived,
        models: Vec<Model>,
    ) -> Result<FrameFiles, (PathBuf, io::Error)> {
        let mut out = Vec::new();
        for (path, format) in files {
            let f = StreamFile::create(path, format.clone(), n, derived)
                .map_err(|e| (path.clone(), e))?;
            out.push(f);
        }
        Ok(FrameFiles {
            files: out,
            derived,
            models,
        })
    }

    /// The columns the files need.
    pub fn columns(formats: &[StreamFormat], derived: Derived) -> FrameColumns {
        formats
            .iter()
            .fold(FrameColumns::default(), |c, f| c.union(f.columns(derived)))
    }

    /// Append a chunk to every file. An error names the file.
    pub fn write_chunk(&mut self, chunk: &FrameChunk) -> Result<(), (PathBuf, io::Error)> {
        let first = self.files.first().map(|f| f.path().to_path_buf());
        let fields = ChunkFields::compute(chunk, self.derived, &self.models)
            .map_err(|e| (first.unwrap_or_default(), e))?;
        for f in &mut self.files {
            f.write_chunk(chunk, &fields)
                .map_err(|e| (f.path().to_path_buf(), e))?;
        }
        Ok(())
    }

    /// Complete every file; returns the bytes written. An error names the file (files not yet
    /// renamed are removed).
    pub fn finish(self) -> Result<u64, (PathBuf, io::Error)> {
        let mut bytes = 0;
        for f in self.files {
            let path = f.path().to_path_buf();
            bytes += f.finish().map_err(|e| (path, e))?;
        }
        Ok(bytes)
    }
}
