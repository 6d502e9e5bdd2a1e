//! The sparse grid layout of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022).
//!
//! * Nodes are grouped in blocks of 4x4x4 ([`codes::BLOCK_SIZE`]); only blocks near particles
//!   exist in memory.
//! * Each node has a 64-bit code: the interleaved block coordinates in the high bits (block code)
//!   and `(i1 i0 j1 j0 k1 k0)` in the low 6 bits (cell code), see [`codes`].
//! * The sorted list of block codes turns a block code into a dense 32-bit id (binary search,
//!   [`layout::BlockLayout`]; the CUDA backend keeps a hash table on the device).
//! * Particle blocks are shifted by -0.5 dx from grid blocks: a particle belongs to the block of
//!   its stencil's base node `floor(x / dx - 0.5)`.
//! * gblocks are the blocks that hold particles; pblocks are the gblocks plus their 3x3x3
//!   neighbours, and every gblock lists its 27 neighbour pblock ids explicitly.

pub mod codes;
pub mod layout;

pub use layout::BlockLayout;
