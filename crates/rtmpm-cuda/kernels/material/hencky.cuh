// Hencky (logarithmic) strain: the St.Venant-Kirchhoff stress of the log-strain models and the one
// return mapping they share (port of crates/rtmpm-physics/src/material/hencky.rs; Klar et al. 2016,
// "Drucker-Prager elastoplasticity for sand animation", section 7.3).
#pragma once
#include "../svd.cuh"

#define HENCKY_SIGMA_MIN ((real)1e-4)  // singular values clamped before ln

__device__ __forceinline__ vec3 hencky_strain(vec3 s) {
    return make_v3(log(fmax(s.x, HENCKY_SIGMA_MIN)), log(fmax(s.y, HENCKY_SIGMA_MIN)), log(fmax(s.z, HENCKY_SIGMA_MIN)));
}

// 2 mu eps + lambda tr(eps) (Klar 2016 eq. 26 times F^T)
__device__ __forceinline__ vec3 hencky_principal_stress(vec3 eps, real mu, real lambda) {
    return (real)2 * mu * eps + make_v3s(lambda * sum(eps));
}

// tau = U (2 mu eps + lambda tr(eps) I) U^T
__device__ __forceinline__ mat3 hencky_kirchhoff(const mat3& f, real mu, real lambda) {
    mat3 u, v;
    vec3 s;
    svd3(f, u, s, v);
    return mul_diag_bt(u, hencky_principal_stress(hencky_strain(s), mu, lambda), u);
}

__device__ __forceinline__ vec3 exp3(vec3 a) { return make_v3(exp(a.x), exp(a.y), exp(a.z)); }

// The return mapping of a log-strain model: F = U sigma V^T, eps = ln(sigma); rule(eps, plastic,
// &eps_new, &plastic_new) returns false for an elastic step (f_trial is returned unchanged), else
// sets the admissible strain and the new plastic state; the result is U exp(eps_new) V^T.
template <class Rule>
__device__ __forceinline__ mat3 hencky_return_map(const mat3& f_trial, real* plastic, Rule rule) {
    mat3 u, v;
    vec3 s;
    svd3(f_trial, u, s, v);
    vec3 h;
    real p = *plastic;
    if (!rule(hencky_strain(s), *plastic, &h, &p)) return f_trial;
    *plastic = p;
    return mul_diag_bt(u, exp3(h), v);
}
