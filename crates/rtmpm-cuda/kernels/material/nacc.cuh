// Non-associated Cam-clay (Wolper et al. 2019, CD-MPM): port of crates/rtmpm-physics/src/material/nacc.rs.
// The plastic scalar is alpha, the log plastic volume change; p0 = kappa sinh(xi max(-alpha, 0)).
#pragma once
#include "hencky.cuh"

__device__ __forceinline__ mat3 nacc_kirchhoff(const NaccParams& p, const mat3& f, real alpha, const mat3& c) {
    (void)alpha;
    (void)c;
    return hencky_kirchhoff(f, p.mu, p.lambda);
}

// Beyond a tip to the tip (alpha takes the plastic volume change), else q down to the ellipse
// (1 + 2 beta) q^2 + M^2 (p + beta p0)(p - p0) = 0 at the same p.
__device__ __forceinline__ mat3 nacc_project(const NaccParams& p, const mat3& f_trial, real* alpha, real dt) {
    (void)dt;
    return hencky_return_map(f_trial, alpha, [&](vec3 eps, real a, vec3* e, real* a1) {
        real kappa = p.lambda + (real)2 / (real)3 * p.mu;
        real tr = sum(eps);
        vec3 e_hat = eps - make_v3s(tr / (real)3);
        real pr = -kappa * tr;
        real q = sqrt((real)1.5) * (real)2 * p.mu * length(e_hat);
        real p0 = kappa * sinh(p.xi * fmax(-a, (real)0));
        real p_tip = pr > p0 ? p0 : (pr < -p.beta * p0 ? -p.beta * p0 : pr);
        if (p_tip != pr) {
            real tr_new = -p_tip / kappa;
            *e = make_v3s(tr_new / (real)3);
            *a1 = a + tr - tr_new;
            return true;
        }
        real m2 = p.m * p.m;
        real y = ((real)1 + (real)2 * p.beta) * q * q + m2 * (pr + p.beta * p0) * (pr - p0);
        if (y <= (real)0) return false;
        real q_new = sqrt(fmax(-m2 * (pr + p.beta * p0) * (pr - p0) / ((real)1 + (real)2 * p.beta), (real)0));
        real scale = q > (real)0 ? q_new / q : (real)0;
        *e = e_hat * scale + make_v3s(tr / (real)3);
        *a1 = a;
        return true;
    });
}
