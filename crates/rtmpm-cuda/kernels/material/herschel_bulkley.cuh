// Herschel-Bulkley viscoplastic fluid: port of crates/rtmpm-physics/src/material/herschel_bulkley.rs
// (the elastic-viscoplastic scheme of Yue et al. 2015 on the principal Hencky strain; the volume
// as a weakly compressible fluid).
#pragma once
#include "fluid.cuh"
#include "hencky.cuh"

#define HB_BISECTION_STEPS 40

// tau = U diag(2 mu dev eps) U^T - J p(J) I
__device__ __forceinline__ mat3 herschel_bulkley_kirchhoff(const HerschelBulkleyParams& p, const mat3& f, real plastic,
                                                           const mat3& c) {
    (void)plastic;
    (void)c;
    mat3 u, v;
    vec3 s;
    svd3(f, u, s, v);
    vec3 eps = hencky_strain(s);
    vec3 e_hat = eps - make_v3s(sum(eps) / (real)3);
    real j = fmax(determinant(f), FLUID_J_MIN);
    real pr = fluid_eos_pressure(p.bulk_modulus, p.tait, p.gamma, j);
    return mul_diag_bt(u, e_hat * ((real)2 * p.shear_modulus), u) - mat3_diag(make_v3s(j * pr));
}

// The root in (tau_y, tau_trial] of tau_trial - tau = mu dt ((tau - tau_y) / K)^(1/n): closed form
// for Bingham (n = 1), tau_y when K = 0, else bisection.
__device__ __forceinline__ real herschel_bulkley_relax(const HerschelBulkleyParams& p, real tau_trial, real dt) {
    real ty = p.yield_stress, k = p.consistency, n = p.flow_index;
    if (k <= (real)0) return ty;
    real a = p.shear_modulus * dt / k;
    if (n == (real)1) return (tau_trial + a * ty) / ((real)1 + a);
    real lo = ty, hi = tau_trial;
    for (int i = 0; i < HB_BISECTION_STEPS; ++i) {
        real mid = (real)0.5 * (lo + hi);
        real g = tau_trial - mid - p.shear_modulus * dt * pow((mid - ty) / k, (real)1 / n);
        if (g > (real)0) lo = mid;
        else hi = mid;
    }
    return (real)0.5 * (lo + hi);
}

// Above the yield stress the deviatoric strain is scaled to the relaxed stress, the volume kept;
// the plastic scalar accumulates the plastic shear strain.
__device__ __forceinline__ mat3 herschel_bulkley_project(const HerschelBulkleyParams& p, const mat3& f_trial, real* gamma_p,
                                                         real dt) {
    return hencky_return_map(f_trial, gamma_p, [&](vec3 eps, real g, vec3* e, real* g1) {
        real tr = sum(eps);
        vec3 e_hat = eps - make_v3s(tr / (real)3);
        real tau = sqrt((real)2) * p.shear_modulus * length(e_hat);
        if (tau <= p.yield_stress || tau <= (real)0) return false;
        real t = herschel_bulkley_relax(p, tau, dt);
        *e = e_hat * (t / tau) + make_v3s(tr / (real)3);
        *g1 = g + (tau - t) / p.shear_modulus;
        return true;
    });
}
