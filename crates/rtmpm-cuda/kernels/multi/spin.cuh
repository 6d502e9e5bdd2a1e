// The spin lock of barrier.cu as a device function, for the kernels that take the inter-GPU
// barrier inside them (barrier_spin; the fused shared-block list of reduce_shared.cu).
#pragma once
#include "../common.cuh"

struct SpinBarrier {
    unsigned long long* count;  // on GPU 0: arrivals so far, over every GPU and call
    unsigned long long* calls;  // on this GPU: this GPU's barrier calls so far
    unsigned long long timeout_ns;
    unsigned n;                 // GPUs
    unsigned pad;
};

__device__ __forceinline__ unsigned long long bar_now_ns() {
    unsigned long long t;
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t));
    return t;
}

// One thread of the grid calls it: arrive at this GPU's next barrier call and wait for every GPU
// (see barrier.cu). On timeout it sets ERR_BARRIER and returns.
__device__ __forceinline__ void spin_barrier_arrive_wait(const Ctx& c, const SpinBarrier& b) {
#if __CUDA_ARCH__ >= 700
    __threadfence_system();
    unsigned long long g = *b.calls + 1ull;
    *b.calls = g;
    atomicAdd_system(b.count, 1ull);
    unsigned long long target = g * (unsigned long long)b.n;
    unsigned long long start = bar_now_ns();
    for (;;) {
        unsigned long long v;
        asm volatile("ld.acquire.sys.global.u64 %0, [%1];" : "=l"(v) : "l"(b.count) : "memory");
        if (v >= target) break;
        if (bar_now_ns() - start > b.timeout_ns) {
            atomicOr(&c.ctl[CTL_ERROR], ERR_BARRIER);
            break;
        }
        __nanosleep(32);
    }
    __threadfence_system();
#else
    // Peer access and system-scope atomics need compute capability 7.0 here.
    atomicOr(&c.ctl[CTL_ERROR], ERR_BARRIER);
#endif
}
