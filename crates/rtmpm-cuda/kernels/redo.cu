// The P2G of some worlds of a batch redone (crate::batch::redo), queued before a step: with
// G2P2G the grid the coming step reads holds the last fused scatter, of the particles as they
// were; worlds put since (a reset, a state given) need theirs again, the others' is still right.
// `redo_clear` zeroes the pblocks of the worlds listed, `redo_p2g` scatters their particles
// again, the warp scatter of the P2G kernel (p2g_warp_entry, p2g/warp.cuh); every other world's
// nodes are left as they are. MLS-MPM only: a batch takes no CK-MPM scene (batch/accept.rs).
//
// Which pblocks and warps are a world's: the world of a block is its x block coordinate's
// stripe (node_world; crate::batch::layout: each world's stripe is whole blocks and holds every
// node its particles reach, the neighbour blocks too), a warp's that of its gblock. Neither the
// pblock ids nor the warp list are in world order (ids are given in hash-table order at a
// rebuild), so each kernel tests every pblock or warp entry against the runs listed.
//
// Both kernels do nothing when the step will redo every world's P2G anyway: a rebuild is due
// (a put particle left its zone, the mapping the scatter would use no longer holds it), the
// host asked for the full P2G (CTL_P2G_PENDING: first step, new dt, a put the redo does not
// cover), every step rebuilds, or an error stopped the run. The flags are not changed between
// the two launches, so both take the same decision.
#include "p2g/warp.cuh"

#ifndef P2G_MIN_BLOCKS
#define P2G_MIN_BLOCKS 1
#endif

struct RedoWorlds {
    unsigned count;
    unsigned lo[REDO_RANGES], hi[REDO_RANGES];  // run i: worlds lo[i] .. hi[i] - 1
};

__device__ __forceinline__ bool redo_listed(const RedoWorlds& r, unsigned world) {
    for (unsigned i = 0; i < r.count && i < REDO_RANGES; ++i)
        if (world >= r.lo[i] && world < r.hi[i]) return true;
    return false;
}

// The world of pblock `id` (0 in a program of one world).
__device__ __forceinline__ unsigned redo_block_world(const Ctx& c, unsigned id) {
#ifdef RTMPM_BATCH
    int bx = c.block_coords[3 * id];
    return bx < 0 ? ~0u : node_world(4 * bx);
#else
    return 0u;
#endif
}

__device__ __forceinline__ bool redo_skipped(const Ctx& c) {
    const volatile unsigned* ctl = c.ctl;
    return !c.grid_next || c.always_rebuild || ctl[CTL_ERROR] || ctl[CTL_NEED_REBUILD] ||
           ctl[CTL_P2G_PENDING];
}

// The nodes of the listed worlds' pblocks (and grid_aux's, where there is one), as
// grid_clear_body (rebuild.cu) clears every pblock: a warp a pblock, its 256 words by the lanes.
extern "C" __global__ void redo_clear(Ctx c, RedoWorlds r) {
    if (redo_skipped(c)) return;
    unsigned pblocks = min(c.ctl[CTL_PBLOCKS], c.pblock_cap), stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned id = thread_index() >> 5; id < pblocks; id += stride) {
        if (!redo_listed(r, redo_block_world(c, id))) continue;
        for (unsigned t = id * 256u + lane; t < id * 256u + 256u; t += 32) {
            c.grid[t] = 0;
            if (c.grid_aux) c.grid_aux[t] = 0;
        }
    }
}

// The warp list's entries of the listed worlds' gblocks, as `p2g` (p2g/scatter.cu) scatters them.
extern "C" __global__ void __launch_bounds__(128, P2G_MIN_BLOCKS) redo_p2g(Ctx c, RedoWorlds r) {
    if (redo_skipped(c)) return;
    unsigned n_warps = min(c.ctl[CTL_WARPS], c.warp_cap), stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w];
        if (redo_listed(r, redo_block_world(c, g)))
            p2g_warp_entry(c, g, c.warps[3 * w + 1], c.warps[3 * w + 2], lane);
    }
}

// The redo's kernels as launched by default (crate::batch::redo; RTMPM_BATCH_REDO=wave launches
// the two above): the same nodes cleared and the same entries scattered, found with a lane an
// item. A warp tests 32 pblocks (`redo_clear_lanes`) or REDO_ENTRIES_PER_WARP warp-list entries
// (`redo_p2g_lanes`) at once and then clears or scatters those of the worlds listed one after
// another, so the host launches a thread a pblock (where `redo_clear` takes a warp each, a full
// wave). A warp-list entry's scatter is long (the warp's particles' stresses, then the shuffles
// and atomics of nine rows): two in one warp would double the launch's longest warp, so
// REDO_ENTRIES_PER_WARP is 1, the entries spread over the warps as `redo_p2g` spreads them. Both
// read the flags together, not one after the other.
__device__ __forceinline__ bool redo_skipped_at_once(const Ctx& c) {
    const volatile unsigned* ctl = c.ctl;
    unsigned e = ctl[CTL_ERROR], r = ctl[CTL_NEED_REBUILD], p = ctl[CTL_P2G_PENDING];
    return !c.grid_next || c.always_rebuild || (e | r | p) != 0;
}

extern "C" __global__ void redo_clear_lanes(Ctx c, RedoWorlds r) {
    if (redo_skipped_at_once(c)) return;
    unsigned pblocks = min(c.ctl[CTL_PBLOCKS], c.pblock_cap), lane = threadIdx.x & 31;
    for (unsigned first = thread_index() & ~31u; first < pblocks; first += gridDim.x * blockDim.x) {
        unsigned id = first + lane;
        bool listed = id < pblocks && redo_listed(r, redo_block_world(c, id));
        for (unsigned m = __ballot_sync(0xffffffffu, listed); m != 0; m &= m - 1) {
            unsigned b = first + (unsigned)(__ffs(m) - 1);
            for (unsigned t = b * 256u + lane; t < b * 256u + 256u; t += 32) {
                c.grid[t] = 0;
                if (c.grid_aux) c.grid_aux[t] = 0;
            }
        }
    }
}

extern "C" __global__ void __launch_bounds__(128, P2G_MIN_BLOCKS) redo_p2g_lanes(Ctx c, RedoWorlds r) {
    if (redo_skipped_at_once(c)) return;
    unsigned n_warps = min(c.ctl[CTL_WARPS], c.warp_cap), lane = threadIdx.x & 31;
    unsigned step = ((gridDim.x * blockDim.x) >> 5) * REDO_ENTRIES_PER_WARP;
    for (unsigned w0 = (thread_index() >> 5) * REDO_ENTRIES_PER_WARP; w0 < n_warps; w0 += step) {
        unsigned w = w0 + lane;
        bool listed = lane < REDO_ENTRIES_PER_WARP && w < n_warps && redo_listed(r, redo_block_world(c, c.warps[3 * w]));
        for (unsigned m = __ballot_sync(0xffffffffu, listed); m != 0; m &= m - 1) {
            unsigned e = w0 + (unsigned)(__ffs(m) - 1);
            p2g_warp_entry(c, c.warps[3 * e], c.warps[3 * e + 1], c.warps[3 * e + 2], lane);
        }
    }
}
