// P2G as a gather through a node-to-particle reverse map with replicated maps (Chiang et al., "GPU Acceleration of the Generalized Interpolation Material Point Method" (SAAHPC 2009), section
// II: "we maintain a set of nine independent reverse maps to reduce the number of atomicAdd calls
// to a single location"; the map stores each node's entries successively so that the gather's
// reads are coalesced, their Figure 2).
//
// 1. p2g_rmap_build, one thread per particle (fused, Chiang et al.'s "kernel fusion"): the particle
//    quantities and its 27 node values (p2g_particle.cuh, the same functions as the scatter) go to
//    the entry array, and the particle inserts each entry into map p % replicas of its node's
//    column: slot = atomicAdd(count[map][node], 1). A full column sets ERR_P2G_MAP.
// 2. p2g_rmap_gather, one thread per grid node of the pblocks in use: walks its columns in all
//    maps, sums the entries, stores the node (no atomics) and resets its counters for the next
//    step.
//
// Layout: counts[r * node_cap + node]; entries[(r * slots + s) * node_cap + node]: for a fixed
// (replica, slot) the entries of consecutive nodes are consecutive (coalesced gather reads).
#include "particle.cuh"

// Passed by value with the Ctx (src/p2g_reverse_map.rs mirrors it).
struct RmapCtx {
    real* contrib;      // 27 x cap entries of 4 reals (p2g_particle.cuh)
    unsigned* counts;   // replicas x node_cap
    unsigned* entries;  // replicas x slots x node_cap
    unsigned node_cap;  // nodes covered (64 per pblock)
    unsigned replicas;
    unsigned slots;  // entries per node and replica
    unsigned pad;
};

extern "C" __global__ void __launch_bounds__(128) p2g_rmap_build(Ctx c, RmapCtx r) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5, lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        P2gParticle q = p2g_particle(c, p);
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, q.base);
        const unsigned* nbs = c.neighbors + 27 * g;
        unsigned replica = p % r.replicas;
        unsigned* counts = r.counts + replica * r.node_cap;
        unsigned* entries = r.entries + replica * r.slots * r.node_cap;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    unsigned e = p2g_entry(c, p, i, j, k);
                    real val[4];
                    p2g_node_value(q, i, j, k, val);
                    p2g_store_entry(r.contrib, e, val);
                    unsigned node = stencil_node(si, nbs, i, j, k);
                    if (node >= r.node_cap) { atomicOr(&c.ctl[CTL_ERROR], ERR_P2G_MAP); continue; }
                    unsigned s = atomicAdd(&counts[node], 1u);
                    if (s >= r.slots) { atomicOr(&c.ctl[CTL_ERROR], ERR_P2G_MAP); continue; }
                    entries[s * r.node_cap + node] = e;
                }
    }
}

extern "C" __global__ void __launch_bounds__(256) p2g_rmap_gather(Ctx c, RmapCtx r) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_nodes = min(c.ctl[CTL_PBLOCKS] * 64u, r.node_cap);
    for (unsigned node = thread_index(); node < n_nodes; node += gridDim.x * blockDim.x) {
        real acc[4] = {0, 0, 0, 0};
        for (unsigned rep = 0; rep < r.replicas; ++rep) {
            unsigned* cnt = r.counts + rep * r.node_cap + node;
            unsigned n = min(*cnt, r.slots);
            *cnt = 0;
            const unsigned* col = r.entries + rep * r.slots * r.node_cap + node;
            for (unsigned s = 0; s < n; ++s) p2g_add_entry(r.contrib, col[s * r.node_cap], acc);
        }
        p2g_store_node(c, node, acc);
    }
}
