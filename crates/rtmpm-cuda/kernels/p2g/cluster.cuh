// The fused step's P2G scatter summed on chip in a thread-block cluster (Hopper, compute
// capability 9.0: thread-block clusters and distributed shared memory), the CUDA option
// cluster=K (-DRTMPM_P2G_CLUSTER=K, K = 2 or 4 blocks of 128 threads; the backend passes it only
// for sm_90 and later, and refuses the option before Hopper). Off by default: an experiment for
// the speed A/B (bench/RESULTS.md, "Thread-block clusters for the scatter").
//
// Which blocks are neighbours here. The fused kernels give warp w of the warp list to thread
// block w / 4 of the round (a grid-stride loop), and the warp list is written by the rebuild in
// the order of the sorted particles (gblock by gblock, cell by cell within a gblock; the gblock
// ids in the order the hash table met them, not in space). A cluster of K consecutive blocks
// therefore takes 4K consecutive warps of the list in every round: mostly warps of ONE gblock (a
// gblock of 4x4x4 cells at 8 particles a cell holds 16 warps), which scatter into the same 6x6x6
// nodes around it; cluster neighbours are not spatial neighbours that own neighbouring nodes. So
// the cluster here does not exchange halo nodes between blocks: it sums the warps of one gblock
// that fall into the same round, in a tile of that gblock's nodes held in the shared memory of
// one block of the cluster, and that block adds each touched node to the grid with one global
// atomic after the round.
//
// The round of a cluster: every block reads the gblock of the first warp of each block of the
// cluster (the tiles' gblocks); a warp whose gblock is one of them sends its segment heads' node
// values to the tile of the first block with that gblock (red.shared::cluster, four scalar adds a
// node: distributed shared memory has no vector add), nodes outside the tile's window and warps
// of another gblock add to the grid directly; a cluster barrier; each block whose tile was used
// adds its nonzero nodes to the grid and clears them. Two tiles a block alternate between rounds,
// so one barrier a round suffices (a tile is written again only two rounds later, after the next
// barrier, which its owner reaches only after clearing it).
#pragma once
#include "warp.cuh"

#if defined(RTMPM_P2G_CLUSTER) && RTMPM_P2G_CLUSTER > 1
#if !defined(__CUDA_ARCH__) || __CUDA_ARCH__ < 900
#error "RTMPM_P2G_CLUSTER (thread-block clusters) needs compute capability 9.0 or later"
#endif
#if RTMPM_P2G_CLUSTER != 2 && RTMPM_P2G_CLUSTER != 4
#error "RTMPM_P2G_CLUSTER: 2 or 4 blocks"
#endif

// The tile's window: nodes 4 bc + o of the gblock at bc with o in [CLUSTER_TILE_LO,
// CLUSTER_TILE_LO + CLUSTER_TILE_N) along each axis. A freshly sorted particle of the gblock has
// its stencil base in [4 bc - 1, 4 bc + 3], so its 27 nodes lie in [-1, 5]: the window holds every
// node until particles drift (the free zone lets the base reach 4 bc - 4 .. 4 bc + 5; those
// nodes go to the grid directly).
#define CLUSTER_TILE_LO (-1)
#define CLUSTER_TILE_N 7
#define CLUSTER_TILE_NODES (CLUSTER_TILE_N * CLUSTER_TILE_N * CLUSTER_TILE_N)
#define CLUSTER_NO_GBLOCK 0xffffffffu
#define CLUSTER_NO_TILE 0xffffffffu

// A block's two tiles (static shared memory of the fused kernels: 2 x 343 nodes x 4 reals, 10,976
// bytes in f32).
struct ClusterTiles {
    real v[2][CLUSTER_TILE_NODES * 4];
};

// This block's rank in its cluster.
__device__ __forceinline__ unsigned cluster_rank() {
    unsigned r;
    asm volatile("mov.u32 %0, %%cluster_ctarank;" : "=r"(r));
    return r;
}

// Barrier of every thread of the cluster: shared-memory writes before it (local or remote) are
// seen by every thread of the cluster after it. The warp is reconverged first (.aligned: every
// lane executes the same barrier instruction).
__device__ __forceinline__ void cluster_barrier() {
    __syncwarp();
    asm volatile("barrier.cluster.arrive.release.aligned;\n\tbarrier.cluster.wait.acquire.aligned;" ::: "memory");
}

// The shared::cluster address of `p` (this block's shared memory) in the block of rank `rank`.
__device__ __forceinline__ unsigned cluster_address(const void* p, unsigned rank) {
    unsigned local, remote;
    asm("{\n\t.reg .u64 t;\n\tcvta.to.shared.u64 t, %1;\n\tcvt.u32.u64 %0, t;\n\t}" : "=r"(local) : "l"(p));
    asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(remote) : "r"(local), "r"(rank));
    return remote;
}

// Add v to the real at shared::cluster address a (no return value: a reduction).
__device__ __forceinline__ void cluster_red_add(unsigned a, float v) {
    asm volatile("red.shared::cluster.add.f32 [%0], %1;" ::"r"(a), "f"(v) : "memory");
}
__device__ __forceinline__ void cluster_red_add(unsigned a, double v) {
    asm volatile("red.shared::cluster.add.f64 [%0], %1;" ::"r"(a), "d"(v) : "memory");
}

// The gblocks of the round's tiles: that of the first warp of each block of the cluster
// (CLUSTER_NO_GBLOCK past the list's end). w0: the cluster's first warp of the round.
struct ClusterRound {
    unsigned gblock[RTMPM_P2G_CLUSTER];
};
__device__ __forceinline__ ClusterRound cluster_round(const Ctx& c, unsigned w0, unsigned n_warps) {
    ClusterRound r;
#pragma unroll
    for (unsigned b = 0; b < RTMPM_P2G_CLUSTER; ++b) {
        unsigned w = w0 + 4u * b;
        r.gblock[b] = w < n_warps ? c.warps[3 * w] : CLUSTER_NO_GBLOCK;
    }
    return r;
}
// The rank of the block whose tile takes gblock g's nodes this round: the first with that gblock,
// or RTMPM_P2G_CLUSTER (none: the warp adds to the grid directly).
__device__ __forceinline__ unsigned cluster_owner(const ClusterRound& r, unsigned g) {
    unsigned owner = RTMPM_P2G_CLUSTER;
#pragma unroll
    for (int b = RTMPM_P2G_CLUSTER - 1; b >= 0; --b)
        if (r.gblock[b] == g) owner = (unsigned)b;
    return owner;
}

// The segment heads' sink of the cluster variant: nodes in the window of the owner's tile are
// added there (four reductions into distributed shared memory), the others to `grid`.
struct ClusterSink {
    real* grid;
    unsigned tile;  // shared::cluster address of the owner's tile of the round; CLUSTER_NO_TILE: none
    int r[3];       // the stencil base from the window's first node (4 bc + CLUSTER_TILE_LO)
    __device__ __forceinline__ void add(unsigned node, int i, int j, int k, const real val[4]) const {
        unsigned a = (unsigned)(r[0] + i), b = (unsigned)(r[1] + j), e = (unsigned)(r[2] + k);
        if (tile != CLUSTER_NO_TILE && a < CLUSTER_TILE_N && b < CLUSTER_TILE_N && e < CLUSTER_TILE_N) {
            unsigned t = tile + (unsigned)sizeof(real) * 4u * ((a * CLUSTER_TILE_N + b) * CLUSTER_TILE_N + e);
#pragma unroll
            for (int q = 0; q < 4; ++q) cluster_red_add(t + (unsigned)sizeof(real) * q, val[q]);
        } else {
            atomic_add_node(grid + 4u * node, val);
        }
    }
};
// The sink of a lane whose particle (of gblock g, stencil base `base`) scatters this round; `tile`
// as in ClusterSink.
__device__ __forceinline__ ClusterSink cluster_sink(const Ctx& c, unsigned g, const int base[3], unsigned tile, real* grid) {
    ClusterSink s;
    s.grid = grid;
    s.tile = tile;
    const int* bc = c.block_coords + 3 * g;
#pragma unroll
    for (int a = 0; a < 3; ++a) s.r[a] = base[a] - 4 * bc[a] - CLUSTER_TILE_LO;
    return s;
}

// Zero both tiles of this block (every thread of the block calls it).
__device__ __forceinline__ void cluster_tiles_clear(ClusterTiles& t) {
    for (unsigned i = threadIdx.x; i < 2u * CLUSTER_TILE_NODES * 4u; i += blockDim.x) (&t.v[0][0])[i] = (real)0;
}

// After the round's barrier: this block's tile `v` (of gblock g) added to `grid` node by node
// (the nonzero ones) and cleared. Every thread of the block calls it.
__device__ __forceinline__ void cluster_tile_flush(const Ctx& c, unsigned g, real* v, real* grid) {
    const unsigned* nbs = c.neighbors + 27 * g;
    for (unsigned t = threadIdx.x; t < CLUSTER_TILE_NODES; t += blockDim.x) {
        real* e = v + 4u * t;
        real val[4] = {e[0], e[1], e[2], e[3]};
        if (val[0] == (real)0 && val[1] == (real)0 && val[2] == (real)0 && val[3] == (real)0) continue;
        e[0] = e[1] = e[2] = e[3] = (real)0;
        // The node's offset from the gblock's origin (in [-1, 5]: its neighbour slot and cell).
        int o0 = (int)(t / (CLUSTER_TILE_N * CLUSTER_TILE_N)) + CLUSTER_TILE_LO;
        int o1 = (int)(t / CLUSTER_TILE_N % CLUSTER_TILE_N) + CLUSTER_TILE_LO;
        int o2 = (int)(t % CLUSTER_TILE_N) + CLUSTER_TILE_LO;
        unsigned node = nbs[nb_slot(o0 >> 2, o1 >> 2, o2 >> 2)] * 64u + (unsigned)cell_code(o0, o1, o2);
        atomic_add_node(grid + 4u * node, val);
    }
}
#endif
