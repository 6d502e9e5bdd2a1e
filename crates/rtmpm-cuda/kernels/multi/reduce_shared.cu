// Multi-GPU: reduce-sum of the grid blocks that several GPUs share (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), "job splitting by
// particles": particles are split between GPUs, each GPU builds its own blocks, the blocks present
// on several GPUs are summed after P2G, then every GPU runs the grid update and G2P alone).
//
// Every step, on every GPU (src/reduce_shared.rs enqueues, no host synchronisation):
//   1. sb_clear_mask, sb_mark: after a rebuild of this GPU's mapping, its occupancy mask over the
//      dense array of the domain's blocks (1 where it has a pblock); mask[d] = rebuilt this step.
//   2. NCCL all-reduce (sum, u8) of the masks -> counts: how many GPUs hold each block;
//      counts[d] = how many GPUs rebuilt this step.
//   3. When some GPU rebuilt (counts[d] > 0; else the kernels return at once): sb_chunk_count,
//      sb_chunk_scan, sb_list list the shared blocks (count >= 2) in the order of the dense index,
//      the same list on every GPU, with this GPU's pblock id of each (EMPTY_ID if it has none);
//      sb_boundary marks the gblocks with a shared neighbour (P2G runs them first).
//   4. After P2G of the boundary gblocks: sb_pack copies the shared blocks' nodes into a buffer,
//      NCCL all-reduce (sum) of the buffer, sb_unpack copies the sums back; P2G of the other
//      gblocks runs meanwhile on the compute stream.
// transport=p2p (GPUs of one process with peer access; no NCCL): step 2 is sb_counts_peers, which
// sums the GPUs' masks read through peer pointers after an inter-GPU barrier (barrier.cu); in
// step 4 the NCCL all-reduce and sb_unpack are replaced by a barrier and sb_sum_peers, which sums
// every GPU's packed buffer, read through peer pointers, into this GPU's grid.
// The scan helper block_exclusive_scan is rebuild.cu's (same NVRTC program, compiled before).
#include "../common.cuh"
#include "../scan.cuh"

struct SharedCtx {
    unsigned char* mask;     // d + 1: this GPU's pblocks; [d] = 1 if it rebuilt this step
    unsigned char* counts;   // d + 1: the sum of the masks over the GPUs
    unsigned* chunk;         // per chunk of 1024 dense blocks: shared count, then its offset
    unsigned* shared_local;  // cap: this GPU's pblock id of each shared block, or EMPTY_ID
    real* buf;               // cap * 256 reals: the nodes of the shared blocks
    int dims[3];             // dense block array: pblock coordinates -1 .. dims - 2 per axis
    unsigned d;              // dims[0] * dims[1] * dims[2]
    unsigned cap;            // shared blocks the reduction holds
    unsigned pad;
};

#define SB_GRID_STRIDE(i, n) for (unsigned i = thread_index(); i < (n); i += gridDim.x * blockDim.x)

// Block coordinates are stored as 19-bit codes (compact3): -1 comes back as 0x7ffff.
__device__ __forceinline__ int sb_sign19(int v) { return v >= (1 << 18) ? v - (1 << 19) : v; }

// Dense index of block (bi, bj, bk), or EMPTY_ID outside the domain's blocks.
__device__ __forceinline__ unsigned sb_dense(const SharedCtx& s, int bi, int bj, int bk) {
    int q[3] = {bi + 1, bj + 1, bk + 1};
    for (int a = 0; a < 3; ++a)
        if (q[a] < 0 || q[a] >= s.dims[a]) return EMPTY_ID;
    return ((unsigned)q[0] * (unsigned)s.dims[1] + (unsigned)q[1]) * (unsigned)s.dims[2] + (unsigned)q[2];
}

__device__ __forceinline__ bool sb_any_rebuilt(const SharedCtx& s) { return s.counts[s.d] != 0; }

extern "C" __global__ void sb_clear_mask(Ctx c, SharedCtx s) {
    if (!c.ctl[CTL_REBUILT_NOW]) return;
    SB_GRID_STRIDE(i, s.d) s.mask[i] = 0;
}

extern "C" __global__ void sb_mark(Ctx c, SharedCtx s) {
    unsigned rebuilt = c.ctl[CTL_REBUILT_NOW];
    if (thread_index() == 0) s.mask[s.d] = rebuilt ? 1 : 0;
    if (!rebuilt) return;
    unsigned np = min(c.ctl[CTL_PBLOCKS], c.pblock_cap);
    SB_GRID_STRIDE(id, np) {
        const int* bc = c.block_coords + 3 * id;
        unsigned di = sb_dense(s, sb_sign19(bc[0]), sb_sign19(bc[1]), sb_sign19(bc[2]));
        if (di != EMPTY_ID) s.mask[di] = 1;
    }
}

// One CUDA block of 1024 threads per chunk of 1024 dense blocks (grid-stride over chunks).
extern "C" __global__ void sb_chunk_count(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    unsigned chunks = (s.d + 1023u) / 1024u;
    for (unsigned ch = blockIdx.x; ch < chunks; ch += gridDim.x) {
        unsigned i = ch * 1024u + threadIdx.x;
        int n = __syncthreads_count(i < s.d && s.counts[i] >= 2);
        if (threadIdx.x == 0) s.chunk[ch] = (unsigned)n;
    }
}

// One CUDA block of 1024 threads: exclusive scan of the chunk counts; the total is the number of
// shared blocks.
extern "C" __global__ void sb_chunk_scan(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    unsigned chunks = (s.d + 1023u) / 1024u;
    unsigned carry = 0;
    for (unsigned start = 0; start < chunks; start += blockDim.x) {
        unsigned i = start + threadIdx.x;
        unsigned v = i < chunks ? s.chunk[i] : 0;
        unsigned total;
        unsigned e = block_exclusive_scan(v, &total);
        if (i < chunks) s.chunk[i] = e + carry;
        carry += total;
    }
    if (threadIdx.x == 0) {
        c.ctl[CTL_SHARED] = carry;
        c.ctl[CTL_SHARED_CAP] = s.cap;
        if (carry > s.cap) atomicOr(&c.ctl[CTL_ERROR], ERR_SHARED);
    }
}

extern "C" __global__ void sb_list(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    unsigned chunks = (s.d + 1023u) / 1024u;
    for (unsigned ch = blockIdx.x; ch < chunks; ch += gridDim.x) {
        unsigned i = ch * 1024u + threadIdx.x;
        unsigned flag = (i < s.d && s.counts[i] >= 2) ? 1u : 0u;
        unsigned total;
        unsigned pos = s.chunk[ch] + block_exclusive_scan(flag, &total);
        if (flag && pos < s.cap) {
            int bk = (int)(i % (unsigned)s.dims[2]) - 1;
            int bj = (int)(i / (unsigned)s.dims[2] % (unsigned)s.dims[1]) - 1;
            int bi = (int)(i / ((unsigned)s.dims[2] * (unsigned)s.dims[1])) - 1;
            s.shared_local[pos] = hash_find(c, block_code(bi, bj, bk));
        }
    }
}

// A gblock is a boundary gblock when one of its 27 neighbours is shared; a pblock shared itself
// gets the number of GPUs that hold it (its grid update waits for the sum, and its share of a
// rigid body's impulse is 1 / that number on each of them, grid_update.cu: couple_bodies), 0
// otherwise.
extern "C" __global__ void sb_boundary(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    unsigned np = min(c.ctl[CTL_PBLOCKS], c.pblock_cap);
    SB_GRID_STRIDE(p, np) {
        const int* bc = c.block_coords + 3 * p;
        unsigned di = sb_dense(s, sb_sign19(bc[0]), sb_sign19(bc[1]), sb_sign19(bc[2]));
        unsigned holders = di != EMPTY_ID ? s.counts[di] : 0u;
        c.shared_pblock[p] = holders >= 2 ? holders : 0u;
    }
    unsigned ng = min(c.ctl[CTL_GBLOCKS], c.gblock_cap);
    SB_GRID_STRIDE(g, ng) {
        const int* bc = c.block_coords + 3 * g;
        unsigned b = 0;
        for (int t = 0; t < 27 && !b; ++t) {
            unsigned di = sb_dense(s, sb_sign19(bc[0]) + t / 9 - 1, sb_sign19(bc[1]) + t / 3 % 3 - 1,
                                   sb_sign19(bc[2]) + t % 3 - 1);
            b = di != EMPTY_ID && s.counts[di] >= 2;
        }
        c.boundary[g] = b;
    }
}

// 256 reals per block: 64 nodes of (mass, momentum).
extern "C" __global__ void sb_pack(Ctx c, SharedCtx s) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n = min(c.ctl[CTL_SHARED], s.cap) * 256u;
    SB_GRID_STRIDE(t, n) {
        unsigned id = s.shared_local[t >> 8];
        s.buf[t] = id == EMPTY_ID ? (real)0 : c.grid[id * 256u + (t & 255u)];
    }
}

extern "C" __global__ void sb_unpack(Ctx c, SharedCtx s) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n = min(c.ctl[CTL_SHARED], s.cap) * 256u;
    SB_GRID_STRIDE(t, n) {
        unsigned id = s.shared_local[t >> 8];
        if (id != EMPTY_ID) c.grid[id * 256u + (t & 255u)] = s.buf[t];
    }
}

// transport=p2p: every GPU's mask and packed buffer (this GPU's included), as pointers this GPU
// can dereference (unified addressing + peer access), in rank order.
struct PeerCtx {
    const unsigned char* mask[SB_MAX_GPUS];  // d + 1 bytes each (SharedCtx::mask of that GPU)
    const real* buf[SB_MAX_GPUS];            // cap * 256 reals each (SharedCtx::buf of that GPU)
    unsigned n;                              // GPUs
    unsigned me;                             // this GPU's rank
};

// counts = the sum of every GPU's mask (the NCCL all-reduce of the masks, done by reading the peers'
// masks; runs after the barrier that follows every GPU's sb_mark). When no GPU rebuilt, no mask
// changed since the last sum: only counts[d] (= 0) is written and the list kernels return at once.
extern "C" __global__ void sb_counts_peers(Ctx c, SharedCtx s, PeerCtx p) {
    unsigned rebuilt = 0;
    for (unsigned g = 0; g < p.n; ++g) rebuilt += __ldcg(p.mask[g] + s.d);
    if (thread_index() == 0) s.counts[s.d] = (unsigned char)rebuilt;
    if (!rebuilt) return;
    SB_GRID_STRIDE(i, s.d) {
        unsigned n = 0;
        for (unsigned g = 0; g < p.n; ++g) n += __ldcg(p.mask[g] + i);
        s.counts[i] = (unsigned char)n;
    }
}

// The reduce-sum of the shared blocks through peer reads: after the barrier that follows every
// GPU's sb_pack, node t of shared block t / 256 is the sum of the GPUs' packed values in rank order
// (for 2 GPUs the same single addition as the NCCL all-reduce), written into this GPU's grid.
extern "C" __global__ void sb_sum_peers(Ctx c, SharedCtx s, PeerCtx p) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n = min(c.ctl[CTL_SHARED], s.cap) * 256u;
    SB_GRID_STRIDE(t, n) {
        unsigned id = s.shared_local[t >> 8];
        if (id == EMPTY_ID) continue;
        real sum = __ldcg(p.buf[0] + t);
        for (unsigned g = 1; g < p.n; ++g) sum += __ldcg(p.buf[g] + t);
        c.grid[id * 256u + (t & 255u)] = sum;
    }
}
