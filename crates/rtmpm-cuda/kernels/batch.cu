// Batches of worlds (crate::batch): one world's particles put back into the state (a reset to
// its initial state, or to a given one), wherever the sort has moved them. `src` holds the
// world's `count` particles, structure of arrays with stride `stride` (`count` for a put's own
// image; the batch's kept image of every world's initial particles has stride n, `src` then
// pointing at particle `first` of its first row), in original order from `first`; a slot whose
// id lies in [first, first + count) takes every word of its particle but the id. Two kernels:
// `batch_put_world` tests every slot, `batch_put_gblocks` the put worlds' gblocks only (below;
// crate::batch::put_slots says when the host may launch it). Launched in the batch's program;
// compiled in every program (there a particle's world is 0).
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

// Whether particle `k` of `src` put into slot `i` leaves the free zone of gblock `bc` (its block
// coordinates): G2P's rule (g2p_finish in g2p/particle.cuh). Reads the slot's material word (its
// world) before the put writes it.
__device__ __forceinline__ bool put_leaves_zone(const Ctx& c, const real* src, unsigned k, unsigned stride,
                                                unsigned i, const int* bc) {
    vec3 x = make_v3(src[(size_t)F_X * stride + k], src[(size_t)(F_X + 1) * stride + k],
                     src[(size_t)(F_X + 2) * stride + k]);
    int nb[3];
    real fx[3];
    stencil_of(c, x, particle_world(c, i), nb, fx);
    bool out = false;
    for (int a = 0; a < 3; ++a) out = out || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
    return out;
}

// Every slot tested by its id (any storage order): the put as first written, one field's load
// then its store at a time. `batch_put_world`'s body; `batch_put_gblocks` where the gblocks'
// slot ranges cannot be used.
__device__ __forceinline__ void put_scan_body(const Ctx& c, const real* src, unsigned first, unsigned count,
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
            rebuild = rebuild || put_leaves_zone(c, src, k, stride, i, c.block_coords + 3 * slot_gblock(c, i, gblocks));
        }
        for (int f = 0; f < RTMPM_NFIELDS; ++f)
            if (f != F_ID) c.state[sidx(c.cap, f, i)] = src[(size_t)f * stride + k];
    }
    if (rebuild) c.ctl[CTL_NEED_REBUILD] = 1;
}

extern "C" __global__ void batch_put_world(Ctx c, const real* src, unsigned first, unsigned count,
                                           unsigned stride) {
    put_scan_body(c, src, first, count, stride);
}

// Every word of particle `k` of `src` but the id into slot `i`: all loads first, then the stores
// (the compiler may not move a load of `src` past a store to the state, which might alias it:
// one after another, each load waited for in turn).
__device__ __forceinline__ void put_slot_words(const Ctx& c, const real* src, unsigned k, unsigned stride,
                                               unsigned i) {
    real w[RTMPM_NFIELDS];
#pragma unroll
    for (int f = 0; f < RTMPM_NFIELDS; ++f)
        if (f != F_ID) w[f] = src[(size_t)f * stride + k];
#pragma unroll
    for (int f = 0; f < RTMPM_NFIELDS; ++f)
        if (f != F_ID) c.state[sidx(c.cap, f, i)] = w[f];
}

// The put of `batch_put_world` (the same words into the same slots, the same rebuild flag), over
// the run's gblocks only: the last rebuild sorted the slots by gblock (gblock g's slots are
// hist[64 g] up to the next gblock's first, the last gblock's up to n), and every slot of a gblock
// holds a particle of the gblock's world (the host launches it only where that holds:
// crate::batch::put, "the gblocks' slot ranges"). So a gblock is the run's when its first slot's
// particle is, and each warp tests PUT_GBLOCKS_PER_WARP gblocks (its first lanes, one each), then
// puts the slots of those that are the run's one after another (few a warp keep the longest warp
// short: a run's gblocks are spread over the ids, given in hash-table order), a lane a slot, the zone checked against that gblock (no search for it) and the
// loads of a slot's words issued together. Where no rebuild has sorted the slots (no gblocks),
// after an error, or where every step rebuilds, every slot is tested as `batch_put_world` does
// (this kernel writes none of the words it decides by, so every block decides alike).
extern "C" __global__ void batch_put_gblocks(Ctx c, const real* src, unsigned first, unsigned count,
                                             unsigned stride) {
    const volatile unsigned* ctl = c.ctl;
    unsigned gblocks = min(c.ctl[CTL_GBLOCKS], c.gblock_cap);
    if (ctl[CTL_ERROR] || gblocks == 0 || c.always_rebuild) {
        put_scan_body(c, src, first, count, stride);
        return;
    }
    // A rebuild already due: nothing to check (the flag only ever goes from 0 to 1 here).
    bool check = ctl[CTL_NEED_REBUILD] == 0;
    unsigned lane = threadIdx.x & 31, step = ((gridDim.x * blockDim.x) >> 5) * PUT_GBLOCKS_PER_WARP;
    bool rebuild = false;
    for (unsigned g0 = (thread_index() >> 5) * PUT_GBLOCKS_PER_WARP; g0 < gblocks; g0 += step) {
        unsigned g = g0 + lane;
        bool ours = false;
        if (lane < PUT_GBLOCKS_PER_WARP && g < gblocks) {
            unsigned s = c.hist[64u * g];
            ours = s < c.n && state_bits(c.state[sidx(c.cap, F_ID, s)]) - first < count;
        }
        for (unsigned m = __ballot_sync(0xffffffffu, ours); m != 0; m &= m - 1) {
            unsigned h = g0 + (unsigned)(__ffs(m) - 1);
            unsigned lo = c.hist[64u * h], hi = h + 1 < gblocks ? min(c.hist[64u * (h + 1)], c.n) : c.n;
            const int* bc = c.block_coords + 3 * h;
            for (unsigned i = lo + lane; i < hi; i += 32) {
                unsigned k = state_bits(c.state[sidx(c.cap, F_ID, i)]) - first;
                if (k >= count) continue;
                if (check) rebuild = rebuild || put_leaves_zone(c, src, k, stride, i, bc);
                put_slot_words(c, src, k, stride, i);
            }
        }
    }
    if (rebuild) c.ctl[CTL_NEED_REBUILD] = 1;
}
