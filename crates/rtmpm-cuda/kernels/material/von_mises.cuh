// von Mises (J2) with Hencky strain, radial return (Simo & Hughes box 3.1): port of
// crates/rtmpm-physics/src/material/von_mises.rs. Plastic scalar: equivalent plastic strain.
#pragma once
#include "hencky.cuh"

__device__ __forceinline__ mat3 von_mises_kirchhoff(const VonMisesParams& p, const mat3& f, real plastic, const mat3& c) {
    (void)plastic;
    (void)c;
    return hencky_kirchhoff(f, p.mu, p.lambda);
}

// sqrt(2/3) (sigma_y + H eps_p)
__device__ __forceinline__ real von_mises_yield_radius(const VonMisesParams& p, real eps_p) {
    return sqrt((real)2 / (real)3) * (p.yield_stress + p.hardening * eps_p);
}

// Returns the projected principal log strain; *dp = increment of eps_p (0 = elastic).
__device__ __forceinline__ vec3 von_mises_project_strain(const VonMisesParams& p, vec3 eps, real eps_p, real* dp) {
    real tr = sum(eps);
    vec3 e_hat = eps - make_v3s(tr / (real)3);
    real norm = length(e_hat);
    real f = (real)2 * p.mu * norm - von_mises_yield_radius(p, eps_p);
    if (f <= (real)0 || norm <= (real)0) {
        *dp = 0;
        return eps;
    }
    real dg = f / ((real)2 * p.mu + (real)2 * p.hardening / (real)3);
    *dp = sqrt((real)2 / (real)3) * dg;
    return eps - e_hat * (dg / norm);
}

__device__ __forceinline__ mat3 von_mises_project(const VonMisesParams& p, const mat3& f_trial, real* eps_p, real dt) {
    (void)dt;
    return hencky_return_map(f_trial, eps_p, [&](vec3 eps, real ep, vec3* e, real* ep1) {
        real dp;
        *e = von_mises_project_strain(p, eps, ep, &dp);
        *ep1 = ep + dp;
        return dp > (real)0;
    });
}
