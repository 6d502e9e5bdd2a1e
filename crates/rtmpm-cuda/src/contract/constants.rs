//! The constants the kernels and the host share: the fill and sample tables' word layouts,
//! control words, error bits, limits, and the collider, boundary and stress-update codes
//! (emitted into `contract.cuh` by [`super::prelude`]).

use super::state_layout::MAX_FIELDS;
use rtmpm_geometry::Shape;
use rtmpm_physics::boundary::Condition;
use rtmpm_physics::transfer::Update;

// ---------------------------------------------------------------------------------------------
// Particle state: structure of arrays, word w of particle i at state[w * cap + i]; the words of
// each field are given by the backend's [`StateLayout`] (state_layout.rs).

// ---------------------------------------------------------------------------------------------
// The body table of the device fill (`kernels/fill.cu`, `crate::setup::fill`): one row of u32
// words per sampled body; reals as f32 bits.

/// Words of one row of the fill table.
pub const FILL_WORDS: usize = FT_CONST + 3 * MAX_FIELDS;
/// First particle (slot and original index) of the body: low, then high 32 bits.
pub const FT_START: usize = 0;
/// Particles of the body: low, then high 32 bits.
pub const FT_COUNT: usize = 2;
/// Initial velocity v0 (3 f32).
pub const FT_V0: usize = 4;
/// Angular velocity w (3 f32).
pub const FT_W: usize = 7;
/// Centre c of the rotation (3 f32): v = v0 + w x (x - c).
pub const FT_CENTRE: usize = 10;
/// Number of constant words.
pub const FT_NCONST: usize = 13;
/// The constant words: (state word, low 32 bits, high 32 bits) each, the word's bits in the
/// state's precision (an f32 word: the low bits).
pub const FT_CONST: usize = 14;

// ---------------------------------------------------------------------------------------------
// The recipe of a deferred body's walk (`kernels/sample.cu`, `crate::setup::sample`): u32
// words; reals as f32 bits, 64- and 128-bit integers low word first.

/// Words of one recipe.
pub const SAMPLE_WORDS: usize = SP_TRIES + 2;
/// Origin of the lattice (3 f32): point (i, j, k) is `origin + (i + 1/2, j + 1/2, k + 1/2) h`.
pub const SP_ORIGIN: usize = 0;
/// Lattice spacing h (f32).
pub const SP_H: usize = 3;
/// First lattice index per axis (3 i64).
pub const SP_FIRST: usize = 4;
/// Points per row (along x, u64).
pub const SP_NX: usize = 10;
/// Rows per layer (along y, u64): row r is `j = r % ny`, `k = r / ny`.
pub const SP_NY: usize = 12;
/// 1: each point moved by a uniform jitter of its sub-cell (three draws of the stream).
pub const SP_JITTER: usize = 14;
/// The random stream's 128-bit state at the walk's first point.
pub const SP_STATE: usize = 15;
/// The stream's 128-bit (odd) increment.
pub const SP_INC: usize = 19;
/// The shape's kind code ([`rtmpm_geometry::Shape::code`]; `SHAPE_*` in the kernels).
pub const SP_SHAPE: usize = 23;
/// The shape's parameters (8 f32, [`rtmpm_geometry::shape::ShapeKind::gpu`]).
pub const SP_PARAMS: usize = 24;
/// A mesh's distance grid dimensions (3 u32; its values in a buffer of their own).
pub const SP_DIMS: usize = SP_PARAMS + 8;
/// The walk (`SAMPLE_LATTICE`, `SAMPLE_RANDOM`).
pub const SP_KIND: usize = SP_DIMS + 3;
/// Random tries: the box's upper corner (3 f32; `SP_ORIGIN` is the lower).
pub const SP_HI: usize = SP_KIND + 1;
/// Random tries: the tries (u64).
pub const SP_TRIES: usize = SP_HI + 3;
/// Walk codes of a recipe.
pub const SAMPLE_LATTICE: u32 = 0;
pub const SAMPLE_RANDOM: u32 = 1;
/// Random tries a device row (one thread) makes.
pub const SAMPLE_TRIES_PER_ROW: u64 = 64;

// ---------------------------------------------------------------------------------------------
// Control words (u32, one array per GPU).

/// Rebuild the mapping at the next step.
pub const CTL_NEED_REBUILD: usize = 0;
/// Gblock count.
pub const CTL_GBLOCKS: usize = 1;
/// Pblock count.
pub const CTL_PBLOCKS: usize = 2;
/// Error bits (`ERR_*`).
pub const CTL_ERROR: usize = 3;
/// First bad particle: `original index << 1 | reason` (reason 0: not finite, 1: too fast;
/// `u32::MAX`: none), see [`bad_particle`].
pub const CTL_BAD_INDEX: usize = 4;
/// Unused (reset with [`CTL_BAD_INDEX`]): the reason is in that word's low bit.
pub const CTL_BAD_REASON: usize = 5;

/// The bad particle of the health check's control word [`CTL_BAD_INDEX`], as the kernels
/// write it (`atomicMin` of `id << 1 | reason`: the lowest id and its own reason).
pub fn bad_particle(word: u32) -> Option<rtmpm_sim::BadParticle> {
    (word != u32::MAX).then_some(rtmpm_sim::BadParticle {
        index: (word >> 1) as usize,
        reason: if word & 1 == 0 {
            rtmpm_sim::BadReason::NonFinite
        } else {
            rtmpm_sim::BadReason::TooFast
        },
        seen: None,
    })
}
/// Max speed of the step (f32 bits).
pub const CTL_MAX_SPEED: usize = 6;
/// Rebuilds so far.
pub const CTL_REBUILDS: usize = 7;
/// Warp count.
pub const CTL_WARPS: usize = 8;
/// Scratch of the rebuild (extra warps of the warp list).
pub const CTL_EXTRA: usize = 9;
/// Gblock count before the neighbour insertion of a rebuild.
pub const CTL_PREV_GBLOCKS: usize = 10;
/// 1 when the mapping was rebuilt in this step (several GPUs: the occupancy mask is redone).
pub const CTL_REBUILT_NOW: usize = 11;
/// Blocks shared with other GPUs.
pub const CTL_SHARED: usize = 12;
/// Capacity of the shared-block reduction (blocks).
pub const CTL_SHARED_CAP: usize = 13;
/// Grid barrier of the fused rebuild (`rb_fused`): blocks arrived.
pub const CTL_BARRIER_COUNT: usize = 14;
/// Grid barrier of the fused rebuild: generation.
pub const CTL_BARRIER_GEN: usize = 15;
/// G2P2G: the grid of the coming step still needs its P2G (first step, new dt).
pub const CTL_P2G_PENDING: usize = 16;
/// Number of control words.
pub const CTL_WORDS: usize = 17;

// ---------------------------------------------------------------------------------------------
// Error bits of CTL_ERROR, with what the host says of each.

/// The block hash table is full.
pub const ERR_HASH: u32 = 1;
/// More gblocks than allocated.
pub const ERR_GBLOCKS: u32 = 2;
/// More pblocks than allocated.
pub const ERR_PBLOCKS: u32 = 4;
/// More warps than allocated.
pub const ERR_WARPS: u32 = 8;
/// The reverse map of the gather P2G is full.
pub const ERR_P2G_MAP: u32 = 16;
/// More blocks shared between GPUs than the reduction holds.
pub const ERR_SHARED: u32 = 32;
/// The inter-GPU spin barrier timed out.
pub const ERR_BARRIER: u32 = 64;
/// The capacity errors of the mapping (hash, gblocks, pblocks, warps).
pub const ERR_MAPPING: u32 = ERR_HASH | ERR_GBLOCKS | ERR_PBLOCKS | ERR_WARPS;

// ---------------------------------------------------------------------------------------------
// Limits and codes.

/// Colliders a scene may have on the GPU (constant-memory table).
pub const MAX_COLLIDERS: usize = 16;
/// Materials a scene may have on the GPU (constant-memory table).
pub const MAX_MATERIALS: usize = 64;
/// Rigid bodies a scene may have on the GPU (constant-memory table).
pub const MAX_BODIES: usize = 32;
/// Runs of consecutive worlds a batch's redo of some worlds' P2G takes at once
/// ([`RedoWorlds`], a kernel argument; more runs fall back to the full redo).
pub const REDO_RANGES: usize = 32;
/// Gblocks a warp of `batch_put_gblocks` tests at once (`kernels/batch.cu`: it then puts the
/// slots of the put worlds' ones among them one after another): the launch is
/// `gblock_cap * 32 / PUT_GBLOCKS_PER_WARP` threads.
pub const PUT_GBLOCKS_PER_WARP: usize = 8;
/// Warp-list entries a warp of `redo_p2g_lanes` tests at once (`kernels/redo.cu`: it then
/// scatters those of the worlds listed one after another): the launch is
/// `warp_cap * 32 / REDO_ENTRIES_PER_WARP` threads (one wave at most). 1: an entry's scatter is
/// the launch's longest path, two in one warp would double it (not measured).
pub const REDO_ENTRIES_PER_WARP: usize = 1;
/// Copies of the rigid bodies' impulse sums (thread blocks add to copy `blockIdx.x % slots`, so
/// fewer atomics meet on one address); the host sums them.
pub const BODY_EXCHANGE_SLOTS: usize = 32;
/// Most GPUs of transport=p2p.
pub const MAX_PEER_GPUS: usize = 8;
/// `real` parameters per material on the GPU (the largest model's).
pub const MATERIAL_PARAMS: usize = 8;

/// Collider shape codes (`GpuCollider::kind`): the shape's registry code ([`Shape::code`]).
pub fn collider_kind(s: &Shape) -> u32 {
    s.code()
}

/// Boundary condition codes (walls and colliders).
pub fn condition(c: Condition) -> u32 {
    match c {
        Condition::Sticky => 0,
        Condition::Slip => 1,
        Condition::Separate => 2,
    }
}

/// Stress update code (`Ctx::update`).
pub fn update(u: Update) -> u32 {
    match u {
        Update::Usl => 0,
        Update::Musl => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_sim::BadReason;

    /// The key the kernels' `atomicMin` keeps: the lowest index wins whatever the reasons, and
    /// its own reason comes back with it; `u32::MAX` is none.
    #[test]
    fn the_bad_particle_word_keeps_the_lowest_index_with_its_reason() {
        let key = |id: u32, finite: bool| (id << 1) | u32::from(finite);
        let words = [key(7, true), key(3, false), key(5, true), key(3, true)];
        let first = bad_particle(words.into_iter().fold(u32::MAX, u32::min)).expect("bad");
        assert_eq!((first.index, first.reason), (3, BadReason::NonFinite));
        let fast = bad_particle(key(1_000_000_000, true)).expect("bad");
        assert_eq!(
            (fast.index, fast.reason),
            (1_000_000_000, BadReason::TooFast)
        );
        assert!(fast.seen.is_none());
        assert!(bad_particle(u32::MAX).is_none());
    }
}
