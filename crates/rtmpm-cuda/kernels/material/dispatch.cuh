// The materials of the kernels: every model of rtmpm-physics's registry (crates/rtmpm-physics/src/material),
// one file per model (material/<name>.cuh, a port of material/<name>.rs, formula by formula), with
// the uniform interface
//   <name>_kirchhoff(const <Name>Params& p, const mat3& f, real plastic, const mat3& c)  tau = P F^T
//   <name>_project(const <Name>Params& p, const mat3& f_trial, real* plastic, real dt)  return map
// registry.cuh is generated from the Rust registry (src/contract/): each model's kind code
// (MATERIAL_*), its parameter struct with the fields of the model's GPU_PARAMS and a reader
// <name>_params(m), the includes, and material_kirchhoff / material_project, a switch over the kind.
#pragma once
#include "../common.cuh"
#include "registry.cuh"
