// FixedCorotated (Stomakhin et al. 2012): port of crates/rtmpm-core/src/material/fixed_corotated.rs.
#pragma once
#include "../svd.cuh"

// Host mirror (#[repr(C)]): { f32 mu; f32 lambda; } (8 bytes).
struct FixedCorotatedParams {
    real mu;
    real lambda;
};

// tau = 2 mu (F - R) F^T + lambda (J - 1) J I (Stomakhin et al. 2012), given R and J = det F.
__device__ __forceinline__ mat3 fixed_corotated_kirchhoff_rj(const mat3& f, const mat3& r, real j, real mu, real lambda) {
    return (f - r) * transpose(f) * ((real)2 * mu) + mat3_diag(make_v3s(lambda * (j - (real)1) * j));
}

// The same with R from the polar decomposition of F.
__device__ __forceinline__ mat3 fixed_corotated_kirchhoff_lame(const mat3& f, real mu, real lambda) {
    mat3 r, s;
    polar(f, r, s);
    return fixed_corotated_kirchhoff_rj(f, r, determinant(f), mu, lambda);
}

__device__ __forceinline__ mat3 fixed_corotated_kirchhoff(const FixedCorotatedParams& p, const mat3& f) {
    return fixed_corotated_kirchhoff_lame(f, p.mu, p.lambda);
}
