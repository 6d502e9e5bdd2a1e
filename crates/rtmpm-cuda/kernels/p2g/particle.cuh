// The per-particle quantities of P2G, from ONE function for every P2G strategy: the scatter
// kernels of p2g.cu and the gathers of p2g_reverse_map.cu and p2g_sort.cu (Chiang et al., "GPU Acceleration of the Generalized Interpolation Material Point Method" (SAAHPC 2009)). A change of
// the shape function (weights at the 3x3x3 stencil) or of the stress term is made here once.
//
// MLS-MPM (Hu et al. 2018, eq. 16/29): node i of the stencil receives
//   m_i += w_ip m_p,   (m v)_i += w_ip (m_p v_p + A_p (x_i - x_p)),
//   A_p = -dt V0 (4 / dx^2) tau_p + m_p C_p   (tau: Kirchhoff stress of the material).
#pragma once
#include "../common.cuh"
#include "../material/dispatch.cuh"

struct P2gParticle {
    int base[3];   // stencil base node (grid coordinates)
    real w[3][3];  // shape-function weights per axis at base + 0, 1, 2
    real m;        // mass
    // Momentum term of node base + (i, j, k): m v + A_p (x_i - x_p) = q0 + i a[0] + j a[1] + k a[2]
    // with a[c] = dx A_p e_c and q0 = m v - dx A_p fx (the affine term split per axis, so that a
    // node costs three additions instead of a matrix-vector product).
    vec3 q0;
    vec3 a[3];
};

// A particle that contributes nothing (inactive lanes of the warp scatter).
__device__ __forceinline__ P2gParticle p2g_particle_zero() {
    P2gParticle q;
    for (int a = 0; a < 3; ++a) {
        q.base[a] = 0;
        q.w[a][0] = q.w[a][1] = q.w[a][2] = 0;
        q.a[a] = make_v3(0, 0, 0);
    }
    q.m = 0;
    q.q0 = make_v3(0, 0, 0);
    return q;
}

// Stencil, weights, momentum and affine term of a particle from its state (the stress is
// evaluated here): from memory in p2g_particle, from registers in the fused G2P2G (g2p.cu).
// ALL_FLUID: the material is a fluid (g2p_particle.cuh), its stress is not dispatched.
template <bool ALL_FLUID>
__device__ __forceinline__ P2gParticle p2g_particle_of(const Ctx& c, vec3 x, real m, real vol0, vec3 v, const mat3& C,
                                                       const mat3& F, real plastic, unsigned material) {
    P2gParticle q;
    real fx[3];
    stencil_of(c, x, material_world(material), q.base, fx);
    for (int a = 0; a < 3; ++a) weights_1d(fx[a], q.w[a]);
    q.m = m;
    const MaterialGpu& mat = material_at(c, material);
    mat3 tau = ALL_FLUID ? fluid_kirchhoff(fluid_params(mat), F, plastic, C) : material_kirchhoff(mat, F, plastic, C);
    real dt = step_params(c).dt;
    const Scalars& sc = scalars(c);
    mat3 affine = tau * (-dt * vol0 * (real)4 * sc.inv_dx * sc.inv_dx) + C * m;
    for (int a = 0; a < 3; ++a) q.a[a] = make_v3(affine.m[3 * a], affine.m[3 * a + 1], affine.m[3 * a + 2]) * sc.dx;
    q.q0 = v * m - (q.a[0] * fx[0] + q.a[1] * fx[1] + q.a[2] * fx[2]);
    return q;
}

// The same for particle p of the state array.
__device__ __forceinline__ P2gParticle p2g_particle(const Ctx& c, unsigned p) {
    return p2g_particle_of<false>(c, load_v3(c.state, c.cap, F_X, p), c.state[sidx(c.cap, F_MASS, p)], c.state[sidx(c.cap, F_VOL0, p)],
                                  load_vel(c.state, c.cap, p), load_affine(c.state, c.cap, p),
                                  load_deformation(c.state, c.cap, p, false), load_plastic(c.state, c.cap, p),
                                  state_bits(c.state[sidx(c.cap, F_MAT, p)]));
}

// Particle q of lane `src` (a warp-wide permutation: every lane of the warp calls it).
__device__ __forceinline__ P2gParticle p2g_particle_from_lane(const P2gParticle& q, unsigned src) {
    P2gParticle r;
    const unsigned all = 0xffffffffu;
    for (int a = 0; a < 3; ++a) {
        r.base[a] = __shfl_sync(all, q.base[a], src);
        for (int n = 0; n < 3; ++n) r.w[a][n] = __shfl_sync(all, q.w[a][n], src);
        r.a[a] = make_v3(__shfl_sync(all, q.a[a].x, src), __shfl_sync(all, q.a[a].y, src), __shfl_sync(all, q.a[a].z, src));
    }
    r.m = __shfl_sync(all, q.m, src);
    r.q0 = make_v3(__shfl_sync(all, q.q0.x, src), __shfl_sync(all, q.q0.y, src), __shfl_sync(all, q.q0.z, src));
    return r;
}

// a[i] for i in 0..3 by selects (a dynamic index would move the whole particle to local memory).
__device__ __forceinline__ real pick3(const real a[3], int i) { return i == 0 ? a[0] : (i == 1 ? a[1] : a[2]); }

// RTMPM_P2G_ZERO_TERMS (compile-time, default 0; the CUDA option `zero_terms=skip`): the terms
// a[c] * 0 of node 0 along an axis left out instead of added (x + a * 0 is x for a finite a, but
// the compiler may not drop it: three FFMA with a zero operand a row). The same sums except where
// the momentum term is a zero of the other sign or a is not finite.
#ifndef RTMPM_P2G_ZERO_TERMS
#define RTMPM_P2G_ZERO_TERMS 0
#endif
// Weight product w0[i] w1[j] and momentum term q0 + i a0 + j a1 of the stencil row (i, j).
__device__ __forceinline__ real p2g_row_weight(const P2gParticle& q, int i, int j) { return pick3(q.w[0], i) * pick3(q.w[1], j); }
__device__ __forceinline__ vec3 p2g_row_momentum(const P2gParticle& q, int i, int j) {
#if RTMPM_P2G_ZERO_TERMS && RTMPM_P2G_UNROLL == 1
    // The warp scatter's rows unrolled (RTMPM_P2G_UNROLL, p2g/warp.cuh): i and j are
    // compile-time there, so the zero terms fold away; in a row loop they stay (selects).
    if (i == 0 || j == 0) {
        if (i == 0 && j == 0) return q.q0;
        return i == 0 ? q.q0 + q.a[1] * (real)j : q.q0 + q.a[0] * (real)i;
    }
#elif RTMPM_P2G_ZERO_TERMS && RTMPM_P2G_UNROLL == 2
    if (j == 0) return q.q0 + q.a[0] * (real)i;
#endif
    return q.q0 + q.a[0] * (real)i + q.a[1] * (real)j;
}

// (mass, momentum) that particle q gives to node base + (i, j, k), from the row terms of (i, j):
// w_ip (m_p, m_p v_p + A_p (x_i - x_p)).
__device__ __forceinline__ void p2g_row_node_value(const P2gParticle& q, real w_ij, vec3 mom_ij, int k, real val[4]) {
    real weight = w_ij * pick3(q.w[2], k);
#if RTMPM_P2G_ZERO_TERMS
    vec3 mom = (k == 0 ? mom_ij : mom_ij + q.a[2] * (real)k) * weight;
#else
    vec3 mom = (mom_ij + q.a[2] * (real)k) * weight;
#endif
    val[0] = weight * q.m;
    val[1] = mom.x;
    val[2] = mom.y;
    val[3] = mom.z;
}

// (mass, momentum) that particle q gives to its stencil node base + (i, j, k).
__device__ __forceinline__ void p2g_node_value(const P2gParticle& q, int i, int j, int k, real val[4]) {
    p2g_row_node_value(q, p2g_row_weight(q, i, j), p2g_row_momentum(q, i, j), k, val);
}

// ---- Gather strategies (Chiang et al.): the particle pass computes every (particle, stencil node)
// value with p2g_node_value and stores it at entry (i * 9 + j * 3 + k) * cap + p of an array of
// 4 reals per entry (slot-major: the lanes of a warp store consecutive entries); the maps name
// entries, and the gather of a node sums its entries.
__device__ __forceinline__ unsigned p2g_entry(const Ctx& c, unsigned p, int i, int j, int k) {
    return (unsigned)(i * 9 + j * 3 + k) * c.cap + p;
}

__device__ __forceinline__ void p2g_store_entry(real* contrib, unsigned entry, const real val[4]) {
#ifdef RTMPM_F64
    for (int e = 0; e < 4; ++e) contrib[4u * entry + e] = val[e];
#else
    reinterpret_cast<float4*>(contrib)[entry] = make_float4(val[0], val[1], val[2], val[3]);
#endif
}

// acc += the value of entry `entry`.
__device__ __forceinline__ void p2g_add_entry(const real* __restrict__ contrib, unsigned entry, real acc[4]) {
#ifdef RTMPM_F64
    for (int e = 0; e < 4; ++e) acc[e] += __ldg(contrib + 4u * entry + e);
#else
    float4 v = __ldg(reinterpret_cast<const float4*>(contrib) + entry);
    acc[0] += v.x; acc[1] += v.y; acc[2] += v.z; acc[3] += v.w;
#endif
}

// Store the gathered node (plain stores: one thread owns the node).
__device__ __forceinline__ void p2g_store_node(const Ctx& c, unsigned node, const real acc[4]) {
#ifdef RTMPM_F64
    for (int e = 0; e < 4; ++e) c.grid[4u * node + e] = acc[e];
#else
    reinterpret_cast<float4*>(c.grid)[node] = make_float4(acc[0], acc[1], acc[2], acc[3]);
#endif
}

// Memory index (pblock id * 64 + cell) of stencil node (i, j, k) of a particle of the gblock whose
// neighbour list is nbs (the addressing of every P2G strategy).
__device__ __forceinline__ unsigned stencil_node(const StencilIdx& si, const unsigned* nbs, int i, int j, int k) {
    return nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]] * 64u + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
}
