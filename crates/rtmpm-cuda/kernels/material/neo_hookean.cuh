// Compressible NeoHookean: port of crates/rtmpm-physics/src/material/neo_hookean.rs.
#pragma once
#include "../math.cuh"

#define NEO_HOOKEAN_J_MIN ((real)1e-4)  // J clamp in ln(J) (finite, repulsive when inverted)

// tau = mu (F F^T - I) + lambda ln(J) I (Bonet & Wood eq. 6.28 times J)
__device__ __forceinline__ mat3 neo_hookean_kirchhoff(const NeoHookeanParams& p, const mat3& f, real plastic, const mat3& c) {
    (void)plastic;
    (void)c;
    real j = fmax(determinant(f), NEO_HOOKEAN_J_MIN);
    return (f * transpose(f) - mat3_identity()) * p.mu + mat3_diag(make_v3s(p.lambda * log(j)));
}

// Elastic: F stays the trial F.
__device__ __forceinline__ mat3 neo_hookean_project(const NeoHookeanParams& p, const mat3& f_trial, real* plastic, real dt) {
    (void)dt;
    (void)p;
    (void)plastic;
    return f_trial;
}
