//! Frames in chunks: the columns of the particles an output format needs, in original particle
//! order, handed over a chunk at a time (a few million particles), so that a frame of hundreds of
//! millions of particles never sits in host memory as a whole `Particles` and its encoding and
//! writing can overlap the copies and the next steps (see `rtmpm_sim::Backend::export_frame`
//! and [`crate::stream`]).
//!
//! A chunk holds particles `start..start + len` (original indices) as a structure of arrays of
//! 32-bit words: the columns of [`FrameColumns::layout`] in that order, each component a row of
//! `cap` words (`cap`: the chunk's capacity, at least `len`). Float columns hold the bits of an
//! f32 (f64 state rounded to nearest, as `rtmpm_sim::Backend::read_particles` rounds it); the
//! material column holds the index as an integer.

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

/// One particle's values, in the interface's f32, for `rtmpm_sim::fill_chunks`.
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
