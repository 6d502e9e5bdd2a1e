// CK-MPM's compact kernel on two staggered grids (Liu, Wang & Li, "CK-MPM: A Compact-Kernel
// Material Point Method", ACM TOG 2025): the mirror of rtmpm_physics::compact_kernel, formula by
// formula (the math is documented there). Grid 0 has its nodes a quarter cell below the B-spline
// grid's, grid 1 a quarter cell above; node n of either grid is stored at the index of the
// B-spline grid's node n (grid 0 in Ctx::grid, grid 1 in Ctx::grid_aux, the same block layout), so
// a particle's two 2x2x2 stencils lie inside its 3x3x3 B-spline stencil (base, fx of stencil_of).
#pragma once
#include "math.cuh"

// Occupancy bound of CK-MPM's warp-scatter kernels (g2p2g_ck, p2g_ck_warp), set by the CUDA option
// ck_bound=N (-DCK_MIN_BLOCKS=N): N resident blocks of 128 threads a SM, at most 65536 / (128 N)
// registers a thread; ck_bound=0: ptxas's own choice (128 registers for g2p2g_ck). Left out (the
// default): the fused g2p2g_ck, CK-MPM's default kernel, held to 5 blocks in f32 (measured on an
// H200 with its resident grid: -4.9 % on the fluid dam 2M, -2.6 % on the jelly drop 2M;
// bench/RESULTS.md), ptxas's choice in f64 (not timed there) and for p2g_ck_warp.
#if defined(CK_MIN_BLOCKS) && CK_MIN_BLOCKS > 0
#define CK_BOUNDS 128, CK_MIN_BLOCKS
#define CK_FUSED_BOUNDS 128, CK_MIN_BLOCKS
#elif defined(CK_MIN_BLOCKS) || defined(RTMPM_F64)
#define CK_BOUNDS 128
#define CK_FUSED_BOUNDS 128
#else
#define CK_BOUNDS 128
#define CK_FUSED_BOUNDS 128, 5
#endif

// Offset of grid g's nodes from the B-spline grid's, in cells (compact_kernel.rs: GRID_SHIFT).
__device__ __forceinline__ real ck_shift(int g) { return g == 0 ? (real)-0.25 : (real)0.25; }

// The 1D weight of a node at distance r (cells): 1 - |r| + sin(2 pi |r|) / (2 pi) for |r| < 1,
// else 0 (compact_kernel.rs: ck_1d).
__device__ __forceinline__ real ck_1d(real r) {
    real a = fabs(r);
    if (a >= (real)1) return 0;
    const real tau = (real)6.283185307179586;
    return (real)1 - a + sin(tau * a) / tau;
}

// One grid's 2x2x2 stencil of a particle (compact_kernel.rs: CkGrid): per axis, the first node's
// index in the 3x3x3 B-spline stencil (0 or 1), the two weights and the particle's distance from
// the first node (cells, [0, 1]).
struct CkGrid {
    int offset[3];
    real w[3][2];
    real d[3];
};

// Weight of node (i, j, k) (each 0 or 1) of the stencil.
__device__ __forceinline__ real ck_weight(const CkGrid& s, int i, int j, int k) { return s.w[0][i] * s.w[1][j] * s.w[2][k]; }

// Node position minus particle position, in cells.
__device__ __forceinline__ vec3 ck_dpos(const CkGrid& s, int i, int j, int k) {
    return make_v3((real)i - s.d[0], (real)j - s.d[1], (real)k - s.d[2]);
}

// Grid g's stencil of a particle at fx = xg - base (cells, [0.5, 1.5) per axis; CkStencil::new).
__device__ __forceinline__ CkGrid ck_grid(const real fx[3], int g) {
    CkGrid s;
    for (int a = 0; a < 3; ++a) {
        real r = fx[a] - ck_shift(g);
        int o = r >= (real)1 ? 1 : 0;
        real d = fmin(fmax(r - (real)o, (real)0), (real)1);
        real w0 = ck_1d(d);
        s.offset[a] = o;
        s.w[a][0] = w0;
        s.w[a][1] = (real)1 - w0;
        s.d[a] = d;
    }
    return s;
}

// Second moment sum_i w_ip (x_i - x_p)(x_i - x_p)^T of one grid, in cells^2 (CkGrid::moment).
__device__ __forceinline__ mat3 ck_moment(const CkGrid& s) {
    mat3 m = mat3_zero();
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j)
            for (int k = 0; k < 2; ++k) {
                vec3 r = ck_dpos(s, i, j, k);
                m = m + outer(r, r) * ck_weight(s, i, j, k);
            }
    return m;
}

// D_p^-1 in cells^-2: the inverse of the mean of the two grids' second moments
// (CkStencil::inv_moment; positive definite).
__device__ __forceinline__ mat3 ck_inv_moment(const CkGrid s[2]) {
    return inverse((ck_moment(s[0]) + ck_moment(s[1])) * (real)0.5);
}
