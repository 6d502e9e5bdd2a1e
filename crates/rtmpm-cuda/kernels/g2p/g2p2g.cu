// G2P2G: the "merge kernels" of Fei, Huang & Gao ("Real-Time Simulation of MPM on Modern GPUs",
// GTC 2022) taken across the step boundary (the G2P2G of Wang et al.
// 2020). One pass over the particles does the G2P of step n from `grid` and, while the new state
// is still in registers, the P2G of step n+1 into `grid_next` (cleared by this step's grid
// update): the next step reads no particle for its P2G and launches no P2G kernel.
//
// G2P2G's caveat (no particle may change between G2P and P2G, Fei, Huang & Gao) meets the free
// zone here: a particle that leaves its free zone may no longer be covered by its gblock's 3x3x3
// neighbourhood, so it is not scattered; it has set the rebuild flag, and the next step rebuilds
// the mapping and redoes its P2G from the stored state (the P2G kernel runs only then, see
// grid_needs_p2g). The scatter uses this step's dt; the host asks for a P2G when dt changes.
#include "particle.cuh"
#include "../p2g/warp.cuh"
#include "../p2g/cluster.cuh"

// Register budgets, measured on an H200 (bench/RESULTS.md, "Occupancy"): in f32 both fused
// kernels held to 5 resident blocks of 128 threads a SM (96 registers, 24-48 bytes of spills with
// ptxas 13.0) and launched as the blocks resident at once (crates/rtmpm-cuda/src/kernels.rs) ran
// the claymore scenes 5-8 % faster than ptxas's own choice for the general kernel (128
// registers; a hint of 1 to 4 cost jelly 8 %) with 4 blocks for the fluid one. In f64 the same
// bounds made the step 18-33 % slower (its doubles spill), so f64 keeps the earlier ones.
// -DG2P2G_MIN_BLOCKS=0 leaves the general kernel to ptxas, -DG2P2G_FLUID_MIN_BLOCKS=N sets the
// fluid kernel's bound.
#ifdef RTMPM_F64
#define G2P2G_DEFAULT_MIN_BLOCKS 0
#define G2P2G_DEFAULT_FLUID_MIN_BLOCKS 4
#else
#define G2P2G_DEFAULT_MIN_BLOCKS 5
#define G2P2G_DEFAULT_FLUID_MIN_BLOCKS 5
#endif
#ifndef G2P2G_FLUID_MIN_BLOCKS
#define G2P2G_FLUID_MIN_BLOCKS G2P2G_DEFAULT_FLUID_MIN_BLOCKS
#endif
#ifndef G2P2G_MIN_BLOCKS
#define G2P2G_MIN_BLOCKS G2P2G_DEFAULT_MIN_BLOCKS
#endif
#if G2P2G_MIN_BLOCKS > 0
#define G2P2G_BOUNDS 128, G2P2G_MIN_BLOCKS
#else
#define G2P2G_BOUNDS 128
#endif

// One entry w of the warp list, by every lane of a warp: the G2P of step n of its particles
// (lane < count) and the P2G of step n+1 of those that stay in their free zone. `halo`: gblock
// g's node window (RTMPM_G2P_HALO) or null.
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_warp(const Ctx& c, unsigned w, unsigned lane, unsigned* speed, const real* halo) {
    unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
#if RTMPM_WARP_LIST_SORTED
    if (count == 0) return;  // a slot the sorted list left over (rebuild.cu: rb_rank)
#endif
    // G2P of step n; the particle's P2G quantities of step n+1 from the new state.
    bool scatter = false;
    unsigned key = P2G_KEY_NONE;
    P2gParticle q = p2g_particle_zero();
    if (lane < count) {
        unsigned p = first + lane;
        real m = state_ld(c.state, sidx(c.cap, F_MASS, p)), vol0 = state_ld(c.state, sidx(c.cap, F_VOL0, p));
        G2pResult r = g2p_particle<ALL_FLUID>(c, g, p, halo);
        *speed = max(*speed, r.speed);
        if (!r.leave) {
            q = p2g_particle_of<ALL_FLUID>(c, r.x, m, vol0, r.v, r.C, r.F, r.plastic, r.material);
            key = p2g_sort_key(c, g, q.base);
            scatter = true;
        }
    }
    // P2G of step n+1, as in p2g.cu: in-warp sort (the particles change lanes by shuffles,
    // only when the warp is out of order), segmented reduction, atomics into grid_next.
    if (c.warp_sort) {
        unsigned src = p2g_warp_sort(key, lane, &scatter);
        if (__any_sync(0xffffffffu, src != lane)) q = p2g_particle_from_lane(q, src);
    }
    p2g_scatter_warp(c, g, q, scatter, lane, c.grid_next);
}

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks).
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_body(const Ctx& c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) g2p2g_warp<ALL_FLUID>(c, w, lane, &speed, nullptr);
    report_max_speed(c, speed);
}

#if RTMPM_G2P_HALO
// The same with the G2P gather from a shared-memory node halo (halo.cuh says how): each block
// takes a contiguous run of the warp list, four warps (a sub-round) at a time; the sub-round's
// window is that of its second warp's gblock (`halo_gblock`), copied once for the sub-rounds of
// that gblock in a row. The loop runs sub-round by sub-round for the whole block (every thread
// reaches the barriers, also past the run's end); the barriers are block-uniform decisions.
__device__ __forceinline__ unsigned halo_gblock(const Ctx& c, unsigned w0, unsigned hi) {
    return w0 < hi ? c.warps[3 * min(w0 + 1u, hi - 1u)] : HALO_NONE;
}
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_halo_body(const Ctx& c, HaloTiles& tiles) {
    if (c.ctl[CTL_ERROR]) return;  // the same value in every thread: no thread leaves a barrier alone
    unsigned n_warps = c.ctl[CTL_WARPS], lane = threadIdx.x & 31, warps_a_block = blockDim.x >> 5;
    // This block's run of the list: [lo, hi), the runs of the blocks differing by at most one warp.
    unsigned lo = (unsigned)((unsigned long long)n_warps * blockIdx.x / gridDim.x);
    unsigned hi = (unsigned)((unsigned long long)n_warps * (blockIdx.x + 1) / gridDim.x);
    unsigned speed = 0;
    // The window in buffer `buf` holds gblock `held`.
    unsigned buf = 0, held = halo_gblock(c, lo, hi);
    if (held != HALO_NONE) halo_issue(c, held, tiles.v[0]);
    halo_wait();
    __syncthreads();
    for (unsigned w0 = lo; w0 < hi; w0 += warps_a_block) {
        unsigned hg = halo_gblock(c, w0, hi);
#if RTMPM_G2P_HALO == 2
        // A new gblock: its window was issued into the other buffer at the start of the previous
        // sub-round (below); wait for it. After the barrier no thread reads the old buffer.
        if (hg != held) {
            buf ^= 1u;
            held = hg;
            halo_wait();
            __syncthreads();
        }
        // The next sub-round's window into the other buffer, when its gblock is another one.
        unsigned next = halo_gblock(c, w0 + warps_a_block, hi);
        if (next != HALO_NONE && next != held) halo_issue(c, next, tiles.v[buf ^ 1u]);
#else
        if (hg != held) {
            __syncthreads();  // every thread is done with the old window
            halo_issue(c, hg, tiles.v[0]);
            held = hg;
            halo_wait();
            __syncthreads();
        }
#endif
        unsigned w = w0 + (threadIdx.x >> 5);
        if (w < hi) g2p2g_warp<ALL_FLUID>(c, w, lane, &speed, c.warps[3 * w] == held ? tiles.v[buf] : nullptr);
    }
    halo_wait();  // no copy outlives the kernel (the last sub-round issues none; kept for safety)
    report_max_speed(c, speed);
}
#endif

#if defined(RTMPM_P2G_CLUSTER) && RTMPM_P2G_CLUSTER > 1
// The same in thread-block clusters of RTMPM_P2G_CLUSTER blocks (the CUDA option cluster=K,
// sm_90 and later; p2g/cluster.cuh): every warp takes the same entries of the warp list as above
// (warp w of the list: block w / 4 of the round), the loop runs round by round for the whole
// cluster (its barrier is reached by every thread of the cluster, also past the list's end), and
// the scatter of the warps of the round's gblocks is summed in the tiles of `tiles` first.
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_cluster_body(const Ctx& c, ClusterTiles& tiles) {
    if (c.ctl[CTL_ERROR]) return;  // the same value in every block: no block leaves a barrier alone
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31, rank = cluster_rank(), warps_a_block = blockDim.x >> 5;
    unsigned speed = 0;
    cluster_tiles_clear(tiles);
    // Every block of the cluster has started and cleared its tiles before any remote add.
    cluster_barrier();
    unsigned buf = 0;
    for (unsigned w0 = (blockIdx.x - rank) * warps_a_block; w0 < n_warps; w0 += stride, buf ^= 1u) {
        ClusterRound round = cluster_round(c, w0, n_warps);
        unsigned w = w0 + rank * warps_a_block + (threadIdx.x >> 5);
        if (w < n_warps) {
            // g2p2g_body's loop body up to the scatter (written out again, so that the default
            // kernels stay as they were, PTX byte for byte).
            unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
            bool scatter = false;
            unsigned key = P2G_KEY_NONE;
            P2gParticle q = p2g_particle_zero();
            if (lane < count) {
                unsigned p = first + lane;
                real m = state_ld(c.state, sidx(c.cap, F_MASS, p)), vol0 = state_ld(c.state, sidx(c.cap, F_VOL0, p));
                G2pResult r = g2p_particle<ALL_FLUID>(c, g, p);
                speed = max(speed, r.speed);
                if (!r.leave) {
                    q = p2g_particle_of<ALL_FLUID>(c, r.x, m, vol0, r.v, r.C, r.F, r.plastic, r.material);
                    key = p2g_sort_key(c, g, q.base);
                    scatter = true;
                }
            }
            if (c.warp_sort) {
                unsigned src = p2g_warp_sort(key, lane, &scatter);
                if (__any_sync(0xffffffffu, src != lane)) q = p2g_particle_from_lane(q, src);
            }
            unsigned owner = cluster_owner(round, g);
            unsigned tile = owner < RTMPM_P2G_CLUSTER ? cluster_address(tiles.v[buf], owner) : CLUSTER_NO_TILE;
            p2g_scatter_warp_into(c, g, q, scatter, lane, cluster_sink(c, g, q.base, tile, c.grid_next));
        }
        cluster_barrier();
        // This block's tile, when it was the round's tile of its gblock: to the grid, cleared.
        unsigned mine = round.gblock[rank];
        if (mine != CLUSTER_NO_GBLOCK && cluster_owner(round, mine) == rank) cluster_tile_flush(c, mine, tiles.v[buf], c.grid_next);
    }
    report_max_speed(c, speed);
}
#define G2P2G_CLUSTER_DIMS __cluster_dims__(RTMPM_P2G_CLUSTER, 1, 1)
#else
#define G2P2G_CLUSTER_DIMS
#endif

// Every scene.
extern "C" __global__ void __launch_bounds__(G2P2G_BOUNDS) G2P2G_CLUSTER_DIMS g2p2g(Ctx c) {
#if defined(RTMPM_P2G_CLUSTER) && RTMPM_P2G_CLUSTER > 1
    __shared__ ClusterTiles tiles;
    g2p2g_cluster_body<false>(c, tiles);
#elif RTMPM_G2P_HALO
    __shared__ HaloTiles tiles;
    g2p2g_halo_body<false>(c, tiles);
#else
    g2p2g_body<false>(c);
#endif
}
// Scenes whose materials are all fluids (see ALL_FLUID in g2p_particle.cuh).
extern "C" __global__ void __launch_bounds__(128, G2P2G_FLUID_MIN_BLOCKS) G2P2G_CLUSTER_DIMS g2p2g_fluid(Ctx c) {
#if defined(RTMPM_P2G_CLUSTER) && RTMPM_P2G_CLUSTER > 1
    __shared__ ClusterTiles tiles;
    g2p2g_cluster_body<true>(c, tiles);
#elif RTMPM_G2P_HALO
    __shared__ HaloTiles tiles;
    g2p2g_halo_body<true>(c, tiles);
#else
    g2p2g_body<true>(c);
#endif
}
