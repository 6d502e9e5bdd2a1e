// Compressible NeoHookean: port of crates/rtmpm-core/src/material/neo_hookean.rs.
#pragma once
#include "../math.cuh"

#define NEO_HOOKEAN_J_MIN ((real)1e-4)  // J clamp in ln(J) (finite, repulsive when inverted)

// Host mirror (#[repr(C)]): { f32 mu; f32 lambda; } (8 bytes).
struct NeoHookeanParams {
    real mu;
    real lambda;
};

// tau = mu (F F^T - I) + lambda ln(J) I (Bonet & Wood eq. 6.28 times J)
__device__ __forceinline__ mat3 neo_hookean_kirchhoff(const NeoHookeanParams& p, const mat3& f) {
    real j = fmax(determinant(f), NEO_HOOKEAN_J_MIN);
    return (f * transpose(f) - mat3_identity()) * p.mu + mat3_diag(make_v3s(p.lambda * log(j)));
}
