//! Particle frames written chunk by chunk ([`super::chunks`]): PLY and BGEO (plain or gzip)
//! files byte for byte the same as [`super::ply::write_ply_with_comments`] and
//! [`super::bgeo::write_bgeo`] write for the same particles, without the whole frame in memory.
//! Each file is written under a temporary name and renamed when complete
//! ([`super::atomic::AtomicFile`]): an error or a crash leaves no partial file.
//!
//! The derived fields (`J = det F`, the Cauchy stress) are computed per chunk from the columns
//! `F`, `C`, `plastic` and `material`, with the same f32 arithmetic as the whole-frame writers.

use super::atomic::AtomicFile;
use super::chunks::{Column, FrameChunk, FrameColumns};
use crate::frame::{ChunkEncoder, ChunkRows, FrameFormat};
use rayon::prelude::*;
use rtmpm_physics::material::Model;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

pub use crate::frame::Derived;

/// A frame file format that can be written in chunks: a format of [`crate::FRAME_FORMATS`]
/// with a chunk encoder, and the comment lines of its header (for formats that have some).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StreamFormat {
    /// The format.
    pub format: &'static FrameFormat,
    /// One-line comments of the header (PLY; ignored by formats without comments).
    pub comments: Vec<String>,
}

impl StreamFormat {
    /// `format` with the header comments `comments`; `None` when the format cannot be written
    /// in chunks.
    pub fn new(format: &'static FrameFormat, comments: Vec<String>) -> Option<StreamFormat> {
        format
            .streamable()
            .then_some(StreamFormat { format, comments })
    }

    /// The encoder (an error for a format without one).
    fn encoder(&self) -> io::Result<&'static dyn ChunkEncoder> {
        self.format.chunks.ok_or_else(|| {
            invalid(format!(
                "the {} format cannot be written in chunks",
                self.format.name
            ))
        })
    }

    /// The columns this format needs (with `derived`).
    pub fn columns(&self, derived: Derived) -> FrameColumns {
        let mut c = FrameColumns {
            v: true,
            material: true,
            plastic: true,
            ..FrameColumns::default()
        };
        if let Ok(e) = self.encoder() {
            c = c.union(e.columns(derived));
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
    encoder: &'static dyn ChunkEncoder,
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
        let encoder = format.encoder()?;
        let comments: Vec<&str> = format.comments.iter().map(String::as_str).collect();
        let header = encoder.header(n, derived, &comments)?;
        let (guard, file) = AtomicFile::create(path)?;
        let w = BufWriter::with_capacity(1 << 20, file);
        let mut sink = match encoder.gzip() {
            true => Sink::Gz(flate2::write::GzEncoder::new(
                w,
                flate2::Compression::fast(),
            )),
            false => Sink::Plain(w),
        };
        sink.writer().write_all(&header)?;
        Ok(StreamFile {
            guard,
            sink,
            encoder,
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
        let rows = self.rows(chunk, fields)?;
        let rec = self.encoder.record_bytes(self.derived);
        // Encoded a block at a time into a buffer reused for the whole file (a few MB, not
        // the chunk's size), in parallel, then written.
        let block = BLOCK.min(chunk.len);
        if self.encoded.len() < block * rec {
            self.encoded.resize(block * rec, 0);
        }
        let encoder = self.encoder;
        for lo in (0..chunk.len).step_by(BLOCK.max(1)) {
            let hi = (lo + BLOCK).min(chunk.len);
            let buf = &mut self.encoded[..(hi - lo) * rec];
            buf.par_chunks_mut(rec * TASK)
                .enumerate()
                .try_for_each(|(t, out)| {
                    encoder.encode(&rows, lo + t * TASK, out.len() / rec, out)
                })?;
            self.sink.writer().write_all(buf)?;
            self.bytes += buf.len() as u64;
        }
        self.written += chunk.len;
        Ok(())
    }

    /// The columns of `chunk` and its derived `fields` as the encoder reads them.
    fn rows<'a>(
        &self,
        chunk: &'a FrameChunk,
        fields: &'a ChunkFields,
    ) -> io::Result<ChunkRows<'a>> {
        let cols = |c: Column| {
            chunk
                .column(c)
                .ok_or_else(|| invalid(format!("frame chunk without the column {c:?}")))
        };
        let three = |c: Column| -> io::Result<[&'a [f32]; 3]> {
            let r = cols(c)?;
            Ok([r[0], r[1], r[2]])
        };
        let mat_row = chunk
            .cols
            .row(Column::Material)
            .ok_or_else(|| invalid("frame chunk without materials".into()))?;
        let material = chunk.row(mat_row);
        if let Some(m) = material.iter().find(|&&m| m > i32::MAX as u32) {
            return Err(invalid(format!(
                "material index {m} does not fit the file's 32-bit int"
            )));
        }
        let jacobian = match (self.derived.jacobian, &fields.jacobian) {
            (false, _) => None,
            (true, Some(j)) if j.len() == chunk.len => Some(j.as_slice()),
            _ => return Err(invalid("J missing for the chunk".into())),
        };
        let stress = match (self.derived.stress, &fields.stress) {
            (false, _) => None,
            (true, Some(s)) if s.len() == chunk.len => Some(s.as_slice()),
            _ => return Err(invalid("stress missing for the chunk".into())),
        };
        let wants = self.encoder.columns(self.derived);
        let optional = |on: bool, c: Column| -> io::Result<Option<&'a [f32]>> {
            Ok(if on { Some(cols(c)?[0]) } else { None })
        };
        Ok(ChunkRows {
            start: chunk.start,
            x: three(Column::X)?,
            v: three(Column::V)?,
            material,
            plastic: cols(Column::Plastic)?[0],
            mass: optional(wants.mass, Column::Mass)?,
            vol0: optional(wants.vol0, Column::Vol0)?,
            jacobian,
            stress,
        })
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
        let trailer = self.encoder.trailer();
        self.sink.writer().write_all(trailer)?;
        self.bytes += trailer.len() as u64;
        let w = match self.sink {
            Sink::Plain(w) => w,
            Sink::Gz(g) => g.finish()?,
        };
        let file = w.into_inner().map_err(|e| e.into_error())?;
        self.guard.commit(file)?;
        Ok(self.bytes)
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
