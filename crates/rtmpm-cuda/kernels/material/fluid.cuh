// Weakly compressible fluid tracking only J = det F: port of crates/rtmpm-core/src/material/fluid.rs.
#pragma once
#include "../math.cuh"

#define FLUID_J_MIN ((real)1e-3)  // J clamp of project and the EOS (finite pressure when inverted)
#define FLUID_EOS_LINEAR 0
#define FLUID_EOS_TAIT 1

// Host mirror (#[repr(C)]): { f32 bulk_modulus; i32 eos; f32 gamma; f32 viscosity; } (16 bytes).
// eos: FLUID_EOS_LINEAR (gamma unused) or FLUID_EOS_TAIT.
struct FluidParams {
    real bulk_modulus;
    int eos;
    real gamma;
    real viscosity;
};

__device__ __forceinline__ real fluid_pressure(const FluidParams& p, real j) {
    j = fmax(j, FLUID_J_MIN);
    if (p.eos == FLUID_EOS_TAIT) return p.bulk_modulus * (pow(j, -p.gamma) - (real)1);  // Tait
    return p.bulk_modulus * ((real)1 - j);                                               // mpm88 linear
}

// tau = -J p I + J mu (C + C^T)
__device__ __forceinline__ mat3 fluid_kirchhoff(const FluidParams& p, const mat3& f, const mat3& c) {
    real j = fmax(determinant(f), FLUID_J_MIN);
    real pr = fluid_pressure(p, j);
    return mat3_diag(make_v3s(-j * pr)) + (c + transpose(c)) * (j * p.viscosity);
}

// F reset to J^(1/3) I (Taichi mpm99), J clamped to FLUID_J_MIN.
__device__ __forceinline__ mat3 fluid_project(const FluidParams& p, const mat3& f_trial) {
    (void)p;
    real j = fmax(determinant(f_trial), FLUID_J_MIN);
    return mat3_diag(make_v3s(cbrt(j)));
}
