// Material dispatch of the CUDA pipeline: the constitutive models of kernels/material/ (one file
// per model, ported line for line from rtmpm-core's material/*.rs) through MaterialGpu.
#pragma once
#include "common.cuh"
