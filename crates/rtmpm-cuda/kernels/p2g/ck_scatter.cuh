// CK-MPM's P2G (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025;
// cpu/p2g.rs: p2g_ck), its per-particle terms and its warp scatter. Each of the two staggered
// grids (grid 0 in c.grid, grid 1 in c.grid_aux) receives the particle's full mass w_ip m_p and
// MLS-MPM momentum w_ip (m_p v_p + A_p (x_i - x_p)) through its 2x2x2 compact-kernel stencil,
// A_p = m_p C_p - dt V0_p tau_p D_p^-1 with the particle's own D_p (ck.cuh).
//
// The warp scatter brings the machinery of the MLS-MPM scatter (warp.cuh; Fei, Huang & Gao,
// "Real-Time Simulation of MPM on Modern GPUs", GTC 2022) to the two grids: per grid, the warp's
// particles are sorted in the warp by the first node of their 2x2x2 stencil on that grid (the
// in-warp sort of mixed sorting; the two grids' first nodes differ, so each grid has its own
// order), lanes with the same first node are summed with segmented shuffles (Gao et al. 2018) and
// one lane per segment adds the eight summed nodes with global atomics.
#pragma once
#include "warp.cuh"
#include "../ck.cuh"

// The grid of node values of CK-MPM grid g.
__device__ __forceinline__ real* ck_nodes(const Ctx& c, int g) { return g == 0 ? c.grid : c.grid_aux; }

// What a particle gives both grids: its mass, its momentum m_p v_p and the affine term dx A_p
// (A_p applied to x_i - x_p = dx dpos, dpos in cells).
struct CkP2gTerms {
    real m;
    vec3 mv;
    mat3 affine_dx;
};

// The terms of a particle from its state (the stress evaluated here) and its two stencils: from
// memory in the P2G kernels, from registers in a fused G2P2G.
__device__ __forceinline__ CkP2gTerms ck_p2g_terms_of(const Ctx& c, const CkGrid s[2], real m, real vol0, vec3 v, const mat3& C,
                                                      const mat3& F, real plastic, unsigned material) {
    const MaterialGpu& mat = material_at(c, material);
    mat3 tau = material_kirchhoff(mat, F, plastic, C);
    // A_p = m C - dt V0 tau D_p^-1 (D_p^-1 in world units: cells^-2 / dx^2).
    const Scalars& sc = scalars(c);
    mat3 inv_d = ck_inv_moment(s) * (sc.inv_dx * sc.inv_dx);
    CkP2gTerms t;
    t.m = m;
    t.mv = v * m;
    t.affine_dx = (tau * inv_d * (-step_params(c).dt * vol0) + C * m) * sc.dx;
    return t;
}

// The same for particle p of the state array.
__device__ __forceinline__ CkP2gTerms ck_p2g_terms(const Ctx& c, unsigned p, const CkGrid s[2]) {
    return ck_p2g_terms_of(c, s, c.state[sidx(c.cap, F_MASS, p)], c.state[sidx(c.cap, F_VOL0, p)], load_vel(c.state, c.cap, p),
                           load_affine(c.state, c.cap, p), load_deformation(c.state, c.cap, p, false),
                           load_plastic(c.state, c.cap, p), state_bits(c.state[sidx(c.cap, F_MAT, p)]));
}

// A particle's contribution to one grid, in the form of the MLS-MPM scatter (P2gParticle): the
// first node `base` of its 2x2x2 stencil (index of the B-spline grid's node), the weights
// w[axis][0 or 1], the mass, and the momentum term of node base + (i, j, k):
// m v + A_p (x_i - x_p) = q0 + i a[0] + j a[1] + k a[2], a[c] = dx A_p e_c, q0 = m v - dx A_p d
// (d: the particle's distance from the first node, cells).
struct CkScatter {
    int base[3];
    real w[3][2];
    real m;
    vec3 q0;
    vec3 a[3];
};

// Grid g's part of a particle at stencil base `base` (the B-spline grid's) with terms t.
__device__ __forceinline__ CkScatter ck_scatter_of(const int base[3], const CkGrid& s, const CkP2gTerms& t) {
    CkScatter q;
    for (int a = 0; a < 3; ++a) {
        q.base[a] = base[a] + s.offset[a];
        q.w[a][0] = s.w[a][0];
        q.w[a][1] = s.w[a][1];
        q.a[a] = make_v3(t.affine_dx.m[3 * a], t.affine_dx.m[3 * a + 1], t.affine_dx.m[3 * a + 2]);
    }
    q.m = t.m;
    q.q0 = t.mv - t.affine_dx * make_v3(s.d[0], s.d[1], s.d[2]);
    return q;
}

// A particle that contributes nothing (inactive lanes of the warp scatter).
__device__ __forceinline__ CkScatter ck_scatter_zero() {
    CkScatter q;
    for (int a = 0; a < 3; ++a) {
        q.base[a] = 0;
        q.w[a][0] = q.w[a][1] = 0;
        q.a[a] = make_v3(0, 0, 0);
    }
    q.m = 0;
    q.q0 = make_v3(0, 0, 0);
    return q;
}

// Contribution q of lane `src` (a warp-wide permutation: every lane of the warp calls it).
__device__ __forceinline__ CkScatter ck_scatter_from_lane(const CkScatter& q, unsigned src) {
    CkScatter r;
    const unsigned all = 0xffffffffu;
    for (int a = 0; a < 3; ++a) {
        r.base[a] = __shfl_sync(all, q.base[a], src);
        r.w[a][0] = __shfl_sync(all, q.w[a][0], src);
        r.w[a][1] = __shfl_sync(all, q.w[a][1], src);
        r.a[a] = make_v3(__shfl_sync(all, q.a[a].x, src), __shfl_sync(all, q.a[a].y, src), __shfl_sync(all, q.a[a].z, src));
    }
    r.m = __shfl_sync(all, q.m, src);
    r.q0 = make_v3(__shfl_sync(all, q.q0.x, src), __shfl_sync(all, q.q0.y, src), __shfl_sync(all, q.q0.z, src));
    return r;
}

// The scatter of one warp's contributions to one grid (one per lane, in sorted order; q of an
// inactive lane is ck_scatter_zero): per plane i of the 2x2x2 stencil, its four nodes' 16 values
// summed over each segment by shuffles (rounds up to the warp's longest segment, at most
// 2^RTMPM_P2G_ROUNDS_MAX lanes, as in warp.cuh), then added by the segment heads. Every lane of the
// warp calls it.
__device__ __forceinline__ void ck_scatter_warp(const Ctx& c, unsigned g, const CkScatter& q, bool active, unsigned lane,
                                                real* grid) {
    WarpSegments seg = warp_segments(c, q.base, active, lane);
    StencilIdx si = stencil_idx(c.block_coords + 3 * g, q.base);
    const unsigned* nbs = c.neighbors + 27 * g;
#pragma unroll
    for (int i = 0; i < 2; ++i) {
        real val[4][4];
        vec3 mom_i = q.q0 + q.a[0] * (real)i;
#pragma unroll
        for (int n = 0; n < 4; ++n) {
            int j = n >> 1, k = n & 1;
            real weight = q.w[0][i] * q.w[1][j] * q.w[2][k];
            vec3 mom = (mom_i + q.a[1] * (real)j + q.a[2] * (real)k) * weight;
            val[n][0] = weight * q.m;
            val[n][1] = mom.x;
            val[n][2] = mom.y;
            val[n][3] = mom.z;
        }
#pragma unroll
        for (unsigned s = 1; s < (1u << RTMPM_P2G_ROUNDS_MAX); s <<= 1) {
            if (s > seg.max_seg) break;
            bool take = s <= seg.seg_len;
#pragma unroll
            for (int n = 0; n < 4; ++n)
#pragma unroll
                for (int e = 0; e < 4; ++e) {
                    real o = __shfl_down_sync(0xffffffffu, val[n][e], s);
                    if (take) val[n][e] += o;
                }
        }
        if (seg.head) {
#pragma unroll
            for (int n = 0; n < 4; ++n) atomic_add_node(grid + 4u * stencil_node(si, nbs, i, n >> 1, n & 1), val[n]);
        }
    }
}

// The warp's contributions to one grid (q: this lane's particle's, in the warp list's order; q
// of an inactive lane is ck_scatter_zero): sorted in the warp by their first node (mixed
// sorting's cheap part, skipped when already in order or with mixed_sort=off), then
// ck_scatter_warp. Every lane of the warp calls it.
__device__ __forceinline__ void ck_scatter_sorted(const Ctx& c, unsigned g, const CkScatter& q, bool active, unsigned lane,
                                                  real* grid) {
    CkScatter r = q;
    if (c.warp_sort) {
        unsigned src = p2g_warp_sort(active ? p2g_sort_key(c, g, q.base) : P2G_KEY_NONE, lane, &active);
        if (__any_sync(0xffffffffu, src != lane)) r = ck_scatter_from_lane(q, src);
    }
    ck_scatter_warp(c, g, r, active, lane, grid);
}
