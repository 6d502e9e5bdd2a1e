// Drucker-Prager sand (Klar et al. 2016): port of crates/rtmpm-physics/src/material/drucker_prager.rs.
// alpha: the cone slope, from the model's one formula on the host (DruckerPrager::alpha).
#pragma once
#include "hencky.cuh"

__device__ __forceinline__ mat3 drucker_prager_kirchhoff(const DruckerPragerParams& p, const mat3& f, real plastic,
                                                         const mat3& c) {
    (void)plastic;
    (void)c;
    return hencky_kirchhoff(f, p.mu, p.lambda);
}

// Return mapping on the principal log strain (Klar 2016 alg. 2), tip shifted by the cohesion.
// Returns the projected strain; *dq = plastic multiplier (0 = elastic).
__device__ __forceinline__ vec3 drucker_prager_project_strain(const DruckerPragerParams& p, vec3 eps, real* dq) {
    vec3 c = make_v3s(p.cohesion);
    vec3 e = eps - c;
    real tr = sum(e);
    vec3 e_hat = e - make_v3s(tr / (real)3);
    real e_hat_norm = length(e_hat);
    real dg = e_hat_norm + ((real)3 * p.lambda + (real)2 * p.mu) / ((real)2 * p.mu) * tr * p.alpha;
    if (dg <= (real)0) {  // case I: inside the cone
        *dq = 0;
        return eps;
    } else if (e_hat_norm <= (real)0 || tr > (real)0) {  // case II: to the (shifted) tip
        *dq = length(e);
        return c;
    }
    *dq = dg;  // case III: along the deviatoric direction onto the cone
    return e - e_hat * (dg / e_hat_norm) + c;
}

__device__ __forceinline__ mat3 drucker_prager_project(const DruckerPragerParams& p, const mat3& f_trial, real* q, real dt) {
    (void)dt;
    return hencky_return_map(f_trial, q, [&](vec3 eps, real q0, vec3* e, real* q1) {
        real dq;
        *e = drucker_prager_project_strain(p, eps, &dq);
        *q1 = q0 + dq;
        return dq > (real)0;
    });
}
