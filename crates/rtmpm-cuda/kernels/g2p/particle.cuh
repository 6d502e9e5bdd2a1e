// G2P of one particle, shared by the G2P kernels (g2p.cu) and the fused G2P2G (g2p2g.cu):
// interpolation of v and C, F update, plasticity, advection, domain clamp, free-zone check (sets
// the rebuild flag) and health check (first bad particle, max speed).
#pragma once
#include "../common.cuh"
#include "../material/dispatch.cuh"

// The state G2P updates besides x, v and C: loaded before the grid gather, so that its memory
// latency overlaps the gather's instead of following it (G2P is bound by load latency).
//
// ALL_FLUID (template flag of the functions below): the variant for scenes whose materials are
// all weakly compressible fluids, whose F is J^(1/3) I: F is one word in and three out
// (load_deformation), the material model is not dispatched, the plastic word (unused by a fluid)
// is neither read nor written and the id is read only for a bad particle. The general variant
// (false) serves every scene.
struct G2pState {
    mat3 F;
    real plastic;
    unsigned material, id;
};
template <bool ALL_FLUID>
__device__ __forceinline__ G2pState g2p_load_state(const Ctx& c, unsigned p) {
    G2pState s;
    s.F = load_deformation(c.state, c.cap, p, ALL_FLUID);
    s.plastic = ALL_FLUID ? (real)0 : load_plastic(c.state, c.cap, p);
    s.material = state_bits(state_ld(c.state, sidx(c.cap, F_MAT, p)));
    s.id = ALL_FLUID ? 0u : state_bits(state_ld(c.state, sidx(c.cap, F_ID, p)));
    return s;
}

// What G2P leaves a particle with (also stored): read by the fused G2P2G for its scatter.
struct G2pResult {
    vec3 x, v;
    mat3 C, F;
    real plastic;
    bool leave;         // left its free zone (or not finite): the mapping must be rebuilt
    unsigned speed;     // |v| as float bits (0 if not finite)
    unsigned material;  // material id (unchanged)
};

// Max speed of the step (the float bits of the running max of each thread's particles; floats
// >= 0 order like their bit patterns): reduced in the warp and written with ONE atomic per warp
// at the end of the kernel, not one per warp-list entry (65,536 same-address atomics per step for
// 2M particles queue at one L2 slice).
__device__ __forceinline__ void report_max_speed(const Ctx& c, unsigned bits) {
    unsigned wmax = __reduce_max_sync(0xffffffffu, bits);
    if ((threadIdx.x & 31) == 0 && wmax) atomicMax(&c.ctl[CTL_MAX_SPEED], wmax);
}

// The health and free-zone checks of g2p_finish without branches between their terms, and
// the gblock's coordinates read once per particle for the gather and the checks (compile-time,
// default 0; the CUDA option `flat_checks=on`). The same predicates, so the same particles
// flagged and scattered. The fused kernel's P2G still reads the coordinates again: holding them
// through the G2P took more instructions with ptxas 13.0 than reading them.
#ifndef RTMPM_G2P_FLAT_CHECKS
#define RTMPM_G2P_FLAT_CHECKS 0
#endif

// The end of every G2P: F = (I + dt C) F, plasticity, health check (before the clamp, which
// would hide NaN), max speed, domain clamp, free-zone check, stores. `x` is the advected position,
// `C` the velocity gradient (APIC's C for MLS). Returns the new state.
template <bool ALL_FLUID>
__device__ __forceinline__ G2pResult g2p_finish(const Ctx& c, const int* bc, unsigned p, const G2pState& st, vec3 x, vec3 v,
                                                const mat3& C) {
    real dt = step_params(c).dt;
    mat3 F = (mat3_identity() + C * dt) * st.F;
    real plastic = st.plastic;
    const MaterialGpu& mat = material_at(c, st.material);
    F = ALL_FLUID ? fluid_project(fluid_params(mat), F, &plastic, dt) : material_project(mat, F, &plastic, dt);
    // Health check before the clamp (the clamp would hide NaN).
    real speed = length(v);
#if RTMPM_G2P_FLAT_CHECKS
    bool finite = isfinite(x.x) & isfinite(x.y) & isfinite(x.z) & isfinite(v.x) & isfinite(v.y) & isfinite(v.z);
    const Scalars& sc = scalars(c);
    if (!finite | (speed * dt > (real)2 * sc.dx)) {
#else
    bool finite = isfinite(x.x) && isfinite(x.y) && isfinite(x.z) && isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
    const Scalars& sc = scalars(c);
    if (!finite || speed * dt > (real)2 * sc.dx) {
#endif
        unsigned id = ALL_FLUID ? state_bits(state_ld(c.state, sidx(c.cap, F_ID, p))) : st.id;
        // The reason in the key's low bit (0: not finite, 1: too fast), so that one atomic keeps
        // the lowest id with its own reason (a second word written after the minimum could pair
        // one particle's index with another's reason).
        atomicMin(&c.ctl[CTL_BAD_INDEX], (id << 1) | (finite ? 1u : 0u));
    }
    x.x = fmin(fmax(x.x, sc.domain_min[0]), sc.domain_max[0]);
    x.y = fmin(fmax(x.y, sc.domain_min[1]), sc.domain_max[1]);
    x.z = fmin(fmax(x.z, sc.domain_min[2]), sc.domain_max[2]);
    // Free zone: the 3x3x3 neighbourhood of gblock B covers the stencil iff base in [4B-4, 4B+5].
    int nb[3]; real nfx[3];
    stencil_of(c, x, material_world(st.material), nb, nfx);
    bool leave = !finite;
#if RTMPM_G2P_FLAT_CHECKS
    // nb - 4 bc in [-4, 5] as one unsigned comparison per axis (x is clamped to the domain, so
    // the difference is small), with no branch between the axes.
    for (int a = 0; a < 3; ++a) leave |= (unsigned)(nb[a] - 4 * bc[a] + 4) > 9u;
#else
    for (int a = 0; a < 3; ++a) leave = leave || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
#endif
    if (leave) c.ctl[CTL_NEED_REBUILD] = 1;
    store_v3(c.state, c.cap, F_X, p, x);
    // The compact state rounds v and C: the fused P2G uses what is stored, as a separate P2G would.
    vec3 v_stored = store_vel(c.state, c.cap, p, v);
    mat3 C_stored = store_affine(c.state, c.cap, p, C);
    store_deformation(c.state, c.cap, p, F, ALL_FLUID);
    if (!ALL_FLUID) store_plastic(c.state, c.cap, p, plastic);
    G2pResult r;
    r.x = x; r.v = v_stored; r.C = C_stored; r.F = F; r.plastic = plastic;
    r.leave = leave;
    r.speed = finite ? __float_as_uint((float)speed) : 0u;
    r.material = st.material;
    return r;
}

// The G2P gather (compile-time, default 2): 0 node by node as written in the paper's sums,
// every node's id read from the neighbour list; 1 the stencil's eight pblocks read once
// (stencil_blocks) and the sums factorised per axis (the weights are a tensor product, so the k
// sums of a row, then the j sums of a plane, then the i sum): about 40 % fewer instructions for the
// same sums in another order (float rounding only); 2 the sums of 1 with the pair addressing
// (stencil_pairs in stencil.cuh: a row's node indices computed once, the node's offset in the
// load's immediate offset; the same loads and sums as 1 bit for bit, about 50 fewer
// instructions a particle). The CUDA option `addressing=blocks` compiles 1 (compile.rs).
#ifndef RTMPM_G2P_GATHER
#define RTMPM_G2P_GATHER 2
#endif

// Velocity of grid node `node` (memory index pblock id * 64 + cell).
__device__ __forceinline__ vec3 g2p_node_velocity(const Ctx& c, unsigned node) {
#ifdef RTMPM_F64
    const real* n = c.grid + 4u * node;
    return make_v3(n[1], n[2], n[3]);
#else
    float4 nd = __ldg(reinterpret_cast<const float4*>(c.grid) + node);
    return make_v3(nd.y, nd.z, nd.w);
#endif
}
// Velocity of node k of a pair-addressed row (stencil_pair_row): memory index n + k, the k in
// the load's immediate offset.
__device__ __forceinline__ vec3 g2p_row_node_velocity(const Ctx& c, int n, int k) {
#ifdef RTMPM_F64
    const real* nd = c.grid + 4ll * n + 4 * k;
    return make_v3(nd[1], nd[2], nd[3]);
#else
    float4 nd = __ldg(reinterpret_cast<const float4*>(c.grid) + n + k);
    return make_v3(nd.y, nd.z, nd.w);
#endif
}

// v = sum w v_i and B = sum w v_i (i, j, k)^T over the stencil of the particle at base/wt.
__device__ __forceinline__ void g2p_gather(const Ctx& c, const int* bc, const unsigned* nbs, const int base[3],
                                           const real wt[3][3], vec3* v_out, mat3* b_out) {
#if RTMPM_G2P_GATHER == 1 || RTMPM_G2P_GATHER == 2
#if RTMPM_G2P_GATHER == 2
    StencilPairs sp = stencil_pairs(nbs, bc, base);
#else
    StencilBlocks sb = stencil_blocks(nbs, bc, base);
#endif
    // k sums of row (i, j): r = sum_k w_k v_k and rk = sum_k k w_k v_k; j sums of plane i:
    // p = sum_j w_j r, pj = sum_j j w_j r, pk = sum_j w_j rk; then the i sums.
    real w1_2 = (real)2 * wt[1][2], w0_2 = (real)2 * wt[0][2];
    vec3 v, b0, b1, b2;
#pragma unroll
    for (int i = 0; i < 3; ++i) {
        vec3 p, pj, pk;
#if RTMPM_G2P_GATHER == 2
        int tx = sp.r[0] + i;
        unsigned plane[4];
        stencil_pair_plane(sp, tx >= 4, plane);
#endif
#pragma unroll
        for (int j = 0; j < 3; ++j) {
            vec3 vk[3];
#if RTMPM_G2P_GATHER == 2
            int ty = sp.r[1] + j;
            PairRow row = stencil_pair_row(sp, plane, ty >= 4, ((unsigned)(tx & 3) << 4) | ((unsigned)(ty & 3) << 2));
#pragma unroll
            for (int k = 0; k < 3; ++k) vk[k] = g2p_row_node_velocity(c, row.n[k], k);
#else
            unsigned row[2];
            stencil_row_blocks(sb, sb.hi[0][i], sb.hi[1][j], row);
            unsigned cell_ij = sb.cell[0][i] | sb.cell[1][j];
#pragma unroll
            for (int k = 0; k < 3; ++k) vk[k] = g2p_node_velocity(c, (sb.hi[2][k] ? row[1] : row[0]) * 64u + (cell_ij | sb.cell[2][k]));
#endif
            vec3 t = vk[1] * wt[2][1] + vk[2] * wt[2][2];
            vec3 r = vk[0] * wt[2][0] + t;
            vec3 rk = vk[2] * wt[2][2] + t;  // = w_1 v_1 + 2 w_2 v_2
            if (j == 0) {
                p = r * wt[1][0];
                pk = rk * wt[1][0];
            } else {
                p = p + r * wt[1][j];
                pk = pk + rk * wt[1][j];
                pj = j == 1 ? r * wt[1][1] : pj + r * w1_2;
            }
        }
        if (i == 0) {
            v = p * wt[0][0];
            b1 = pj * wt[0][0];
            b2 = pk * wt[0][0];
        } else {
            v = v + p * wt[0][i];
            b1 = b1 + pj * wt[0][i];
            b2 = b2 + pk * wt[0][i];
            b0 = i == 1 ? p * wt[0][1] : b0 + p * w0_2;
        }
    }
#else
    StencilIdx si = stencil_idx(bc, base);
    // v = sum w v_i; B = sum w v_i (i, j, k)^T accumulated axis by axis (cpu/g2p.rs does the same).
    vec3 v = make_v3(0, 0, 0), b0 = v, b1 = v, b2 = v;
    for (int i = 0; i < 3; ++i) {
        vec3 sum_i = make_v3(0, 0, 0), b1_i = sum_i, b2_i = sum_i;
        for (int j = 0; j < 3; ++j) {
            real wij = wt[0][i] * wt[1][j];
            vec3 sum_j = make_v3(0, 0, 0), b2_j = sum_j;
            for (int k = 0; k < 3; ++k) {
                unsigned id = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]];
                unsigned cell = si.cell[0][i] | si.cell[1][j] | si.cell[2][k];
                vec3 wv = g2p_node_velocity(c, id * 64u + cell) * (wij * wt[2][k]);
                sum_j = sum_j + wv;
                b2_j = b2_j + wv * (real)k;
            }
            sum_i = sum_i + sum_j;
            b1_i = b1_i + sum_j * (real)j;
            b2_i = b2_i + b2_j;
        }
        v = v + sum_i;
        b0 = b0 + sum_i * (real)i;
        b1 = b1 + b1_i;
        b2 = b2 + b2_i;
    }
#endif
    *v_out = v;
    *b_out = mat3_from_cols(b0, b1, b2);
}

// MLS-MPM G2P of particle p of gblock g (Hu et al. 2018): gather of v and C from the grid, then
// g2p_finish. The new state is stored and returned.
template <bool ALL_FLUID>
__device__ __forceinline__ G2pResult g2p_particle(const Ctx& c, unsigned g, unsigned p) {
    vec3 x = load_v3(c.state, c.cap, F_X, p);
    G2pState st = g2p_load_state<ALL_FLUID>(c, p);
    int base[3]; real fx[3]; real wt[3][3];
    stencil_of(c, x, material_world(st.material), base, fx);
    for (int a = 0; a < 3; ++a) weights_1d(fx[a], wt[a]);
#if RTMPM_G2P_FLAT_CHECKS
    // The gblock's coordinates read once: the gather and the free-zone check use these values
    // (through a pointer into memory they are read again after every store that may alias them).
    const int* bcp = c.block_coords + 3 * g;
    const int bc[3] = {bcp[0], bcp[1], bcp[2]};
#else
    const int* bc = c.block_coords + 3 * g;
#endif
    vec3 v;
    mat3 B;
    g2p_gather(c, bc, c.neighbors + 27 * g, base, wt, &v, &B);
    // C = D^-1 dx (B - v fx^T) = D^-1 sum w v_i (x_i - x_p)^T (APIC), D^-1 = 4 / dx^2.
    const Scalars& sc = scalars(c);
    B = (B - outer(v, make_v3(fx[0], fx[1], fx[2]))) * sc.dx;
    real dt = step_params(c).dt;
    mat3 C = B * ((real)4 * sc.inv_dx * sc.inv_dx);
    return g2p_finish<ALL_FLUID>(c, bc, p, st, x + v * dt, v, C);
}
