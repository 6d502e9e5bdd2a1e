//! Where the worlds of a batch lie in the grid: side by side along x, each in a stripe of
//! [`world_stride`] cells, and the parameters of that layout the kernels read ([`BatchParams`]).

/// Cells from the start of a world's stripe of the grid to its grid origin.
pub const WORLD_ORIGIN_CELLS: usize = 8;
/// Cells at least between the last node a world can touch and the first of the next world.
pub const WORLD_GAP_CELLS: usize = 5;
/// Cells along x the block codes can address (19 bits of block coordinate, 4 cells a block).
pub const MAX_GRID_CELLS_X: usize = 4 << 19;

/// The parameters of a batch in constant memory (`c_batch`, `kernels/common.cuh`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BatchParams {
    /// Worlds.
    pub worlds: u32,
    /// Materials of one world (rows `w * materials ..` of the table are world `w`'s).
    pub materials: u32,
    /// Cells along x from one world's grid to the next.
    pub stride: u32,
    /// Cells from a world's stripe start to its grid origin ([`WORLD_ORIGIN_CELLS`]).
    pub origin: u32,
    /// Device address of the gravity table: 3 reals per world.
    pub gravity: u64,
    /// Device address of the worlds' own collider records (`worlds x n_colliders`), or 0: the
    /// scene's serve every world.
    pub colliders: u64,
    /// Device address of the worlds' own collider poses (one `ColliderPoses` per world), or 0.
    pub poses: u64,
}

/// Cells along x from one world's grid to the next, for worlds of `n_cells_x` cells: a world's
/// nodes lie from 4 cells below its domain (the grid's margin; the neighbour blocks of the free
/// zone reach one block further) to 11 past it (stencil, block rounding, neighbour block), so
/// they fill `[WORLD_ORIGIN_CELLS - 4, WORLD_ORIGIN_CELLS + n_cells_x + 11]` of its stripe.
pub fn world_stride(n_cells_x: usize) -> usize {
    (WORLD_ORIGIN_CELLS + n_cells_x + 12 + WORLD_GAP_CELLS).div_ceil(4) * 4
}
