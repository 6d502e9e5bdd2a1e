// G2P (merged): interpolation of v and C, F update, plasticity, advection, domain clamp,
// free-zone check (sets the rebuild flag) and health check (first bad particle, max speed).
#include "common.cuh"
#include "material_dispatch.cuh"

#ifndef G2P_MIN_BLOCKS
#define G2P_MIN_BLOCKS 1
#endif

// The state G2P updates besides x, v and C: loaded before the grid gather, so that its memory
// latency overlaps the gather's instead of following it (G2P is bound by load latency).
struct G2pState {
    mat3 F;
    real plastic;
    unsigned material, id;
};
__device__ __forceinline__ G2pState g2p_load_state(const Ctx& c, unsigned p) {
    G2pState s;
    s.F = load_m3(c.state, c.cap, F_F, p);
    s.plastic = c.state[F_PLASTIC * c.cap + p];
    s.material = state_bits(c.state[F_MAT * c.cap + p]);
    s.id = state_bits(c.state[F_ID * c.cap + p]);
    return s;
}

__device__ __forceinline__ unsigned g2p_warp(const Ctx& c, unsigned w, unsigned lane);
__device__ __forceinline__ unsigned g2p_finish(const Ctx& c, const int* bc, unsigned p, G2pState st, vec3 x, vec3 v, const mat3& C);

// Max speed of the step (the float bits of the running max of each thread's particles; floats
// >= 0 order like their bit patterns): reduced in the warp and written with ONE atomic per warp
// at the end of the kernel, not one per warp-list entry (65,536 same-address atomics per step for
// 2M particles queue at one L2 slice).
__device__ __forceinline__ void report_max_speed(const Ctx& c, unsigned bits) {
    unsigned wmax = __reduce_max_sync(0xffffffffu, bits);
    if ((threadIdx.x & 31) == 0 && wmax) atomicMax(&c.ctl[CTL_MAX_SPEED], wmax);
}

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks).
extern "C" __global__ void __launch_bounds__(128, G2P_MIN_BLOCKS) g2p(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) speed = max(speed, g2p_warp(c, w, threadIdx.x & 31));
    report_max_speed(c, speed);
}

// G2P of the particle of `lane` in warp-list entry w; returns its speed (float bits; 0 if none).
__device__ __forceinline__ unsigned g2p_warp(const Ctx& c, unsigned w, unsigned lane) {
    unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
    if (lane >= count) return 0;
    unsigned p = first + lane;
    vec3 x = load_v3(c.state, c.cap, F_X, p);
    G2pState st = g2p_load_state(c, p);
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
    B = (B - outer(v, make_v3(fx[0], fx[1], fx[2]))) * c.dx;
    real dt = step_params(c).dt;
    mat3 C = B * ((real)4 * c.inv_dx * c.inv_dx);
    return g2p_finish(c, bc, p, st, x + v * dt, v, C);
}

// The end of every G2P: F = (I + dt C) F, plasticity, health check (before the clamp, which
// would hide NaN), max speed, domain clamp, free-zone check, stores. `x` is the advected position,
// `C` the velocity gradient (APIC's C for MLS). Returns the speed (float bits, 0 if not finite).
__device__ __forceinline__ unsigned g2p_finish(const Ctx& c, const int* bc, unsigned p, G2pState st, vec3 x, vec3 v, const mat3& C) {
    real dt = step_params(c).dt;
    mat3 F = (mat3_identity() + C * dt) * st.F;
    real plastic = st.plastic;
    GpuMaterial mat = material_at(c, st.material);
    F = material_project(mat, F, &plastic);
    // Health check before the clamp (the clamp would hide NaN).
    unsigned id = st.id;
    real speed = length(v);
    bool finite = isfinite(x.x) && isfinite(x.y) && isfinite(x.z) && isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
    if (!finite || speed * dt > (real)2 * c.dx) {
        unsigned prev = atomicMin(&c.ctl[CTL_BAD_INDEX], id);
        if (prev > id) atomicExch(&c.ctl[CTL_BAD_REASON], finite ? 2u : 1u);
    }
    x.x = fmin(fmax(x.x, (real)c.domain_min[0]), (real)c.domain_max[0]);
    x.y = fmin(fmax(x.y, (real)c.domain_min[1]), (real)c.domain_max[1]);
    x.z = fmin(fmax(x.z, (real)c.domain_min[2]), (real)c.domain_max[2]);
    // Free zone: the 3x3x3 neighbourhood of gblock B covers the stencil iff base in [4B-4, 4B+5].
    int nb[3]; real nfx[3];
    stencil_of(c, x, nb, nfx);
    bool leave = !finite;
    for (int a = 0; a < 3; ++a) leave = leave || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
    if (leave) c.ctl[CTL_NEED_REBUILD] = 1;
    store_v3(c.state, c.cap, F_X, p, x);
    store_v3(c.state, c.cap, F_V, p, v);
    store_m3(c.state, c.cap, F_C, p, C);
    store_m3(c.state, c.cap, F_F, p, F);
    c.state[F_PLASTIC * c.cap + p] = plastic;
    return finite ? __float_as_uint((float)speed) : 0u;
}

// Interpolation of the classic MPM transfers at one particle (cpu/g2p.rs: g2p_mpm): v_pic =
// sum w v_i, the FLIP increment dv = sum w (v_i - v_old_i) (USL: grid_aux = v_old) and the
// velocity gradient L = sum v_i (x) grad w (MUSL: of the re-mapped velocities in grid_aux).
__device__ __forceinline__ void g2p_mpm_gather(const Ctx& c, unsigned g, vec3 x, const int** bc_out,
                                               vec3* v_pic, vec3* dv, mat3* L, bool musl_gradient) {
    int base[3]; real fx[3]; real wt[3][3]; real dw[3][3];
    particle_stencil(c, x, base, fx, wt, dw);
    const int* bc = c.block_coords + 3 * g;
    *bc_out = bc;
    const unsigned* nbs = c.neighbors + 27 * g;
    StencilIdx si = stencil_idx(bc, base);
    *v_pic = make_v3(0, 0, 0);
    *dv = make_v3(0, 0, 0);
    *L = mat3_zero();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) {
                unsigned node = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]] * 64u
                    + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
                const real* n = c.grid + 4u * node;
                const real* a = c.grid_aux + 4u * node;
                vec3 vi = make_v3(n[1], n[2], n[3]);
                vec3 ai = make_v3(a[1], a[2], a[3]);
                real weight = wt[0][i] * wt[1][j] * wt[2][k];
                vec3 grad = shape_grad(wt, dw, i, j, k) * c.inv_dx;
                *v_pic = *v_pic + vi * weight;
                if (musl_gradient) {
                    *L = *L + outer(ai, grad);
                } else {
                    *dv = *dv + (vi - ai) * weight;
                    *L = *L + outer(vi, grad);
                }
            }
}

// G2P of the classic MPM transfers: USL (PIC/FLIP blend here, L from the updated grid) or the
// final MUSL pass (v already blended by g2p_mpm_velocity, L from the re-mapped grid). Positions
// move with v_pic; L is kept in the particle's C.
extern "C" __global__ void g2p_mpm(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    bool musl = c.update == UPDATE_MUSL;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        vec3 x = load_v3(c.state, c.cap, F_X, p);
        vec3 v = load_v3(c.state, c.cap, F_V, p);
        G2pState st = g2p_load_state(c, p);
        const int* bc; vec3 v_pic, dv; mat3 L;
        g2p_mpm_gather(c, g, x, &bc, &v_pic, &dv, &L, musl);
        if (!musl) v = flip_blend((real)c.flip, v, v_pic, dv);
        speed = max(speed, g2p_finish(c, bc, p, st, x + v_pic * (real)step_params(c).dt, v, L));
    }
    report_max_speed(c, speed);
}

// MUSL, first pass (cpu/g2p.rs: g2p_mpm_velocity): the PIC/FLIP blend of the particle velocities
// only; positions and F wait for the re-map.
extern "C" __global__ void g2p_mpm_velocity(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        vec3 x = load_v3(c.state, c.cap, F_X, p);
        vec3 v = load_v3(c.state, c.cap, F_V, p);
        const int* bc; vec3 v_pic, dv; mat3 L;
        g2p_mpm_gather(c, g, x, &bc, &v_pic, &dv, &L, false);
        store_v3(c.state, c.cap, F_V, p, flip_blend((real)c.flip, v, v_pic, dv));
    }
}
