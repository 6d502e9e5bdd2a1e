// Rebuild of the particle-to-block mapping (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022)): block codes, GPU hash table (block code ->
// dense id), gblocks, pblocks with explicit 3x3x3 neighbour lists, complete block+cell counting
// sort (histogram, scan, ranks, then scatter and copy back a chunk of fields at a time) with
// physical reordering of the particle arrays, warp list.
// Each phase is a device function `rb_X_body`, run either as its own kernel `rb_X` (launched every
// step, returning at once unless ctl[CTL_NEED_REBUILD] is set; a grid of at most one wave,
// grid-stride loops) or, by default, as a phase of the single persistent kernel `rb_fused` at the
// end of this file.
#include "common.cuh"
#include "scan.cuh"
#include "grid_barrier.cuh"

#define GRID_STRIDE(i, n) for (unsigned i = thread_index(); i < (n); i += gridDim.x * blockDim.x)

#define NEED(c) (((volatile unsigned*)(c).ctl)[CTL_NEED_REBUILD] != 0)

// One thread: decide whether this step rebuilds; reset per-step counters.
__device__ __forceinline__ void rb_begin_body(const Ctx& c) {
    c.ctl[CTL_MAX_SPEED] = 0;
    if (c.always_rebuild) c.ctl[CTL_NEED_REBUILD] = 1;
    c.ctl[CTL_REBUILT_NOW] = c.ctl[CTL_NEED_REBUILD] ? 1u : 0u;
    if (!c.ctl[CTL_NEED_REBUILD]) return;
    c.ctl[CTL_REBUILDS] += 1;
    c.ctl[CTL_PREV_GBLOCKS] = c.ctl[CTL_GBLOCKS];
    c.ctl[CTL_GBLOCKS] = 0;
    c.ctl[CTL_PBLOCKS] = 0;
    c.ctl[CTL_EXTRA] = 0;
    c.ctl[CTL_WARPS] = 0;
}
extern "C" __global__ void rb_begin(Ctx c) {
    if (thread_index() == 0) rb_begin_body(c);
}

__device__ __forceinline__ void rb_clear_body(const Ctx& c) {
    GRID_STRIDE(i, c.hash_cap) { c.hash_keys[i] = EMPTY_KEY; c.hash_values[i] = EMPTY_ID; }
    // The histogram (bucket starts, read by the shared-memory P2G between rebuilds) of the last
    // rebuild's buckets; the rest is still zero from the allocation.
    GRID_STRIDE(i, min(c.ctl[CTL_PREV_GBLOCKS], c.gblock_cap) * 64u) c.hist[i] = 0;
}
extern "C" __global__ void rb_clear(Ctx c) {
    if (!NEED(c)) return;
    rb_clear_body(c);
}

// Block of the stencil base of particle i.
__device__ __forceinline__ void particle_block(const Ctx& c, unsigned i, int b[3], int base[3]) {
    vec3 x = load_v3(c.state, c.cap, F_X, i);
    real fx[3];
    stencil_of(c, x, particle_world(c, i), base, fx);
    for (int a = 0; a < 3; ++a) b[a] = base[a] >> 2;
}

__device__ __forceinline__ void rb_insert_gblocks_body(const Ctx& c) {
    GRID_STRIDE(i, c.n) {
        int b[3], base[3];
        particle_block(c, i, b, base);
        hash_insert(c, block_code(b[0], b[1], b[2]));
    }
}
extern "C" __global__ void rb_insert_gblocks(Ctx c) {
    if (!NEED(c)) return;
    rb_insert_gblocks_body(c);
}

// Give every new key a dense id: gblocks (first == 1) from 0, neighbours after the gblocks.
__device__ __forceinline__ void rb_assign_body(const Ctx& c, unsigned first) {
    GRID_STRIDE(h, c.hash_cap) {
        unsigned long long key = c.hash_keys[h];
        if (key == EMPTY_KEY || c.hash_values[h] != EMPTY_ID) continue;
        unsigned id;
        if (first) {
            id = atomicAdd(&c.ctl[CTL_GBLOCKS], 1u);
            if (id >= c.gblock_cap) { atomicOr(&c.ctl[CTL_ERROR], ERR_GBLOCKS); continue; }
        } else {
            id = c.ctl[CTL_GBLOCKS] + atomicAdd(&c.ctl[CTL_EXTRA], 1u);
        }
        if (id >= c.pblock_cap) { atomicOr(&c.ctl[CTL_ERROR], ERR_PBLOCKS); continue; }
        c.hash_values[h] = id;
        c.block_coords[3 * id] = (int)compact3(key >> 2);
        c.block_coords[3 * id + 1] = (int)compact3(key >> 1);
        c.block_coords[3 * id + 2] = (int)compact3(key);
    }
}
extern "C" __global__ void rb_assign(Ctx c, unsigned first) {
    if (!NEED(c)) return;
    rb_assign_body(c, first);
}

__device__ __forceinline__ void rb_insert_neighbors_body(const Ctx& c) {
    unsigned gcount = min(c.ctl[CTL_GBLOCKS], c.gblock_cap);
    GRID_STRIDE(t, gcount * 27u) {
        unsigned g = t / 27, s = t % 27;
        const int* bc = c.block_coords + 3 * g;
        int di = (int)(s / 9) - 1, dj = (int)(s / 3 % 3) - 1, dk = (int)(s % 3) - 1;
        hash_insert(c, block_code(bc[0] + di, bc[1] + dj, bc[2] + dk));
    }
}
extern "C" __global__ void rb_insert_neighbors(Ctx c) {
    if (!NEED(c)) return;
    rb_insert_neighbors_body(c);
}

__device__ __forceinline__ void rb_neighbor_lists_body(const Ctx& c) {
    unsigned gcount = c.ctl[CTL_GBLOCKS];
    if (thread_index() == 0) c.ctl[CTL_PBLOCKS] = min(gcount + c.ctl[CTL_EXTRA], c.pblock_cap);
    gcount = min(gcount, c.gblock_cap);
    GRID_STRIDE(t, gcount * 27u) {
        unsigned g = t / 27, s = t % 27;
        const int* bc = c.block_coords + 3 * g;
        int di = (int)(s / 9) - 1, dj = (int)(s / 3 % 3) - 1, dk = (int)(s % 3) - 1;
        c.neighbors[27 * g + s] = hash_find(c, block_code(bc[0] + di, bc[1] + dj, bc[2] + dk));
    }
}
extern "C" __global__ void rb_neighbor_lists(Ctx c) {
    if (!NEED(c)) return;
    rb_neighbor_lists_body(c);
}

// Counting sort, 1: histogram of (gblock, cell code) buckets; remember each particle's bucket
// (pkey: the sort scratch's first field, unused until the scatter) and its rank.
__device__ __forceinline__ void rb_histogram_body(const Ctx& c) {
    GRID_STRIDE(i, c.n) {
        int b[3], base[3];
        particle_block(c, i, b, base);
        unsigned g = hash_find(c, block_code(b[0], b[1], b[2]));
        unsigned key = g * 64u + (unsigned)cell_code(base[0], base[1], base[2]);
        c.pkey[i] = key;
        c.prank[i] = atomicAdd(&c.hist[key], 1u);
    }
}
extern "C" __global__ void rb_histogram(Ctx c) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_histogram_body(c);
}

// Buckets in use: 64 per gblock.
__device__ __forceinline__ unsigned active_buckets(const Ctx& c) { return min(c.ctl[CTL_GBLOCKS], c.gblock_cap) * 64u; }

// Counting sort, 2: exclusive scan of the bucket counts (3 kernels: blocks of 1024, block sums,
// add; block_exclusive_scan in scan.cuh). Our own scan: the CUB host API is not available under NVRTC.
// Chunks of blockDim.x buckets, strided over the blocks (uniform trip count per block).
__device__ __forceinline__ void rb_scan_blocks_body(const Ctx& c) {
    unsigned nb = active_buckets(c), chunks = (nb + blockDim.x - 1) / blockDim.x;
    for (unsigned chunk = blockIdx.x; chunk < chunks; chunk += gridDim.x) {
        unsigned i = chunk * blockDim.x + threadIdx.x;
        unsigned v = i < nb ? c.hist[i] : 0;
        unsigned total;
        unsigned e = block_exclusive_scan(v, &total);
        if (i < nb) c.hist[i] = e;
        if (threadIdx.x == 0) c.scan_sums[chunk] = total;
    }
}
extern "C" __global__ void rb_scan_blocks(Ctx c) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_scan_blocks_body(c);
}

// One block of 1024 threads scans the block sums in chunks.
__device__ __forceinline__ void rb_scan_sums_body(const Ctx& c) {
    unsigned n_sums = (active_buckets(c) + 1023u) / 1024u;
    unsigned carry = 0;
    for (unsigned start = 0; start < n_sums; start += blockDim.x) {
        unsigned i = start + threadIdx.x;
        unsigned v = i < n_sums ? c.scan_sums[i] : 0;
        unsigned total;
        unsigned e = block_exclusive_scan(v, &total);
        if (i < n_sums) c.scan_sums[i] = e + carry;
        carry += total;
    }
}
extern "C" __global__ void rb_scan_sums(Ctx c) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_scan_sums_body(c);
}

__device__ __forceinline__ void rb_scan_add_body(const Ctx& c) {
    unsigned nb = active_buckets(c), chunks = (nb + blockDim.x - 1) / blockDim.x;
    for (unsigned chunk = blockIdx.x; chunk < chunks; chunk += gridDim.x) {
        unsigned i = chunk * blockDim.x + threadIdx.x;
        if (i < nb) c.hist[i] += c.scan_sums[chunk];
    }
}
extern "C" __global__ void rb_scan_add(Ctx c) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_scan_add_body(c);
}

// Counting sort, 3: the permutation, once: each particle's sorted slot (bucket start + rank),
// written over its rank; and the warp list (each warp: up to 32 consecutive particles of one
// gblock). The bucket keys live in the first scratch field (Ctx::pkey aliases it): they are read
// here for the last time, before the scatter overwrites the scratch.
__device__ __forceinline__ void rb_rank_body(const Ctx& c) {
    GRID_STRIDE(i, c.n) {
        unsigned key = c.pkey[i];
        unsigned dst = c.hist[key] + c.prank[i];
        c.prank[i] = dst;
        unsigned g = key >> 6;
        unsigned start = c.hist[g * 64u];
        unsigned end = (g + 1 < c.ctl[CTL_GBLOCKS]) ? c.hist[(g + 1) * 64u] : c.n;
        if ((dst - start) % 32u == 0) {
            unsigned w = atomicAdd(&c.ctl[CTL_WARPS], 1u);
            if (w >= c.warp_cap) { atomicOr(&c.ctl[CTL_ERROR], ERR_WARPS); continue; }
            c.warps[3 * w] = g;
            c.warps[3 * w + 1] = dst;
            c.warps[3 * w + 2] = min(32u, end - dst);
        }
    }
}
extern "C" __global__ void rb_rank(Ctx c) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_rank_body(c);
}

// Counting sort, 4: the fields of the mask `fields` (bit f: field f; at most the scratch's
// fields) to their sorted slots in the scratch (the j-th field of the mask in scratch field j),
// then copied back (the state pointer never changes, so a step can be captured in a CUDA graph).
// The host runs the pairs over chunks of the fields the sort permutes, in order; the scratch holds
// only one chunk, so memory per particle is NFIELDS + chunk words instead of 2 NFIELDS. Every
// chunk moves the same words to the same slots as one pass over all fields would: the same result.
// A field left out of every chunk holds the same value in every particle (the zero off-diagonal
// words of F when every material is a fluid), so leaving it in place permutes it too.
__device__ __forceinline__ void rb_scatter_body(const Ctx& c, unsigned fields) {
    GRID_STRIDE(i, c.n) {
        unsigned dst = c.prank[i];
        int j = 0;
        for (unsigned m = fields; m; m &= m - 1, ++j)
            c.scratch[sidx(c.cap, j, dst)] = c.state[sidx(c.cap, __ffs(m) - 1, i)];
    }
}
extern "C" __global__ void rb_scatter(Ctx c, unsigned fields) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_scatter_body(c, fields);
}

__device__ __forceinline__ void rb_copy_back_body(const Ctx& c, unsigned fields) {
    int j = 0;
    for (unsigned m = fields; m; m &= m - 1, ++j) {  // field by field: n * NFIELDS may pass 2^32
        int f = __ffs(m) - 1;
        GRID_STRIDE(i, c.n) c.state[sidx(c.cap, f, i)] = c.scratch[sidx(c.cap, j, i)];
    }
}
extern "C" __global__ void rb_copy_back(Ctx c, unsigned fields) {
    if (!NEED(c) || c.ctl[CTL_ERROR]) return;
    rb_copy_back_body(c, fields);
}

// The next chunk of the sort: the lowest `k` fields of `rest`, taken out of it.
__device__ __forceinline__ unsigned rb_next_chunk(unsigned& rest, int k) {
    unsigned chunk = 0;
    for (int j = 0; j < k && rest; ++j) {
        unsigned low = rest & (0u - rest);
        chunk |= low;
        rest &= ~low;
    }
    return chunk;
}

extern "C" __global__ void rb_end(Ctx c) {
    if (thread_index() == 0) c.ctl[CTL_NEED_REBUILD] = 0;
}

// Zero the grid nodes of all pblocks (every step).
__device__ __forceinline__ void grid_clear_body(const Ctx& c) {
    GRID_STRIDE(t, c.ctl[CTL_PBLOCKS] * 64u * 4u) {
        c.grid[t] = 0;
        if (c.grid_aux) c.grid_aux[t] = 0;
    }
}
extern "C" __global__ void grid_clear(Ctx c) {
    if (grid_needs_p2g(c)) grid_clear_body(c);
}
// Clear only grid_aux (before the MUSL re-map).
extern "C" __global__ void grid_clear_aux(Ctx c) {
    GRID_STRIDE(t, c.ctl[CTL_PBLOCKS] * 64u * 4u) c.grid_aux[t] = 0;
}

// ---- The whole rebuild in ONE launch (`rebuild=fused`, the default): Fei et al.'s "merge kernels"
// applied to the rebuild. The kernels above become the phases of one persistent kernel, separated
// by a grid-wide barrier; its grid is exactly the blocks that fit on the device at once (a
// cooperative launch, so every block is resident and the barrier cannot deadlock). A step without
// a rebuild then costs one launch (the decision, the per-step resets and the grid clear) instead of
// fifteen early-exiting ones. Phases never return early: an error only skips the work of the
// remaining phases, every block still meets every barrier.

__device__ __forceinline__ bool rb_error(const Ctx& c) { return ((volatile unsigned*)c.ctl)[CTL_ERROR] != 0; }

// `chunk`: the fields of the scratch (1 to RTMPM_NFIELDS), the fields permuted per pass;
// `fields`: the mask of the fields the sort permutes (see rb_scatter_body).
extern "C" __global__ void __launch_bounds__(1024) rb_fused(Ctx c, int chunk, unsigned fields) {
    // Launched without the attribute (the step's first kernel, cooperative): the wait is a no-op;
    // with pdl=on the trigger lets the next kernel's blocks be scheduled while this one runs (all
    // of this kernel's blocks are resident already: the cooperative launch).
    step_kernel_entry();
    // Every block takes the same decision before anyone writes the flag (it is cleared only at the end).
    bool need = NEED(c) || c.always_rebuild;
    if (!need) {
        if (thread_index() == 0) {
            c.ctl[CTL_MAX_SPEED] = 0;
            c.ctl[CTL_REBUILT_NOW] = 0;
        }
        // G2P2G: the grid already holds the fused kernel's scatter unless the host asked for a P2G.
        if (!c.grid_next || c.ctl[CTL_P2G_PENDING]) grid_clear_body(c);
        return;  // uniform: no block meets a barrier
    }
    if (thread_index() == 0) rb_begin_body(c);
    rb_grid_barrier(c);
    rb_clear_body(c);
    rb_grid_barrier(c);
    rb_insert_gblocks_body(c);
    rb_grid_barrier(c);
    rb_assign_body(c, 1u);
    rb_grid_barrier(c);
    rb_insert_neighbors_body(c);
    rb_grid_barrier(c);
    rb_assign_body(c, 0u);
    rb_grid_barrier(c);
    rb_neighbor_lists_body(c);
    rb_grid_barrier(c);
    // From here the phases skip their work after an error (read after a barrier: the same value
    // in every block), but never a barrier.
    bool err = rb_error(c);
    if (!err) rb_histogram_body(c);
    rb_grid_barrier(c);
    err = rb_error(c);
    if (!err) rb_scan_blocks_body(c);
    rb_grid_barrier(c);
    if (!err && blockIdx.x == 0) rb_scan_sums_body(c);
    rb_grid_barrier(c);
    if (!err) rb_scan_add_body(c);
    rb_grid_barrier(c);
    if (!err) rb_rank_body(c);
    rb_grid_barrier(c);
    err = rb_error(c);
    // The fields, `chunk` at a time (the scratch's fields): scatter, barrier, copy back, barrier.
    // Uniform: every block takes the same chunks and meets the same barriers.
    chunk = max(1, min(chunk, RTMPM_NFIELDS));
    unsigned rest = fields & ((1u << RTMPM_NFIELDS) - 1u);
    while (rest) {
        unsigned m = rb_next_chunk(rest, chunk);
        if (!err) rb_scatter_body(c, m);
        rb_grid_barrier(c);
        if (!err) rb_copy_back_body(c, m);
        rb_grid_barrier(c);
    }
    if (thread_index() == 0) c.ctl[CTL_NEED_REBUILD] = 0;
    grid_clear_body(c);
}
