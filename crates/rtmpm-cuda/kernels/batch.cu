// Batches of worlds (crate::batch): one world's particles put back into the state (a reset to
// its initial state, or to a given one), wherever the sort has moved them. `src` holds the
// world's `count` particles, structure of arrays with stride `stride` (`count` for a put's own
// image; the batch's kept image of every world's initial particles has stride n, `src` then
// pointing at particle `first` of its first row), in original order from `first`; a slot whose
// id lies in [first, first + count) takes every word of its particle but the id. Launched in
// the batch's program; compiled in every program (there a particle's world is 0).
//
// The mapping is rebuilt only when a particle put needs it (not for every put, which would
// rebuild every world's mapping for a few worlds' reset). The last rebuild sorted the slots by
// gblock: gblock g's are hist[64 g] up to the next gblock's first (the bucket starts, which
// stay until the next rebuild, as the shared-memory P2G reads them), and a step needs no
// rebuild while each particle's stencil base lies in its gblock B's free zone, [4B - 4, 4B + 5]
// per axis (G2P's rule, g2p_finish in g2p/particle.cuh). So each particle put is checked
// against the zone of its slot's gblock, found by a binary search of those starts, and the
// kernel sets the rebuild flag where one leaves it, as G2P does. Where the flag is already set
// (a rebuild is due anyway, or none was made yet) nothing is checked.
#include "common.cuh"

// The gblock the last rebuild sorted slot `i` into: the last of the `gblocks` whose first slot
// (the start of its first bucket) is at most `i`.
__device__ __forceinline__ unsigned slot_gblock(const Ctx& c, unsigned i, unsigned gblocks) {
    unsigned lo = 0, hi = gblocks;  // the answer in [lo, hi)
    while (hi - lo > 1) {
        unsigned mid = lo + (hi - lo) / 2;
        if (c.hist[mid * 64u] <= i) lo = mid;
        else hi = mid;
    }
    return lo;
}

extern "C" __global__ void batch_put_world(Ctx c, const real* src, unsigned first, unsigned count,
                                           unsigned stride) {
    unsigned gblocks = min(c.ctl[CTL_GBLOCKS], c.gblock_cap);
    bool check = ((volatile unsigned*)c.ctl)[CTL_NEED_REBUILD] == 0 && c.ctl[CTL_ERROR] == 0;
    bool rebuild = false;
    for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
        unsigned k = state_bits(c.state[sidx(c.cap, F_ID, i)]) - first;
        if (k >= count) continue;
        if (check && gblocks == 0) {
            rebuild = true;
        } else if (check) {
            const int* bc = c.block_coords + 3 * slot_gblock(c, i, gblocks);
            vec3 x = make_v3(src[(size_t)F_X * stride + k], src[(size_t)(F_X + 1) * stride + k],
                             src[(size_t)(F_X + 2) * stride + k]);
            int nb[3];
            real fx[3];
            stencil_of(c, x, particle_world(c, i), nb, fx);
            for (int a = 0; a < 3; ++a) rebuild = rebuild || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
        }
        for (int f = 0; f < RTMPM_NFIELDS; ++f)
            if (f != F_ID) c.state[sidx(c.cap, f, i)] = src[(size_t)f * stride + k];
    }
    if (rebuild) c.ctl[CTL_NEED_REBUILD] = 1;
}
