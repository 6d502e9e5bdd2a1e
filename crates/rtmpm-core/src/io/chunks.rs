//! Frames in chunks: the columns of the particles an output format needs, in original particle
//! order, handed over a chunk at a time (a few million particles), so that a frame of hundreds of
//! millions of particles never sits in host memory as a whole [`Particles`] and its encoding and
//! writing can overlap the copies and the next steps (see [`crate::sim::Backend::export_frame`]
//! and [`super::stream`]).
//!
//! A chunk holds particles `start..start + len` (original indices) as a structure of arrays of
//! 32-bit words: the columns of [`FrameColumns::layout`] in that order, each component a row of
//! `cap` words (`cap`: the chunk's capacity, at least `len`). Float columns hold the bits of an
//! f32 (f64 state rounded to nearest, as [`crate::sim::Backend::read_particles`] rounds it); the
//! material column holds the index as an integer.

use crate::sim::SimError;
use rayon::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// A column of a frame chunk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Column {
    /// Position, 3 components.
    X,
    /// Velocity, 3 components.
    V,
    /// Material index (integer), 1 component.
    Material,
    /// Plastic state, 1 component.
    Plastic,
    /// Mass, 1 component.
    Mass,
    /// Initial volume, 1 component.
    Vol0,
    /// Deformation gradient, 9 components (column-major, as `Mat3::to_cols_array`).
    F,
    /// Affine velocity matrix, 9 components (column-major).
    C,
}

impl Column {
    /// Number of words per particle.
    pub fn components(self) -> usize {
        match self {
            Column::X | Column::V => 3,
            Column::F | Column::C => 9,
            _ => 1,
        }
    }
}

/// Which columns a frame needs besides the positions (always present).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameColumns {
    /// Velocities.
    pub v: bool,
    /// Material indices.
    pub material: bool,
    /// Plastic state.
    pub plastic: bool,
    /// Masses.
    pub mass: bool,
    /// Initial volumes.
    pub vol0: bool,
    /// Deformation gradients (for `J = det F` and stresses).
    pub f: bool,
    /// Affine velocity matrices (for stresses of models that use them).
    pub c: bool,
}

impl FrameColumns {
    /// Every column.
    pub fn all() -> FrameColumns {
        FrameColumns {
            v: true,
            material: true,
            plastic: true,
            mass: true,
            vol0: true,
            f: true,
            c: true,
        }
    }

    /// The union of two sets.
    pub fn union(self, o: FrameColumns) -> FrameColumns {
        FrameColumns {
            v: self.v || o.v,
            material: self.material || o.material,
            plastic: self.plastic || o.plastic,
            mass: self.mass || o.mass,
            vol0: self.vol0 || o.vol0,
            f: self.f || o.f,
            c: self.c || o.c,
        }
    }

    /// The columns present, in chunk order.
    pub fn layout(&self) -> Vec<Column> {
        let mut out = vec![Column::X];
        let all = [
            (self.v, Column::V),
            (self.material, Column::Material),
            (self.plastic, Column::Plastic),
            (self.mass, Column::Mass),
            (self.vol0, Column::Vol0),
            (self.f, Column::F),
            (self.c, Column::C),
        ];
        out.extend(all.iter().filter(|(on, _)| *on).map(|(_, c)| *c));
        out
    }

    /// Words per particle.
    pub fn words(&self) -> usize {
        self.layout().iter().map(|c| c.components()).sum()
    }

    /// The first row (word index within a particle) of `col`, if present.
    pub fn row(&self, col: Column) -> Option<usize> {
        let mut row = 0;
        for c in self.layout() {
            if c == col {
                return Some(row);
            }
            row += c.components();
        }
        None
    }
}

/// Host memory holding chunks: page-locked memory on a GPU backend, a plain vector otherwise.
pub trait HostBuffer: Send {
    /// The words.
    fn words(&self) -> &[u32];
    /// The words, writable.
    fn words_mut(&mut self) -> &mut [u32];
}

impl HostBuffer for Vec<u32> {
    fn words(&self) -> &[u32] {
        self
    }
    fn words_mut(&mut self) -> &mut [u32] {
        self
    }
}

/// One chunk of a frame: particles `start..start + len` (original order), see the module
/// documentation for the layout.
pub struct FrameChunk {
    /// Original index of the first particle.
    pub start: usize,
    /// Particles held.
    pub len: usize,
    /// Capacity in particles: the stride between two rows.
    pub cap: usize,
    /// The columns held.
    pub cols: FrameColumns,
    /// The memory (at least `cap * cols.words()` words).
    pub buf: Box<dyn HostBuffer>,
}

impl FrameChunk {
    /// Row `r` (one component of one column) of the `len` particles.
    pub fn row(&self, r: usize) -> &[u32] {
        &self.buf.words()[r * self.cap..r * self.cap + self.len]
    }

    /// Row `r` as floats.
    pub fn row_f32(&self, r: usize) -> &[f32] {
        bytemuck::cast_slice(self.row(r))
    }

    /// The rows of a column (`None` when the chunk does not hold it).
    pub fn column(&self, col: Column) -> Option<Vec<&[f32]>> {
        let first = self.cols.row(col)?;
        Some(
            (first..first + col.components())
                .map(|r| self.row_f32(r))
                .collect(),
        )
    }

    /// The matrix column `col` (F or C) of particle `j` of the chunk.
    pub fn mat3(rows: &[&[f32]], j: usize) -> Mat3 {
        Mat3::from_cols_array(&std::array::from_fn(|e| rows[e][j]))
    }

    /// The vector of particle `j` from three rows.
    pub fn vec3(rows: &[&[f32]], j: usize) -> Vec3 {
        Vec3::new(rows[0][j], rows[1][j], rows[2][j])
    }
}

/// Where [`crate::sim::Backend::export_frame`] puts the chunks: it hands out empty chunks and
/// takes the filled ones (e.g. to a writer thread).
pub trait ChunkSink {
    /// The columns wanted.
    fn columns(&self) -> FrameColumns;
    /// An empty chunk of capacity [`FrameChunk::cap`] (may wait until a writer gives one back).
    fn take(&mut self) -> Result<FrameChunk, SimError>;
    /// A filled chunk, `start` and `len` set.
    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError>;
}

/// One particle's values, in the interface's f32, for [`fill_chunks`].
#[derive(Clone, Copy, Debug, Default)]
pub struct ParticleRow {
    /// Position.
    pub x: [f32; 3],
    /// Velocity.
    pub v: [f32; 3],
    /// Material index.
    pub material: u32,
    /// Plastic state.
    pub plastic: f32,
    /// Mass.
    pub mass: f32,
    /// Initial volume.
    pub vol0: f32,
    /// Deformation gradient, column-major.
    pub f: [f32; 9],
    /// Affine velocity matrix, column-major.
    pub c: [f32; 9],
}

/// Fill chunks of `n` particles from `row(original index, columns)`, in parallel, and give
/// them to `sink` in order: the export of host-side backends. `row` need only set the fields
/// of the columns asked (the others are not read): each is a random access into storage order.
pub fn fill_chunks(
    n: usize,
    sink: &mut dyn ChunkSink,
    row: impl Fn(usize, FrameColumns) -> ParticleRow + Sync,
) -> Result<(), SimError> {
    let cols = sink.columns();
    let layout = cols.layout();
    let mut start = 0;
    while start < n {
        let mut chunk = sink.take()?;
        let len = chunk.cap.min(n - start);
        if chunk.cap == 0 || chunk.buf.words().len() < chunk.cap * cols.words() {
            return Err(SimError::Backend(
                "frame chunk smaller than its size".into(),
            ));
        }
        let cap = chunk.cap;
        // Each task fills a range of particles of every row.
        const TASK: usize = 1 << 14;
        let words = chunk.buf.words_mut();
        let mut rows: Vec<&mut [u32]> = words.chunks_mut(cap).take(cols.words()).collect();
        let mut per_task: Vec<Vec<&mut [u32]>> = (0..len.div_ceil(TASK)).map(|_| vec![]).collect();
        for r in rows.iter_mut() {
            let r: &mut [u32] = std::mem::take(r);
            for (t, piece) in r[..len].chunks_mut(TASK).enumerate() {
                per_task[t].push(piece);
            }
        }
        per_task
            .into_par_iter()
            .enumerate()
            .for_each(|(t, mut rows)| {
                let first = start + t * TASK;
                for j in 0..rows[0].len() {
                    let p = row(first + j, cols);
                    let mut r = 0;
                    for col in &layout {
                        let mut put = |w: u32| {
                            rows[r][j] = w;
                            r += 1;
                        };
                        let floats = |put: &mut dyn FnMut(u32), vals: &[f32]| {
                            vals.iter().for_each(|v| put(v.to_bits()))
                        };
                        match col {
                            Column::X => floats(&mut put, &p.x),
                            Column::V => floats(&mut put, &p.v),
                            // The integer itself, not through a float.
                            Column::Material => put(p.material),
                            Column::Plastic => put(p.plastic.to_bits()),
                            Column::Mass => put(p.mass.to_bits()),
                            Column::Vol0 => put(p.vol0.to_bits()),
                            Column::F => floats(&mut put, &p.f),
                            Column::C => floats(&mut put, &p.c),
                        }
                    }
                }
            });
        chunk.start = start;
        chunk.len = len;
        sink.put(chunk)?;
        start += len;
    }
    Ok(())
}

/// The chunks of particles already in original order on the host (the default export: after
/// [`crate::sim::Backend::read_particles`]).
pub fn export_particles(p: &Particles, sink: &mut dyn ChunkSink) -> Result<(), SimError> {
    if crate::io::check_particles(p).is_err() {
        return Err(SimError::Backend(
            "particle arrays of unequal lengths".into(),
        ));
    }
    fill_chunks(p.len(), sink, |i, _| ParticleRow {
        x: p.x[i].to_array(),
        v: p.v[i].to_array(),
        material: p.material[i],
        plastic: p.plastic[i],
        mass: p.mass[i],
        vol0: p.vol0[i],
        f: p.f[i].to_cols_array(),
        c: p.c[i].to_cols_array(),
    })
}

/// The inverse of a permutation `ids` (storage slot -> original index): original index ->
/// slot; an error when `ids` is not a permutation of `0..ids.len()`.
pub fn invert_ids(ids: &[u32]) -> Result<Vec<u32>, SimError> {
    let n = ids.len();
    let mut slot = vec![u32::MAX; n];
    for (i, &id) in ids.iter().enumerate() {
        match slot.get_mut(id as usize) {
            Some(s) if *s == u32::MAX => *s = i as u32,
            _ => return Err(SimError::Backend(format!("corrupt particle id {id}"))),
        }
    }
    Ok(slot)
}
