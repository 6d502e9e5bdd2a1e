// Grid-wide barrier of the persistent (cooperative) kernels: the fused rebuild (rebuild.cu) and
// the fused shared-block list of several GPUs (multi/reduce_shared.cu). Only for kernels launched
// cooperatively (every block resident), one at a time on a GPU: they share the two control words.
#pragma once
#include "common.cuh"

// Grid-wide barrier (sense by generation): the last block to arrive resets the count and bumps
// the generation; the others spin on the generation they saw before arriving.
__device__ __forceinline__ void rb_grid_barrier(const Ctx& c) {
    __syncthreads();
    if (threadIdx.x == 0) {
        volatile unsigned* gen = c.ctl + CTL_BARRIER_GEN;
        unsigned g = *gen;
        __threadfence();
        if (atomicAdd(&c.ctl[CTL_BARRIER_COUNT], 1u) == gridDim.x - 1) {
            c.ctl[CTL_BARRIER_COUNT] = 0;
            __threadfence();
            atomicAdd(&c.ctl[CTL_BARRIER_GEN], 1u);
        } else {
            while (*gen == g) {}
        }
        __threadfence();
    }
    __syncthreads();
}
