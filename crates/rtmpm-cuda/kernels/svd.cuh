// 3x3 SVD and polar decomposition: line-for-line port of crates/rtmpm-physics/src/svd.rs.
// 1. one-sided (Hestenes) Jacobi on the columns of B = A V (at most SVD_MAX_SWEEPS cyclic sweeps,
//    early exit after a sweep without rotation), 2. sort columns by decreasing norm (swap + negate
//    to keep det V = +1), 3. Givens QR of B (McAdams et al. 2011): U = Q, sigma = diag(R), the sign
//    of det A carried by sigma.z.
#pragma once
#include "math.cuh"

#define SVD_MAX_SWEEPS 8

#ifdef RTMPM_F64
#define SVD_EPS 2.220446049250313e-16
#else
#define SVD_EPS 1.1920929e-07f
#endif

// b[c][r]: column c, row r.
__device__ __forceinline__ bool svd_jacobi_pair(real b[3][3], real v[3][3], int p, int q) {
    real alpha = b[p][0] * b[p][0] + b[p][1] * b[p][1] + b[p][2] * b[p][2];
    real beta = b[q][0] * b[q][0] + b[q][1] * b[q][1] + b[q][2] * b[q][2];
    real gamma = b[p][0] * b[q][0] + b[p][1] * b[q][1] + b[p][2] * b[q][2];
    if (fabs(gamma) <= (real)SVD_EPS * sqrt(alpha) * sqrt(beta)) return false;
    real zeta = (beta - alpha) / ((real)2 * gamma);
    real az = fabs(zeta);
    real root = az > (real)1 ? az * sqrt((real)1 + ((real)1 / az) * ((real)1 / az)) : sqrt((real)1 + az * az);
    real t = (zeta >= (real)0 ? (real)1 : (real)-1) / (az + root);
    real c = (real)1 / sqrt((real)1 + t * t);
    real s = c * t;
#pragma unroll
    for (int r = 0; r < 3; ++r) {
        real bp = b[p][r], bq = b[q][r];
        b[p][r] = c * bp - s * bq;
        b[q][r] = s * bp + c * bq;
        real vp = v[p][r], vq = v[q][r];
        v[p][r] = c * vp - s * vq;
        v[q][r] = s * vp + c * vq;
    }
    return true;
}

__device__ __forceinline__ real svd_col_norm2(const real b[3][3], int c) { return b[c][0] * b[c][0] + b[c][1] * b[c][1] + b[c][2] * b[c][2]; }

// Swap columns p, q of b and v and negate the new column q.
__device__ __forceinline__ void svd_swap_neg(real b[3][3], real v[3][3], int p, int q) {
#pragma unroll
    for (int r = 0; r < 3; ++r) {
        real bp = b[p][r], vp = v[p][r];
        b[p][r] = b[q][r];
        v[p][r] = v[q][r];
        b[q][r] = -bp;
        v[q][r] = -vp;
    }
}

// Givens rotation on rows p, q of r zeroing r[k][q] against r[k][p]; transpose accumulated into u.
__device__ __forceinline__ void svd_givens_qr(real r[3][3], real u[3][3], int p, int q, int k) {
    real a = r[k][p], b = r[k][q];
    real h = sqrt(a * a + b * b);
    if (h <= (real)0) return;
    real c = a / h, s = b / h;
#pragma unroll
    for (int col = 0; col < 3; ++col) {
        real rp = r[col][p], rq = r[col][q];
        r[col][p] = c * rp + s * rq;
        r[col][q] = -s * rp + c * rq;
    }
    r[k][q] = 0;
#pragma unroll
    for (int row = 0; row < 3; ++row) {
        real up = u[p][row], uq = u[q][row];
        u[p][row] = c * up + s * uq;
        u[q][row] = -s * up + c * uq;
    }
}

// a = u diag(sigma) v^T, u and v rotations, |sigma| decreasing, sigma.z < 0 when det(a) < 0.
__device__ __forceinline__ void svd3(const mat3& a, mat3& u_out, vec3& sigma, mat3& v_out) {
    real b[3][3], v[3][3], u[3][3];
#pragma unroll
    for (int c = 0; c < 3; ++c)
#pragma unroll
        for (int r = 0; r < 3; ++r) {
            b[c][r] = a.m[c * 3 + r];
            v[c][r] = u[c][r] = (c == r) ? (real)1 : (real)0;
        }
    for (int sweep = 0; sweep < SVD_MAX_SWEEPS; ++sweep) {
        bool rotated = svd_jacobi_pair(b, v, 0, 1);
        rotated |= svd_jacobi_pair(b, v, 0, 2);
        rotated |= svd_jacobi_pair(b, v, 1, 2);
        if (!rotated) break;
    }
    if (svd_col_norm2(b, 0) < svd_col_norm2(b, 1)) svd_swap_neg(b, v, 0, 1);
    if (svd_col_norm2(b, 0) < svd_col_norm2(b, 2)) svd_swap_neg(b, v, 0, 2);
    if (svd_col_norm2(b, 1) < svd_col_norm2(b, 2)) svd_swap_neg(b, v, 1, 2);
    svd_givens_qr(b, u, 0, 1, 0);
    svd_givens_qr(b, u, 0, 2, 0);
    svd_givens_qr(b, u, 1, 2, 1);
    sigma = make_v3(b[0][0], b[1][1], b[2][2]);
#pragma unroll
    for (int c = 0; c < 3; ++c)
#pragma unroll
        for (int r = 0; r < 3; ++r) {
            u_out.m[c * 3 + r] = u[c][r];
            v_out.m[c * 3 + r] = v[c][r];
        }
}

// Polar decomposition a = r s, r = u v^T a rotation, s = v diag(sigma) v^T symmetric.
__device__ __forceinline__ void polar(const mat3& a, mat3& r, mat3& s) {
    mat3 u, v;
    vec3 sigma;
    svd3(a, u, sigma, v);
    r = u * transpose(v);
    s = mul_diag_bt(v, sigma, v);
}
