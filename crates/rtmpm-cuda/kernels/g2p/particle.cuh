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
    s.material = state_bits(c.state[sidx(c.cap, F_MAT, p)]);
    s.id = ALL_FLUID ? 0u : state_bits(c.state[sidx(c.cap, F_ID, p)]);
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
    bool finite = isfinite(x.x) && isfinite(x.y) && isfinite(x.z) && isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
    const Scalars& sc = scalars(c);
    if (!finite || speed * dt > (real)2 * sc.dx) {
        unsigned id = ALL_FLUID ? state_bits(c.state[sidx(c.cap, F_ID, p)]) : st.id;
        unsigned prev = atomicMin(&c.ctl[CTL_BAD_INDEX], id);
        if (prev > id) atomicExch(&c.ctl[CTL_BAD_REASON], finite ? 2u : 1u);
    }
    x.x = fmin(fmax(x.x, sc.domain_min[0]), sc.domain_max[0]);
    x.y = fmin(fmax(x.y, sc.domain_min[1]), sc.domain_max[1]);
    x.z = fmin(fmax(x.z, sc.domain_min[2]), sc.domain_max[2]);
    // Free zone: the 3x3x3 neighbourhood of gblock B covers the stencil iff base in [4B-4, 4B+5].
    int nb[3]; real nfx[3];
    stencil_of(c, x, nb, nfx);
    bool leave = !finite;
    for (int a = 0; a < 3; ++a) leave = leave || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
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

// MLS-MPM G2P of particle p of gblock g (Hu et al. 2018): gather of v and C from the grid, then
// g2p_finish. The new state is stored and returned.
template <bool ALL_FLUID>
__device__ __forceinline__ G2pResult g2p_particle(const Ctx& c, unsigned g, unsigned p) {
    vec3 x = load_v3(c.state, c.cap, F_X, p);
    G2pState st = g2p_load_state<ALL_FLUID>(c, p);
    int base[3]; real fx[3]; real wt[3][3];
    stencil_of(c, x, base, fx);
    for (int a = 0; a < 3; ++a) weights_1d(fx[a], wt[a]);
    const int* bc = c.block_coords + 3 * g;
    const unsigned* nbs = c.neighbors + 27 * g;
    StencilIdx si = stencil_idx(bc, base);
    // v = sum w v_i; B = sum w v_i (i, j, k)^T accumulated axis by axis; then
    // C = D^-1 dx (B - v fx^T) = D^-1 sum w v_i (x_i - x_p)^T (APIC; cpu/g2p.rs does the same).
    vec3 v = make_v3(0, 0, 0), b0 = v, b1 = v, b2 = v;
    for (int i = 0; i < 3; ++i) {
        vec3 sum_i = make_v3(0, 0, 0), b1_i = sum_i, b2_i = sum_i;
        for (int j = 0; j < 3; ++j) {
            real wij = wt[0][i] * wt[1][j];
            vec3 sum_j = make_v3(0, 0, 0), b2_j = sum_j;
            for (int k = 0; k < 3; ++k) {
                unsigned id = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]];
                unsigned cell = si.cell[0][i] | si.cell[1][j] | si.cell[2][k];
#ifdef RTMPM_F64
                const real* node = c.grid + 4u * (id * 64u + cell);
                vec3 vi = make_v3(node[1], node[2], node[3]);
#else
                float4 nd = __ldg(reinterpret_cast<const float4*>(c.grid) + (id * 64u + cell));
                vec3 vi = make_v3(nd.y, nd.z, nd.w);
#endif
                vec3 wv = vi * (wij * wt[2][k]);
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
    mat3 B;
    B.m[0] = b0.x; B.m[1] = b0.y; B.m[2] = b0.z;
    B.m[3] = b1.x; B.m[4] = b1.y; B.m[5] = b1.z;
    B.m[6] = b2.x; B.m[7] = b2.y; B.m[8] = b2.z;
    const Scalars& sc = scalars(c);
    B = (B - outer(v, make_v3(fx[0], fx[1], fx[2]))) * sc.dx;
    real dt = step_params(c).dt;
    mat3 C = B * ((real)4 * sc.inv_dx * sc.inv_dx);
    return g2p_finish<ALL_FLUID>(c, bc, p, st, x + v * dt, v, C);
}
