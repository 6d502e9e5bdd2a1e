// The inter-GPU barrier of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022) ("Implementation of the inter-GPU barrier": a spin lock on
// system-scope atomics), used by transport=p2p between the GPUs of one process.
//
// One counter in GPU 0's memory, reached by every GPU through peer access. Every GPU counts its own
// barrier calls (calls, in its own memory, incremented by the kernel itself, so a CUDA graph can
// replay the kernel): at its g-th call a GPU adds 1 to the counter and spins until the counter
// reaches g * n. No GPU passes call g before all n arrived at it (each has then added exactly g),
// so the counter never needs a reset (the talk's kernel resets it from GPU 0 after a second round
// of arrivals; the generation target makes that round unnecessary). 64 bits: no wrap in practice.
//
// __threadfence_system() before arriving makes this GPU's writes (the packed shared blocks, the
// occupancy mask) visible to every GPU before any of them leaves the barrier; the one after the
// spin orders this GPU's later reads of peer memory after it. A GPU that never arrives (its host
// thread failed) does not hang the others: after timeout_ns the kernel sets ERR_BARRIER and
// returns; the host reports the error at the next check.
#include "spin.cuh"

// One block of one thread.
extern "C" __global__ void barrier_spin(Ctx c, SpinBarrier b) {
    if (threadIdx.x != 0 || blockIdx.x != 0) return;
    spin_barrier_arrive_wait(c, b);
}
