//! Particle frame formats: what a format is ([`FrameFormat`]), the frame it writes ([`Frame`])
//! and, for a format that can be written while the simulation goes on, its chunk encoder
//! ([`ChunkEncoder`], used by [`crate::stream`]). The formats themselves are listed in
//! [`crate::FRAME_FORMATS`]: a new format is a module with its writer and a `FORMAT` value, and
//! one line of that list; the command line, the Python package, the budget and the streamed
//! writer all take the formats from there.

use crate::chunks::FrameColumns;
use crate::fields::FrameFields;
use glam::{Quat, Vec3};
use rtmpm_geometry::Shape;
use rtmpm_physics::Particles;
use std::io;
use std::path::Path;

/// The optional derived fields of a frame (the `[output]` switches `jacobian` and `stress`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Derived {
    /// `J = det F` per particle.
    pub jacobian: bool,
    /// Cauchy stress per particle.
    pub stress: bool,
}

/// A rigid body of a frame: its name (from the scene), shape (body frame) and pose.
pub struct FrameBody<'a> {
    /// The body's name in the scene.
    pub name: &'a str,
    /// Its shape, in the body frame.
    pub shape: &'a Shape,
    /// Centre of mass in the world (m).
    pub position: Vec3,
    /// Body to world.
    pub rotation: Quat,
}

/// One frame as a format writes it.
#[derive(Clone, Copy)]
pub struct Frame<'a> {
    /// The particles.
    pub particles: &'a Particles,
    /// The derived fields written with them.
    pub fields: FrameFields<'a>,
    /// One-line comments naming the run (formats with comments keep them in their header).
    pub comments: &'a [&'a str],
    /// The scene's rigid bodies at their poses (formats that hold a scene draw them).
    pub bodies: &'a [FrameBody<'a>],
    /// Compress the arrays where the format can (`[output] compress`).
    pub compress: bool,
}

/// Bytes per particle of one frame file: the base record, and what `J` and the stress add
/// (for the disk budget; an upper bound for compressed formats).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameBytes {
    /// The record without derived fields.
    pub base: u64,
    /// Added by `J`.
    pub jacobian: u64,
    /// Added by the stress.
    pub stress: u64,
}

impl FrameBytes {
    /// Bytes per particle with the fields `derived`.
    pub fn with(&self, derived: Derived) -> u64 {
        self.base
            + if derived.jacobian { self.jacobian } else { 0 }
            + if derived.stress { self.stress } else { 0 }
    }
}

/// A particle frame format: an entry of [`crate::FRAME_FORMATS`].
pub struct FrameFormat {
    /// Its name in a scene's `[output] formats`, in Python's `write_frame(format=...)` and in
    /// `rtmpm bench --frame-formats`.
    pub name: &'static str,
    /// The file name extension, without the dot (`frame_NNNNN.<extension>`).
    pub extension: &'static str,
    /// What it is and what reads it, one line.
    pub about: &'static str,
    /// Bytes per particle of a frame file.
    pub bytes: FrameBytes,
    /// Write a whole frame at a path, atomically (an error leaves no partial file).
    pub write: fn(&Path, &Frame) -> io::Result<()>,
    /// The frames are listed in the run's `frames.pvd` (ParaView's time series).
    pub pvd: bool,
    /// The chunk encoder, for a format that can be written in chunks of particles while the
    /// simulation goes on; `None`: whole frames only.
    pub chunks: Option<&'static dyn ChunkEncoder>,
}

impl FrameFormat {
    /// Frames of this format can be streamed in chunks ([`crate::stream`]).
    pub fn streamable(&self) -> bool {
        self.chunks.is_some()
    }

    /// The file name of frame `frame`: `frame_NNNNN.<extension>`.
    pub fn file_name(&self, frame: u64) -> String {
        format!("frame_{frame:05}.{}", self.extension)
    }
}

impl std::fmt::Debug for FrameFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FrameFormat({})", self.name)
    }
}

impl PartialEq for FrameFormat {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Eq for FrameFormat {}

/// The columns of a chunk of particles, as a chunk encoder reads them (particle `j` of the
/// chunk is original particle `start + j`).
pub struct ChunkRows<'a> {
    /// Original index of the chunk's first particle.
    pub start: usize,
    /// Positions, one row per component.
    pub x: [&'a [f32]; 3],
    /// Velocities, one row per component.
    pub v: [&'a [f32]; 3],
    /// Material indices.
    pub material: &'a [u32],
    /// Plastic state.
    pub plastic: &'a [f32],
    /// Masses, when the encoder asked for them ([`ChunkEncoder::columns`]).
    pub mass: Option<&'a [f32]>,
    /// Initial volumes, when asked for.
    pub vol0: Option<&'a [f32]>,
    /// `J`, when the frame has it.
    pub jacobian: Option<&'a [f32]>,
    /// Cauchy stress `[xx, yy, zz, xy, yz, xz]`, when the frame has it.
    pub stress: Option<&'a [[f32; 6]]>,
}

/// A format's encoder of particle records, for frames written chunk by chunk: a header, fixed
/// size records in particle order, a trailer; the bytes are those of the format's whole-frame
/// writer for the same particles.
pub trait ChunkEncoder: Sync {
    /// The columns a record needs besides positions, velocities, materials and plastic state
    /// (always present).
    fn columns(&self, derived: Derived) -> FrameColumns;
    /// The header of a file of `n` particles.
    fn header(&self, n: usize, derived: Derived, comments: &[&str]) -> io::Result<Vec<u8>>;
    /// Bytes of one particle's record.
    fn record_bytes(&self, derived: Derived) -> usize;
    /// The records of particles `first..first + count` of `rows` into `out` (`count` records).
    /// `rows` holds what [`ChunkEncoder::columns`] asked for, and the frame's derived fields
    /// (an error when a column is missing).
    fn encode(
        &self,
        rows: &ChunkRows,
        first: usize,
        count: usize,
        out: &mut [u8],
    ) -> io::Result<()>;
    /// The bytes after the last record.
    fn trailer(&self) -> &'static [u8] {
        &[]
    }
    /// The file is gzip-compressed.
    fn gzip(&self) -> bool {
        false
    }
}

/// Appends 32-bit values to a pre-sized slice (for [`ChunkEncoder::encode`]).
pub struct Records<'a>(pub &'a mut [u8]);

impl Records<'_> {
    /// One 32-bit value (a fixed size, so the copy is a single store).
    #[inline(always)]
    pub fn put(&mut self, b: [u8; 4]) {
        let (head, tail) = std::mem::take(&mut self.0).split_at_mut(4);
        head.copy_from_slice(&b);
        self.0 = tail;
    }
}
