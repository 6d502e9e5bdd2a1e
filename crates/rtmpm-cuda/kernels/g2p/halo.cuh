// The G2P gather of the fused kernels from a node halo in shared memory (the CUDA option
// halo=sync|async, -DRTMPM_G2P_HALO=1|2; left out, 0: the gather reads the grid in global memory
// node by node, as it always did). An experiment for the speed A/B (bench/RESULTS.md, "Shared node
// halo for the G2P gather"), off by default.
//
// Without it every lane gathers its particle's 27 nodes from the grid with 16-byte loads through
// the L1 (`g2p_node_velocity`), after reading the ids of the stencil's eight pblocks from the
// gblock's neighbour list (`stencil_blocks`): 8 + 27 dependent global loads a lane, of which the
// profile finds the L1 hit rate about 40 % (bench/RESULTS.md, "Occupancy"): the gather waits on
// L2 (long scoreboard). With it a thread block copies the nodes around one gblock once into
// shared memory, a window of HALO_N^3 nodes (HALO_N = 8: the nodes 4 bc - 1 .. 4 bc + 6 along each
// axis, 8 KB of f32 nodes), with cp.async (Ampere's asynchronous copy, compute capability 8.0, the
// program's minimum: the copy goes from L2 to shared memory without registers and without
// stalling the issuing warp), and every particle of that gblock whose 3x3x3 stencil lies in the window
// gathers from there (27 shared loads, no neighbour-list loads). A particle outside the window
// (drifted more than HALO_LO cells since the rebuild) or of another gblock gathers from the grid
// as before: the same sums in the same order, so the results are bit for bit those of the default
// kernels.
//
// Which blocks share a halo: the halo kernels give each thread block a contiguous run of the warp
// list (not the default's grid-stride loop, which gives a block warps of a new gblock every
// round), and the rebuild writes the list gblock by gblock (RTMPM_WARP_LIST_SORTED, rebuild.cu:
// rb_rank; by default the list's order is that of an atomic counter, which interleaves the
// gblocks). At about 16 warps a gblock (8 particles a cell) a block meets each gblock in about four
// sub-rounds in a row (a sub-round: its four warps take the next four warps of its run) and
// copies each gblock's window once. The window of a sub-round is that of its second warp's gblock
// (the gblock of most of its warps when two meet in it).
//
// halo=sync (1): one buffer; when the sub-round's gblock changes, a barrier, the copy, its wait,
// a barrier. halo=async (2): two buffers; at the start of each sub-round the window of the next
// sub-round's gblock is issued into the other buffer when it differs, so the copy runs under this
// sub-round's work (double buffering); at a change of gblock a wait and one barrier. Both have
// no barrier in the sub-rounds that keep their gblock.
#pragma once
#include "../common.cuh"

#ifndef RTMPM_G2P_HALO
#define RTMPM_G2P_HALO 0
#endif

#if RTMPM_G2P_HALO
#if RTMPM_G2P_HALO != 1 && RTMPM_G2P_HALO != 2
#error "RTMPM_G2P_HALO: 1 (sync) or 2 (async)"
#endif
#if defined(RTMPM_P2G_CLUSTER) && RTMPM_P2G_CLUSTER > 1
#error "RTMPM_G2P_HALO and RTMPM_P2G_CLUSTER are exclusive"
#endif
#if !defined(RTMPM_WARP_LIST_SORTED) || !RTMPM_WARP_LIST_SORTED
#error "RTMPM_G2P_HALO needs the sorted warp list: -DRTMPM_WARP_LIST_SORTED=1 (the host passes both)"
#endif
// The window's edge in nodes (6, 8 or 10). A freshly sorted particle of gblock bc has its stencil
// base in 4 bc .. 4 bc + 3 (the gblock is that of its base), so its nodes lie in 4 bc .. 4 bc + 5
// (6 a side); each 2 more nodes let the base drift one cell further either way before the
// particle falls back to the grid (the free zone lets it drift 4 cells).
#ifndef RTMPM_G2P_HALO_N
#define RTMPM_G2P_HALO_N 8
#endif
#if RTMPM_G2P_HALO_N != 6 && RTMPM_G2P_HALO_N != 8 && RTMPM_G2P_HALO_N != 10
#error "RTMPM_G2P_HALO_N: 6, 8 or 10 nodes"
#endif
// How a particle outside the window gathers (compile-time): 0 a branch, the window's gather or
// the grid's (g2p_gather), each its own code; 1 one code path whose loads take each lane's node
// from the window or the grid (generic loads; HaloOrGridNodes in particle.cuh); 2 (default) 1 in
// the general kernel, 0 in the fluid one: what spills least at 96 registers (ptxas 13.0, sm_90,
// f32: the general kernel 120 / 128 bytes of spill stores / loads with 0 and 52 / 76 with 1, the
// fluid kernel in the fluid layout 0 / 0 with 0 and 68 / 76 with 1).
#ifndef RTMPM_G2P_HALO_MIXED
#define RTMPM_G2P_HALO_MIXED 2
#endif
#define HALO_N RTMPM_G2P_HALO_N
#define HALO_LO (-(RTMPM_G2P_HALO_N - 6) / 2)
#define HALO_NODES (HALO_N * HALO_N * HALO_N)
#define HALO_BUFFERS RTMPM_G2P_HALO
#define HALO_NONE 0xffffffffu

// A block's halo buffers (static shared memory: f32 8 KB a buffer at HALO_N = 8, 16 KB for
// halo=async; f64 twice that). A node's four reals as in the grid (mass, velocity).
struct HaloTiles {
    __align__(16) real v[HALO_BUFFERS][HALO_NODES * 4];
};
static_assert(sizeof(HaloTiles) <= 48 * 1024, "HaloTiles: more than the 48 KB of static shared memory");

// The shared-state-space address of `p` (shared memory of this block).
__device__ __forceinline__ unsigned halo_shared_address(const void* p) {
    unsigned a;
    asm("{\n\t.reg .u64 t;\n\tcvta.to.shared.u64 t, %1;\n\tcvt.u32.u64 %0, t;\n\t}" : "=r"(a) : "l"(p));
    return a;
}

// Copy one node (4 reals) from the grid to the halo: cp.async of 16 bytes (one in f32, two in
// f64), from L2 (.cg: the window is read from shared memory, the L1 need not keep it); before
// compute capability 8.0 (which the program does not support anyway: __reduce_max_sync) a load
// and a store.
__device__ __forceinline__ void halo_copy_node(real* dst, const real* src) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
    unsigned d = halo_shared_address(dst);
#pragma unroll
    for (unsigned q = 0; q < 4u * sizeof(real) / 16u; ++q)
        asm volatile("cp.async.cg.shared.global [%0], [%1], 16;" ::"r"(d + 16u * q), "l"(src + q * (16u / sizeof(real))));
#else
#pragma unroll
    for (int q = 0; q < 4; ++q) dst[q] = src[q];
#endif
}

// Wait for this thread's copies (cp.async.wait_all); a barrier after it makes every thread's
// copies visible to the block.
__device__ __forceinline__ void halo_wait() {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
    asm volatile("cp.async.wait_all;" ::: "memory");
#endif
}

// Issue the copy of gblock g's window into `tile`; every thread of the block calls it (each warp
// reads the neighbour list once, lanes 0-26 a slot each, and hands the ids on by shuffles), with
// its warps converged. A neighbour slot without a pblock (only when the rebuild failed, and the
// kernel then does not run) leaves zero nodes.
__device__ __forceinline__ void halo_issue(const Ctx& c, unsigned g, real* tile) {
    unsigned lane = threadIdx.x & 31;
    unsigned id = lane < 27 ? c.neighbors[27 * g + lane] : EMPTY_ID;
    for (unsigned n0 = threadIdx.x & ~31u; n0 < HALO_NODES; n0 += blockDim.x) {
        unsigned n = n0 + lane, m = min(n, (unsigned)HALO_NODES - 1u);
        int o0 = (int)(m / (HALO_N * HALO_N)) + HALO_LO, o1 = (int)(m / HALO_N % HALO_N) + HALO_LO;
        int o2 = (int)(m % HALO_N) + HALO_LO;
        unsigned pb = __shfl_sync(0xffffffffu, id, (unsigned)nb_slot(o0 >> 2, o1 >> 2, o2 >> 2));
        if (n < HALO_NODES) {
            real* dst = tile + 4u * n;
            if (pb == EMPTY_ID) {
                dst[0] = dst[1] = dst[2] = dst[3] = (real)0;
            } else {
                halo_copy_node(dst, c.grid + 4u * (pb * 64u + (unsigned)cell_code(o0, o1, o2)));
            }
        }
    }
}

// The window index of the first node of a particle's stencil (base: its stencil base; bc: its
// gblock's coordinates), when all 27 of its nodes lie in the window.
__device__ __forceinline__ bool halo_window(const int* bc, const int base[3], unsigned* first) {
    unsigned r[3];
    bool in = true;
#pragma unroll
    for (int a = 0; a < 3; ++a) {
        r[a] = (unsigned)(base[a] - 4 * bc[a] - HALO_LO);
        in = in && r[a] <= (unsigned)(HALO_N - 3);
    }
    *first = (r[0] * HALO_N + r[1]) * HALO_N + r[2];
    return in;
}

// The nodes of a stencil in the window, for g2p_gather_sums (particle.cuh): row (i, j) starts at
// the window index first + (i HALO_N + j) HALO_N, node k of a row k further.
struct HaloNodes {
    const real* tile;
    unsigned first;
    typedef unsigned Row;
    __device__ __forceinline__ Row row(int i, int j) const { return first + (unsigned)(i * HALO_N + j) * HALO_N; }
    __device__ __forceinline__ vec3 velocity(Row r, int k) const {
        const real* n = tile + 4u * (r + (unsigned)k);
#ifdef RTMPM_F64
        return make_v3(n[1], n[2], n[3]);
#else
        float4 nd = *reinterpret_cast<const float4*>(n);
        return make_v3(nd.y, nd.z, nd.w);
#endif
    }
};
#endif
