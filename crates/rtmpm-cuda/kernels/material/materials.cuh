// Material dispatch for the kernels (Rust: crates/rtmpm-core/src/material/mod.rs, Model).
#pragma once
#include "fluid.cuh"
#include "fixed_corotated.cuh"
#include "neo_hookean.cuh"
#include "snow.cuh"
#include "drucker_prager.cuh"
#include "von_mises.cuh"

// Same order as the Rust `Model` enum.
#define MATERIAL_FLUID 0
#define MATERIAL_FIXED_COROTATED 1
#define MATERIAL_NEO_HOOKEAN 2
#define MATERIAL_SNOW 3
#define MATERIAL_DRUCKER_PRAGER 4
#define MATERIAL_VON_MISES 5

// One material, uploaded by the host as a #[repr(C)] struct with exactly these fields in this
// order; every field is 4 bytes (f32 / i32 with `real` = float), so there is no padding:
//   kind: i32                                   offset  0
//   fluid: FluidParams (4 x 4 bytes)            offset  4
//   fixed_corotated: FixedCorotatedParams (2)   offset 20
//   neo_hookean: NeoHookeanParams (2)           offset 28
//   snow: SnowParams (5)                        offset 36
//   drucker_prager: DruckerPragerParams (4)     offset 56
//   von_mises: VonMisesParams (4)               offset 72
//   total 88 bytes. Only the member selected by `kind` is read; the others may be zero.
// With RTMPM_F64, `real` is double: 176 bytes, 4 bytes of padding after `kind` and after
// `fluid.eos` (the host mirror GpuMaterial<f64> has the same C layout).
struct MaterialGpu {
    int kind;
    FluidParams fluid;
    FixedCorotatedParams fixed_corotated;
    NeoHookeanParams neo_hookean;
    SnowParams snow;
    DruckerPragerParams drucker_prager;
    VonMisesParams von_mises;
};
#ifndef RTMPM_F64
static_assert(sizeof(MaterialGpu) == 88, "MaterialGpu layout must match the host #[repr(C)] mirror");
#else
static_assert(sizeof(MaterialGpu) == 176, "MaterialGpu layout must match the host #[repr(C)] mirror");
#endif

// Kirchhoff stress tau = P F^T; c is the APIC affine matrix (viscous fluid only).
__device__ __forceinline__ mat3 material_kirchhoff(const MaterialGpu& m, const mat3& f, real plastic, const mat3& c) {
    switch (m.kind) {
    case MATERIAL_FLUID: return fluid_kirchhoff(m.fluid, f, c);
    case MATERIAL_FIXED_COROTATED: return fixed_corotated_kirchhoff(m.fixed_corotated, f);
    case MATERIAL_NEO_HOOKEAN: return neo_hookean_kirchhoff(m.neo_hookean, f);
    case MATERIAL_SNOW: return snow_kirchhoff(m.snow, f, plastic);
    case MATERIAL_DRUCKER_PRAGER: return drucker_prager_kirchhoff(m.drucker_prager, f);
    case MATERIAL_VON_MISES: return von_mises_kirchhoff(m.von_mises, f);
    default: return mat3_zero();
    }
}

// Plastic return mapping of the trial elastic F; updates *plastic. Elastic models return f_trial.
__device__ __forceinline__ mat3 material_project(const MaterialGpu& m, const mat3& f_trial, real* plastic) {
    switch (m.kind) {
    case MATERIAL_FLUID: return fluid_project(m.fluid, f_trial);
    case MATERIAL_SNOW: return snow_project(m.snow, f_trial, plastic);
    case MATERIAL_DRUCKER_PRAGER: return drucker_prager_project(m.drucker_prager, f_trial, plastic);
    case MATERIAL_VON_MISES: return von_mises_project(m.von_mises, f_trial, plastic);
    default: return f_trial;
    }
}
