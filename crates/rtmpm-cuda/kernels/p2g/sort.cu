// P2G as a gather through a sort-based map (Chiang et al., "GPU Acceleration of the Generalized Interpolation Material Point Method" (SAAHPC 2009), section II: "the second GPU implementation
// conserves memory and avoids the potential bottleneck of atomicAdd, but requires one sort per
// time step (of 2*number of particle contributions elements) and uncoalesced memory accesses during
// the grid accumulation"). One step:
// 1. p2g_sort_emit, one thread per particle (fused): the particle quantities and its 27 node values
//    (p2g_particle.cuh, the same functions as the scatter) go to the entry array, and the key of
//    entry slot * cap + p is its node's memory index (the value, the entry number, is implicit).
// 2. An LSD radix sort of the (key, value) pairs, 8 bits per pass, stable, without global atomics:
//    per tile of SORT_TILE pairs a digit histogram (p2g_sort_count, shared-memory counts), an
//    exclusive scan of the digit-major histogram (p2g_sort_scan_*), and a stable scatter
//    (p2g_sort_scatter: ranks from __match_any_sync within a warp and shared per-warp counts). The
//    host enqueues the passes that the node capacity needs; a pass whose digit is above the highest
//    node index in use returns at once, so the sorted pairs are in buffer (passes run) % 2.
// 3. p2g_sort_segments: the first and one-past-last sorted position of every node's run.
// 4. p2g_sort_gather, one thread per grid node of the pblocks in use: sums the entries of its run
//    (uncoalesced reads, as the paper says), stores the node (no atomics) and resets its run.
// The sum order is fixed by the stable sort: unlike the atomics, the result is deterministic.
#include "particle.cuh"
#include "../scan.cuh"

#define SORT_BITS 8
#define SORT_DIGITS 256  // = blockDim.x of the count and scatter kernels
#define SORT_ITEMS 8     // pairs per thread and tile
#define SORT_TILE (SORT_DIGITS * SORT_ITEMS)

// Passed by value with the Ctx (src/p2g_sort.rs mirrors it).
struct SortCtx {
    real* contrib;          // 27 x cap entries of 4 reals (p2g_particle.cuh)
    unsigned* keys[2];      // ping-pong, n_items each
    unsigned* vals[2];      // vals[0] unused at pass 0 (the value is the position)
    unsigned* tile_counts;  // SORT_DIGITS x n_tiles, digit-major; scanned in place
    unsigned* scan_sums;    // block sums of that scan
    unsigned* seg_start;    // node_cap
    unsigned* seg_end;      // node_cap
    unsigned n_items;       // 27 n
    unsigned n_tiles;
    unsigned node_cap;  // pblock capacity x 64
    unsigned pad;
};

// Radix passes that the node indices in use need (at least one).
__device__ __forceinline__ unsigned sort_passes_used(const Ctx& c) {
    unsigned top = max(c.ctl[CTL_PBLOCKS] * 64u, 2u) - 1u;  // highest node index in use
    unsigned bits = 32u - __clz(top);
    return max(1u, (bits + SORT_BITS - 1) / SORT_BITS);
}

extern "C" __global__ void __launch_bounds__(128) p2g_sort_emit(Ctx c, SortCtx s) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5, lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        P2gParticle q = p2g_particle(c, p);
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, q.base);
        const unsigned* nbs = c.neighbors + 27 * g;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    unsigned e = p2g_entry(c, p, i, j, k);
                    real val[4];
                    p2g_node_value(q, i, j, k, val);
                    p2g_store_entry(s.contrib, e, val);
                    s.keys[0][e] = stencil_node(si, nbs, i, j, k);
                }
    }
}

// Pass `pass`: digit histogram of every tile, written digit-major (tile_counts[d * n_tiles + t]).
extern "C" __global__ void __launch_bounds__(SORT_DIGITS) p2g_sort_count(Ctx c, SortCtx s, unsigned pass) {
    __shared__ unsigned cnt[SORT_DIGITS];
    if (c.ctl[CTL_ERROR] || pass >= sort_passes_used(c)) return;
    const unsigned* keys = (pass & 1) ? s.keys[1] : s.keys[0];
    unsigned shift = pass * SORT_BITS;
    for (unsigned tile = blockIdx.x; tile < s.n_tiles; tile += gridDim.x) {
        cnt[threadIdx.x] = 0;
        __syncthreads();
        for (unsigned r = 0; r < SORT_ITEMS; ++r) {
            unsigned idx = tile * SORT_TILE + r * SORT_DIGITS + threadIdx.x;
            if (idx < s.n_items) atomicAdd(&cnt[(keys[idx] >> shift) & (SORT_DIGITS - 1)], 1u);
        }
        __syncthreads();
        s.tile_counts[threadIdx.x * s.n_tiles + tile] = cnt[threadIdx.x];
        __syncthreads();
    }
}

// Exclusive scan of the SORT_DIGITS x n_tiles histogram: blocks of 1024, block sums, add.
extern "C" __global__ void p2g_sort_scan_blocks(Ctx c, SortCtx s, unsigned pass) {
    if (c.ctl[CTL_ERROR] || pass >= sort_passes_used(c)) return;
    unsigned n = SORT_DIGITS * s.n_tiles, chunks = (n + blockDim.x - 1) / blockDim.x;
    for (unsigned chunk = blockIdx.x; chunk < chunks; chunk += gridDim.x) {
        unsigned i = chunk * blockDim.x + threadIdx.x;
        unsigned v = i < n ? s.tile_counts[i] : 0;
        unsigned total;
        unsigned e = block_exclusive_scan(v, &total);
        if (i < n) s.tile_counts[i] = e;
        if (threadIdx.x == 0) s.scan_sums[chunk] = total;
    }
}

extern "C" __global__ void p2g_sort_scan_sums(Ctx c, SortCtx s, unsigned pass) {
    if (c.ctl[CTL_ERROR] || pass >= sort_passes_used(c)) return;
    unsigned n_sums = (SORT_DIGITS * s.n_tiles + blockDim.x - 1) / blockDim.x;
    unsigned carry = 0;
    for (unsigned start = 0; start < n_sums; start += blockDim.x) {
        unsigned i = start + threadIdx.x;
        unsigned v = i < n_sums ? s.scan_sums[i] : 0;
        unsigned total;
        unsigned e = block_exclusive_scan(v, &total);
        if (i < n_sums) s.scan_sums[i] = e + carry;
        carry += total;
    }
}

extern "C" __global__ void p2g_sort_scan_add(Ctx c, SortCtx s, unsigned pass) {
    if (c.ctl[CTL_ERROR] || pass >= sort_passes_used(c)) return;
    unsigned n = SORT_DIGITS * s.n_tiles, chunks = (n + blockDim.x - 1) / blockDim.x;
    for (unsigned chunk = blockIdx.x; chunk < chunks; chunk += gridDim.x) {
        unsigned i = chunk * blockDim.x + threadIdx.x;
        if (i < n) s.tile_counts[i] += s.scan_sums[chunk];
    }
}

// Stable scatter of pass `pass`: the pairs of a tile are taken in index order, round by round
// (SORT_DIGITS consecutive pairs per round); a pair's destination is the scanned offset of its
// (digit, tile) + pairs of that digit in earlier rounds + in earlier warps of this round + its rank
// among the lanes of its warp with the same digit.
extern "C" __global__ void __launch_bounds__(SORT_DIGITS) p2g_sort_scatter(Ctx c, SortCtx s, unsigned pass) {
    __shared__ unsigned offset[SORT_DIGITS];
    __shared__ unsigned warp_count[SORT_DIGITS / 32][SORT_DIGITS];
    if (c.ctl[CTL_ERROR] || pass >= sort_passes_used(c)) return;
    bool odd = pass & 1;  // (selects, not indexing: a dynamic index would copy the struct to local memory)
    const unsigned* keys_in = odd ? s.keys[1] : s.keys[0];
    const unsigned* vals_in = odd ? s.vals[1] : s.vals[0];
    unsigned* keys_out = odd ? s.keys[0] : s.keys[1];
    unsigned* vals_out = odd ? s.vals[0] : s.vals[1];
    unsigned shift = pass * SORT_BITS, t = threadIdx.x, lane = t & 31, warp = t >> 5;
    for (unsigned tile = blockIdx.x; tile < s.n_tiles; tile += gridDim.x) {
        offset[t] = s.tile_counts[t * s.n_tiles + tile];  // thread t owns digit t
        for (unsigned r = 0; r < SORT_ITEMS; ++r) {
            for (unsigned w = 0; w < SORT_DIGITS / 32; ++w) warp_count[w][t] = 0;
            __syncthreads();
            unsigned idx = tile * SORT_TILE + r * SORT_DIGITS + t;
            bool valid = idx < s.n_items;
            unsigned key = valid ? keys_in[idx] : 0u;
            unsigned digit = (key >> shift) & (SORT_DIGITS - 1);
            // Invalid lanes get tags of their own, so they match nobody.
            unsigned peers = __match_any_sync(0xffffffffu, valid ? digit : SORT_DIGITS + lane);
            unsigned rank = __popc(peers & ((1u << lane) - 1u));
            if (valid && rank == 0) warp_count[warp][digit] = __popc(peers);
            __syncthreads();
            if (valid) {
                unsigned pos = offset[digit] + rank;
                for (unsigned w = 0; w < warp; ++w) pos += warp_count[w][digit];
                keys_out[pos] = key;
                vals_out[pos] = pass == 0 ? idx : vals_in[idx];
            }
            __syncthreads();
            unsigned round_total = 0;
            for (unsigned w = 0; w < SORT_DIGITS / 32; ++w) round_total += warp_count[w][t];
            offset[t] += round_total;  // only thread t touches offset[t] and clears column t next
        }
        __syncthreads();
    }
}

// First and one-past-last sorted position of every node's run of contributions.
extern "C" __global__ void p2g_sort_segments(Ctx c, SortCtx s) {
    if (c.ctl[CTL_ERROR]) return;
    const unsigned* keys = (sort_passes_used(c) & 1) ? s.keys[1] : s.keys[0];
    for (unsigned i = thread_index(); i < s.n_items; i += gridDim.x * blockDim.x) {
        unsigned k = keys[i];
        if (k >= s.node_cap) { atomicOr(&c.ctl[CTL_ERROR], ERR_P2G_MAP); continue; }
        if (i == 0 || keys[i - 1] != k) s.seg_start[k] = i;
        if (i + 1 == s.n_items || keys[i + 1] != k) s.seg_end[k] = i + 1;
    }
}

extern "C" __global__ void __launch_bounds__(256) p2g_sort_gather(Ctx c, SortCtx s) {
    if (c.ctl[CTL_ERROR]) return;
    const unsigned* vals = (sort_passes_used(c) & 1) ? s.vals[1] : s.vals[0];
    unsigned n_nodes = min(c.ctl[CTL_PBLOCKS] * 64u, s.node_cap);
    for (unsigned node = thread_index(); node < n_nodes; node += gridDim.x * blockDim.x) {
        unsigned start = s.seg_start[node], end = s.seg_end[node];
        s.seg_start[node] = 0;
        s.seg_end[node] = 0;
        real acc[4] = {0, 0, 0, 0};
        for (unsigned i = start; i < end; ++i) p2g_add_entry(s.contrib, vals[i], acc);
        p2g_store_node(c, node, acc);
    }
}
