// Snow (Stomakhin et al. 2013): port of crates/rtmpm-physics/src/material/snow.rs.
#pragma once
#include "fixed_corotated.cuh"

#define SNOW_MAX_HARDENING_EXPONENT ((real)3)  // xi (1 - Jp) clamped to [-10, 3]
#define SNOW_MAX_SOFTENING_EXPONENT ((real)10)
#define SNOW_JP_MIN ((real)1e-3)
#define SNOW_JP_MAX ((real)1e3)

// exp(clamp(xi (1 - Jp), -S, M)) (Stomakhin 2013 eq. 8)
__device__ __forceinline__ real snow_hardening_factor(const SnowParams& p, real jp) {
    real e = fmin(fmax(p.hardening * ((real)1 - jp), -SNOW_MAX_SOFTENING_EXPONENT), SNOW_MAX_HARDENING_EXPONENT);
    return exp(e);
}

__device__ __forceinline__ mat3 snow_kirchhoff(const SnowParams& p, const mat3& f, real jp, const mat3& c) {
    (void)c;
    real h = snow_hardening_factor(p, jp);
    return fixed_corotated_kirchhoff_lame(f, p.mu * h, p.lambda * h);
}

// Clamp singular values into [1 - theta_c, 1 + theta_s]; Jp *= J_e_trial / J_e_new, clamped.
__device__ __forceinline__ mat3 snow_project(const SnowParams& p, const mat3& f_trial, real* jp, real dt) {
    (void)dt;
    mat3 u, v;
    vec3 s;
    svd3(f_trial, u, s, v);
    real lo = (real)1 - p.critical_compression;
    real hi = (real)1 + p.critical_stretch;
    vec3 sc = make_v3(fmin(fmax(s.x, lo), hi), fmin(fmax(s.y, lo), hi), fmin(fmax(s.z, lo), hi));
    real ratio = (s.x * s.y * s.z) / (sc.x * sc.y * sc.z);
    *jp = fmin(fmax(*jp * ratio, SNOW_JP_MIN), SNOW_JP_MAX);
    return mul_diag_bt(u, sc, v);
}
