// FixedCorotated (Stomakhin et al. 2012): port of crates/rtmpm-physics/src/material/fixed_corotated.rs.
#pragma once
#include "../svd.cuh"

// tau = 2 mu (F - R) F^T + lambda (J - 1) J I, R from the polar decomposition.
__device__ __forceinline__ mat3 fixed_corotated_kirchhoff_lame(const mat3& f, real mu, real lambda) {
    mat3 r, s;
    polar(f, r, s);
    real j = determinant(f);
    return (f - r) * transpose(f) * ((real)2 * mu) + mat3_diag(make_v3s(lambda * (j - (real)1) * j));
}

__device__ __forceinline__ mat3 fixed_corotated_kirchhoff(const FixedCorotatedParams& p, const mat3& f, real plastic,
                                                          const mat3& c) {
    (void)plastic;
    (void)c;
    return fixed_corotated_kirchhoff_lame(f, p.mu, p.lambda);
}

// Elastic: F stays the trial F.
__device__ __forceinline__ mat3 fixed_corotated_project(const FixedCorotatedParams& p, const mat3& f_trial, real* plastic,
                                                        real dt) {
    (void)dt;
    (void)p;
    (void)plastic;
    return f_trial;
}
