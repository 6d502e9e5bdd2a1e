// Weakly compressible fluid tracking only J = det F: port of crates/rtmpm-physics/src/material/fluid.rs.
#pragma once
#include "../math.cuh"

#define FLUID_J_MIN ((real)1e-3)  // J clamp of project and the EOS (finite pressure when inverted)

// p(J) of bulk modulus k: Tait (Cole 1948) when tait != 0, else the linear p = k (1 - J) of mpm88.
__device__ __forceinline__ real fluid_eos_pressure(real k, real tait, real gamma, real j) {
    j = fmax(j, FLUID_J_MIN);
    if (tait != (real)0) return k * (pow(j, -gamma) - (real)1);  // Tait
    return k * ((real)1 - j);                                    // mpm88 linear
}

__device__ __forceinline__ real fluid_pressure(const FluidParams& p, real j) {
    return fluid_eos_pressure(p.bulk_modulus, p.tait, p.gamma, j);
}

// tau = -J p I + J mu (C + C^T)
__device__ __forceinline__ mat3 fluid_kirchhoff(const FluidParams& p, const mat3& f, real plastic, const mat3& c) {
    (void)plastic;
    real j = fmax(determinant(f), FLUID_J_MIN);
    real pr = fluid_pressure(p, j);
    return mat3_diag(make_v3s(-j * pr)) + (c + transpose(c)) * (j * p.viscosity);
}

// F reset to J^(1/3) I (Taichi mpm99), J clamped to FLUID_J_MIN.
__device__ __forceinline__ mat3 fluid_project(const FluidParams& p, const mat3& f_trial, real* plastic, real dt) {
    (void)dt;
    (void)p;
    (void)plastic;
    real j = fmax(determinant(f_trial), FLUID_J_MIN);
    return mat3_diag(make_v3s(cbrt(j)));
}
