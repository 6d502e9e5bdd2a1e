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
#include "../grid_barrier.cuh"
#include "spin.cuh"
// grid_update_node, clear_node (exchange=push_update: grid_update_gather); compiled before in
// the one program, included here so that this file also compiles alone (the exchange PTX test).
#include "../grid_update.cu"

struct SharedCtx {
    unsigned char* mask;     // d + 1: this GPU's pblocks; [d] = 1 if it rebuilt this step
    unsigned char* counts;   // d + 1: the sum of the masks over the GPUs
    unsigned* chunk;         // per chunk of 1024 dense blocks: shared count, then its offset
    unsigned* shared_local;  // cap: this GPU's pblock id of each shared block, or EMPTY_ID
    real* buf;               // cap * 256 reals: the nodes of the shared blocks
    unsigned char* holders;  // cap (exchange=fused|push): bit g set when GPU g holds the block
    int dims[3];             // dense block array: pblock coordinates -1 .. dims - 2 per axis
    unsigned d;              // dims[0] * dims[1] * dims[2]
    unsigned cap;            // shared blocks the reduction holds
    unsigned pad;
};

// transport=p2p: every GPU's mask and packed buffer (this GPU's included), as pointers this GPU
// can dereference (unified addressing + peer access), in rank order.
struct PeerCtx {
    const unsigned char* mask[SB_MAX_GPUS];  // d + 1 bytes each (SharedCtx::mask of that GPU)
    const real* buf[SB_MAX_GPUS];            // cap * 256 reals each (SharedCtx::buf of that GPU)
    unsigned n;                              // GPUs
    unsigned me;                             // this GPU's rank
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

__device__ __forceinline__ void sb_mark_body(const Ctx& c, const SharedCtx& s) {
    unsigned np = min(c.ctl[CTL_PBLOCKS], c.pblock_cap);
    SB_GRID_STRIDE(id, np) {
        const int* bc = c.block_coords + 3 * id;
        unsigned di = sb_dense(s, sb_sign19(bc[0]), sb_sign19(bc[1]), sb_sign19(bc[2]));
        if (di != EMPTY_ID) s.mask[di] = 1;
    }
}
extern "C" __global__ void sb_mark(Ctx c, SharedCtx s) {
    unsigned rebuilt = c.ctl[CTL_REBUILT_NOW];
    if (thread_index() == 0) s.mask[s.d] = rebuilt ? 1 : 0;
    if (!rebuilt) return;
    sb_mark_body(c, s);
}

// One CUDA block of 1024 threads per chunk of 1024 dense blocks (grid-stride over chunks).
__device__ __forceinline__ void sb_chunk_count_body(const SharedCtx& s) {
    unsigned chunks = (s.d + 1023u) / 1024u;
    for (unsigned ch = blockIdx.x; ch < chunks; ch += gridDim.x) {
        unsigned i = ch * 1024u + threadIdx.x;
        int n = __syncthreads_count(i < s.d && s.counts[i] >= 2);
        if (threadIdx.x == 0) s.chunk[ch] = (unsigned)n;
    }
}
extern "C" __global__ void sb_chunk_count(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    sb_chunk_count_body(s);
}

// One CUDA block of 1024 threads: exclusive scan of the chunk counts; the total is the number of
// shared blocks.
__device__ __forceinline__ void sb_chunk_scan_body(const Ctx& c, const SharedCtx& s) {
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
extern "C" __global__ void sb_chunk_scan(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    sb_chunk_scan_body(c, s);
}

// `p` (exchange=fused|push, else null): also the holders of each shared block, from the masks.
__device__ __forceinline__ void sb_list_body(const Ctx& c, const SharedCtx& s, const PeerCtx* p) {
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
            if (p) {
                unsigned h = 0;
#pragma unroll
                for (unsigned g = 0; g < SB_MAX_GPUS; ++g)
                    if (g < p->n && __ldcg(p->mask[g] + i)) h |= 1u << g;
                s.holders[pos] = (unsigned char)h;
            }
        }
    }
}
extern "C" __global__ void sb_list(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    sb_list_body(c, s, nullptr);
}

// A gblock is a boundary gblock when one of its 27 neighbours is shared; a pblock shared itself
// gets the number of GPUs that hold it (its grid update waits for the sum, and its share of a
// rigid body's impulse is 1 / that number on each of them, grid_update.cu: couple_bodies), 0
// otherwise.
__device__ __forceinline__ void sb_boundary_body(const Ctx& c, const SharedCtx& s) {
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
extern "C" __global__ void sb_boundary(Ctx c, SharedCtx s) {
    if (!sb_any_rebuilt(s)) return;
    sb_boundary_body(c, s);
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


__device__ __forceinline__ void sb_counts_body(const SharedCtx& s, const PeerCtx& p) {
    SB_GRID_STRIDE(i, s.d) {
        unsigned n = 0;
        // Unrolled over the constant bound: no local copy of the pointer array.
#pragma unroll
        for (unsigned g = 0; g < SB_MAX_GPUS; ++g)
            if (g < p.n) n += __ldcg(p.mask[g] + i);
        s.counts[i] = (unsigned char)n;
    }
}

// counts = the sum of every GPU's mask (the NCCL all-reduce of the masks, done by reading the peers'
// masks; runs after the barrier that follows every GPU's sb_mark). When no GPU rebuilt, no mask
// changed since the last sum: only counts[d] (= 0) is written and the list kernels return at once.
extern "C" __global__ void sb_counts_peers(Ctx c, SharedCtx s, PeerCtx p) {
    unsigned rebuilt = 0;
    for (unsigned g = 0; g < p.n; ++g) rebuilt += __ldcg(p.mask[g] + s.d);
    if (thread_index() == 0) s.counts[s.d] = (unsigned char)rebuilt;
    if (!rebuilt) return;
    sb_counts_body(s, p);
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

// ---- exchange=fused and exchange=push (transport=p2p with the spin barrier, one process) ----
//
// exchange=fused: the whole shared-list stage of a step in ONE cooperative launch (its grid: one
// block of 1024 threads per SM, all resident), where `kernels` launches eight (sb_clear_mask,
// sb_mark, barrier_spin, sb_counts_peers, sb_chunk_count, sb_chunk_scan, sb_list, sb_boundary),
// seven of them returning at once in a step without a rebuild. The phases are separated by the
// grid barrier of the fused rebuild; the inter-GPU barrier is taken by one thread while the
// other blocks wait at a grid barrier. Every branch below depends only on values that are the
// same in every block (the control words written by earlier kernels, the peers' rebuilt flags
// read after the inter-GPU barrier), so every block meets the same barriers. With `q` (push)
// it also lists the holders of each shared block. The stage is a device function so that
// sb_list_push (exchange=list_push_update) runs it too; its return is the same in every block.
__device__ __forceinline__ void sb_list_stage(const Ctx& c, const SharedCtx& s, const PeerCtx& p,
                                              const SpinBarrier& b) {
    unsigned rebuilt = c.ctl[CTL_REBUILT_NOW];
    if (rebuilt) {
        SB_GRID_STRIDE(i, s.d) s.mask[i] = 0;
        rb_grid_barrier(c);
        sb_mark_body(c, s);
        // The peers read the mask after the inter-GPU barrier: every writer's fence, and every
        // block done marking before the one thread arrives there.
        __threadfence_system();
        rb_grid_barrier(c);
    }
    if (thread_index() == 0) {
        s.mask[s.d] = rebuilt ? 1 : 0;
        spin_barrier_arrive_wait(c, b);
    }
    rb_grid_barrier(c);
    unsigned any = 0;
#pragma unroll
    for (unsigned g = 0; g < SB_MAX_GPUS; ++g)
        if (g < p.n) any += __ldcg(p.mask[g] + s.d);
    if (thread_index() == 0) s.counts[s.d] = (unsigned char)any;
    if (!any) return;  // the same in every block: no GPU rebuilt, the list stands
    sb_counts_body(s, p);
    rb_grid_barrier(c);
    sb_chunk_count_body(s);
    rb_grid_barrier(c);
    if (blockIdx.x == 0) sb_chunk_scan_body(c, s);
    rb_grid_barrier(c);
    sb_list_body(c, s, s.holders ? &p : nullptr);
    sb_boundary_body(c, s);
}

extern "C" __global__ void __launch_bounds__(1024) sb_list_fused(Ctx c, SharedCtx s, PeerCtx p,
                                                                 SpinBarrier b) {
    sb_list_stage(c, s, p, b);
}

// exchange=push: each GPU writes its nodes of every shared block it holds straight into the inbox
// of every other GPU that holds it (remote stores through peer pointers, 16 bytes a thread),
// then arrives at the other GPUs' counters; each GPU waits on its OWN counter (no polling across
// the link) and sums its inbox with its own nodes, every holder in rank order (the same order,
// so the same bits, on every GPU, and the same sum as sb_sum_peers). Two launches where
// exchange=kernels/fused makes three (sb_pack, barrier_spin, sb_sum_peers), and the nodes cross
// the link once, to the GPUs that hold them (pull reads every GPU's buffer, holder or not).
//
// The inbox is double buffered by the parity of the exchange count g, so no GPU overwrites a
// buffer a peer still reads: GPU i writes buffer g & 1 again at exchange g + 2, after its wait of
// exchange g + 1, which needs GPU j's arrival at g + 1, which j makes after its sum of g (stream
// order). Arrival counters only grow (target g * n): a CUDA graph replays both kernels as is.
struct PushCtx {
    real* inbox[SB_MAX_GPUS];                   // every GPU's inbox: 2 x n x cap x 256 reals
    unsigned long long* arrivals[SB_MAX_GPUS];  // every GPU's arrival counter (its memory)
    unsigned long long* calls;                  // this GPU: exchanges so far
    unsigned* done;                             // this GPU: blocks of sb_push done (reset by the last)
    unsigned long long timeout_ns;
    unsigned n;                                 // GPUs
    unsigned me;                                // this GPU's rank
};

// 16 bytes a thread: 4 reals in f32, 2 in f64.
#ifdef RTMPM_F64
typedef double2 sb_vec;
#define SB_VEC 2u
__device__ __forceinline__ sb_vec sb_vadd(sb_vec a, sb_vec b) { return make_double2(a.x + b.x, a.y + b.y); }
__device__ __forceinline__ sb_vec sb_vzero() { return make_double2(0.0, 0.0); }
#else
typedef float4 sb_vec;
#define SB_VEC 4u
__device__ __forceinline__ sb_vec sb_vadd(sb_vec a, sb_vec b) {
    return make_float4(a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w);
}
__device__ __forceinline__ sb_vec sb_vzero() { return make_float4(0.f, 0.f, 0.f, 0.f); }
#endif
#define SB_VECS (256u / SB_VEC)  // vectors a block

// Index of vector v of shared block pos from GPU `from` in an inbox, exchange parity `par`.
__device__ __forceinline__ size_t sb_inbox_at(const SharedCtx& s, const PushCtx& q, unsigned par,
                                              unsigned from, unsigned pos, unsigned v) {
    return (((size_t)par * q.n + from) * s.cap + pos) * SB_VECS + v;
}

// This GPU's nodes of every shared block it holds into the inboxes of the other holders
// (exchange parity `par`), grid-stride; nothing after an error.
__device__ __forceinline__ void sb_push_nodes(const Ctx& c, const SharedCtx& s, const PushCtx& q, unsigned par) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned nb = min(c.ctl[CTL_SHARED], s.cap);
    const sb_vec* grid = (const sb_vec*)c.grid;
    SB_GRID_STRIDE(t, nb * SB_VECS) {
        unsigned pos = t / SB_VECS, v = t % SB_VECS;
        unsigned h = s.holders[pos];
        if (!(h >> q.me & 1u)) continue;  // not held here: nothing to send
        h &= ~(1u << q.me);
        unsigned id = s.shared_local[pos];
        sb_vec x = id == EMPTY_ID ? sb_vzero() : grid[(size_t)id * SB_VECS + v];
        size_t at = sb_inbox_at(s, q, par, q.me, pos, v);
        // Unrolled over the constant bound: the inbox pointers stay kernel parameters (global
        // stores), never a local copy of the array indexed at run time.
#pragma unroll
        for (unsigned to = 0; to < SB_MAX_GPUS; ++to)
            if (h >> to & 1u) ((sb_vec*)q.inbox[to])[at] = x;
    }
}

// One thread, once every thread's pushes are fenced: arrive at every GPU's counter for exchange
// g (always, error or not: no GPU is left waiting for the timeout) and count the exchange.
__device__ __forceinline__ void sb_arrive(const Ctx& c, const PushCtx& q, unsigned long long g) {
    __threadfence_system();
#if __CUDA_ARCH__ >= 700
#pragma unroll
    for (unsigned to = 0; to < SB_MAX_GPUS; ++to)
        if (to < q.n) atomicAdd_system(q.arrivals[to], 1ull);
#else
    atomicOr(&c.ctl[CTL_ERROR], ERR_BARRIER);
#endif
    *q.calls = g;
}

extern "C" __global__ void sb_push(Ctx c, SharedCtx s, PushCtx q) {
    unsigned long long g = *q.calls + 1ull;  // this exchange (set by the last block at the end)
    sb_push_nodes(c, s, q, (unsigned)(g & 1ull));
    // Every thread's remote stores are visible everywhere before the block counts as done; the
    // last block done arrives.
    __threadfence_system();
    __syncthreads();
    if (threadIdx.x == 0 && atomicAdd(q.done, 1u) == gridDim.x - 1) {
        *q.done = 0;
        sb_arrive(c, q, g);
    }
}

// This GPU's inbox and arrival counter, picked with constant indices (no local copy of the
// arrays, which would put them in local memory).
__device__ __forceinline__ void sb_own(const PushCtx& q, const sb_vec** inbox, unsigned long long** mine) {
#pragma unroll
    for (unsigned k = 0; k < SB_MAX_GPUS; ++k)
        if (k == q.me) {
            *inbox = (const sb_vec*)q.inbox[k];
            *mine = q.arrivals[k];
        }
}

// Every thread of the block calls it: thread 0 waits until this GPU's own counter `mine` reaches
// exchange g's target (every GPU arrived, so their pushes into this inbox are visible), then the
// block goes on; ERR_BARRIER after the timeout. False when the step has an error (the block then
// stops: no thread of it meets another barrier).
__device__ __forceinline__ bool sb_wait_own(const Ctx& c, const PushCtx& q, unsigned long long* mine,
                                            unsigned long long g) {
    if (threadIdx.x == 0) {
        unsigned long long target = g * (unsigned long long)q.n;
        unsigned long long start = bar_now_ns();
        for (;;) {
            unsigned long long v;
            asm volatile("ld.acquire.sys.global.u64 %0, [%1];"
                         : "=l"(v)
                         : "l"(mine)
                         : "memory");
            if (v >= target) break;
            if (bar_now_ns() - start > q.timeout_ns) {
                atomicOr(&c.ctl[CTL_ERROR], ERR_BARRIER);
                break;
            }
            __nanosleep(32);
        }
        __threadfence();
    }
    __syncthreads();
    return !((volatile unsigned*)c.ctl)[CTL_ERROR];
}

// Vector v of shared block `pos` summed over its holders `h` in rank order (this GPU's own value
// `mine` at its rank, the others' from the inbox of exchange parity `par`): the same additions in
// the same order on every GPU, in sb_gather and in grid_update_gather.
__device__ __forceinline__ sb_vec sb_sum_holders(const SharedCtx& s, const PushCtx& q, const sb_vec* inbox,
                                                 unsigned par, unsigned h, unsigned pos, unsigned v, sb_vec mine) {
    sb_vec sum = sb_vzero();
    bool first = true;
    for (unsigned from = 0; from < q.n; ++from) {
        if (!(h >> from & 1u)) continue;
        sb_vec x = from == q.me ? mine : __ldcg(inbox + sb_inbox_at(s, q, par, from, pos, v));
        sum = first ? x : sb_vadd(sum, x);
        first = false;
    }
    return sum;
}

extern "C" __global__ void sb_gather(Ctx c, SharedCtx s, PushCtx q) {
    unsigned long long g = *q.calls;  // set by sb_push, the kernel before on this stream
    unsigned par = (unsigned)(g & 1ull);
    const sb_vec* inbox = nullptr;
    unsigned long long* mine = nullptr;
    sb_own(q, &inbox, &mine);
    if (!sb_wait_own(c, q, mine, g)) return;
    unsigned nb = min(c.ctl[CTL_SHARED], s.cap);
    sb_vec* grid = (sb_vec*)c.grid;
    SB_GRID_STRIDE(t, nb * SB_VECS) {
        unsigned pos = t / SB_VECS, v = t % SB_VECS;
        unsigned id = s.shared_local[pos];
        unsigned h = s.holders[pos];
        if (id == EMPTY_ID || !(h >> q.me & 1u)) continue;
        sb_vec* own = grid + (size_t)id * SB_VECS + v;
        *own = sb_sum_holders(s, q, inbox, par, h, pos, v, *own);
    }
}

// ---- exchange=push_update: the inbox summed inside the grid update ----
//
// One kernel in place of sb_gather and grid_update: after sb_push (the kernel before, on the same
// stream), every thread first updates its nodes of the pblocks no other GPU holds (grid_update's
// part 1, while the peers' pushes are still arriving), then each block waits on this GPU's own
// counter (sb_wait_own) and updates the nodes of the shared pblocks, each summed from its holders
// as sb_gather sums it (sb_sum_holders: the same bits) just before its update. One launch and one
// read and write of the shared nodes less than sb_gather + grid_update, no event between two
// streams. The inbox's double buffering holds as for sb_gather: GPU j reads exchange g's buffer
// here, before its sb_push of g + 1, without which no GPU gets past its wait of g + 1 to write
// that buffer again at g + 2.
#define SB_NODE_VECS (4u / SB_VEC)  // vectors a node (mass, momentum)

extern "C" __global__ void grid_update_gather(Ctx c, SharedCtx s, PushCtx q) {
    unsigned long long g = *q.calls;  // set by sb_push
    unsigned par = (unsigned)(g & 1ull);
    const sb_vec* inbox = nullptr;
    unsigned long long* mine = nullptr;
    sb_own(q, &inbox, &mine);
    // No early return before the wait: every thread of a block meets its __syncthreads.
    if (!c.ctl[CTL_ERROR]) {
        unsigned n_nodes = c.ctl[CTL_PBLOCKS] * 64u;
        if (c.grid_next && thread_index() == 0) c.ctl[CTL_P2G_PENDING] = 0;  // this step's P2G is done
        SB_GRID_STRIDE(t, n_nodes) {
            if (c.shared_pblock[t >> 6] != 0) continue;
            grid_update_node(c, t);
            if (c.grid_next) clear_node(c.grid_next, t);
            if (c.grid_aux_next) clear_node(c.grid_aux_next, t);
        }
    }
    if (!sb_wait_own(c, q, mine, g)) return;
    unsigned nb = min(c.ctl[CTL_SHARED], s.cap);
    sb_vec* grid = (sb_vec*)c.grid;
    SB_GRID_STRIDE(t, nb * 64u) {
        unsigned pos = t >> 6, cell = t & 63u;
        unsigned id = s.shared_local[pos];
        unsigned h = s.holders[pos];
        if (id == EMPTY_ID || !(h >> q.me & 1u)) continue;
        unsigned node = id * 64u + cell;
#pragma unroll
        for (unsigned j = 0; j < SB_NODE_VECS; ++j) {
            unsigned v = cell * SB_NODE_VECS + j;
            sb_vec* own = grid + (size_t)id * SB_VECS + v;
            *own = sb_sum_holders(s, q, inbox, par, h, pos, v, *own);
        }
        grid_update_node(c, node);
        if (c.grid_next) clear_node(c.grid_next, node);
        if (c.grid_aux_next) clear_node(c.grid_aux_next, node);
    }
}

// ---- exchange=list_push_update: the shared list and the push in one cooperative kernel ----
//
// Without the overlap the P2G of a step needs no shared list (only its split into boundary and
// interior gblocks does), so the list can follow it: after the step's P2G, one launch makes the
// list stage of sb_list_fused (mask, spin barrier, sum of the masks, list, boundary), then, after
// a grid barrier, the push of sb_push, then, after a second grid barrier (every thread's remote
// stores fenced before it), one thread's arrival at every GPU's counter; grid_update_gather
// follows. Launches a step: the rebuild, the gated P2G, this, grid_update_gather and G2P2G (one
// GPU: 4). The masks, inboxes and counters are used as with exchange=push: a GPU rewrites its
// mask or an inbox buffer only after a wait that needs every peer's arrival of the step before,
// which each peer makes after its reads of them (here: after the list, in the same kernel).
extern "C" __global__ void __launch_bounds__(1024) sb_list_push(Ctx c, SharedCtx s, PeerCtx p, SpinBarrier b,
                                                                PushCtx q) {
    unsigned long long g = *q.calls + 1ull;  // read by every thread before one sets it, at the end
    sb_list_stage(c, s, p, b);
    rb_grid_barrier(c);  // the list, holders and shared count of every block written
    sb_push_nodes(c, s, q, (unsigned)(g & 1ull));
    __threadfence_system();
    rb_grid_barrier(c);
    if (thread_index() == 0) sb_arrive(c, q, g);
}
