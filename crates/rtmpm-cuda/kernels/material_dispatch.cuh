// Material dispatch of the CUDA backend (fluid only for now).
// TODO: call the ported headers kernels/material/*.cuh and kernels/svd.cuh for the elastic and
// plastic models once they land; until then other materials are refused by CudaBackend::new.
#pragma once
#include "common.cuh"

#define FLUID_J_MIN ((real)1e-3)

// Kirchhoff stress tau = -J p I + J mu (C + C^T)  (rtmpm_core::material::Fluid::kirchhoff).
__device__ __forceinline__ mat3 material_kirchhoff(const GpuMaterial& m, const mat3& F, real plastic, const mat3& C) {
    (void)plastic;
    real j = determinant(F);
    j = j > FLUID_J_MIN ? j : FLUID_J_MIN;
    real K = m.p[0];
    real p = m.eos == 0 ? K * ((real)1 - j) : K * (pow(j, -(real)m.p[1]) - (real)1);
    mat3 tau = (C + transpose(C)) * (j * (real)m.p[2]);
    tau.m[0] -= j * p; tau.m[4] -= j * p; tau.m[8] -= j * p;
    return tau;
}

// Plastic return mapping (fluid: F = J^(1/3) I).
__device__ __forceinline__ mat3 material_project(const GpuMaterial& m, const mat3& F, real* plastic) {
    (void)m; (void)plastic;
    real j = determinant(F);
    j = j > FLUID_J_MIN ? j : FLUID_J_MIN;
    real s = cbrt(j);
    return mat3_diag(make_v3(s, s, s));
}
