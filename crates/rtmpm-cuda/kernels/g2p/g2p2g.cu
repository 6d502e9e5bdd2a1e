// G2P2G: the "merge kernels" of Fei, Huang & Gao ("Real-Time Simulation of MPM on Modern GPUs",
// GTC 2022) taken across the step boundary (the G2P2G of Wang et al.
// 2020). One pass over the particles does the G2P of step n from `grid` and, while the new state
// is still in registers, the P2G of step n+1 into `grid_next` (cleared by this step's grid
// update): the next step reads no particle for its P2G and launches no P2G kernel.
//
// G2P2G's caveat (no particle may change between G2P and P2G, Fei, Huang & Gao) meets the free
// zone here: a particle that leaves its free zone may no longer be covered by its gblock's 3x3x3
// neighbourhood, so it is not scattered; it has set the rebuild flag, and the next step rebuilds
// the mapping and redoes its P2G from the stored state (the P2G kernel runs only then, see
// grid_needs_p2g). The scatter uses this step's dt; the host asks for a P2G when dt changes.
#include "particle.cuh"
#include "../p2g/warp.cuh"

// Register budgets, measured on an H200 (bench/RESULTS.md, "Occupancy"): in f32 both fused
// kernels held to 5 resident blocks of 128 threads a SM (96 registers, 24-48 bytes of spills with
// ptxas 13.0) and launched as the blocks resident at once (crates/rtmpm-cuda/src/kernels.rs) ran
// the claymore scenes 5-8 % faster than ptxas's own choice for the general kernel (128
// registers; a hint of 1 to 4 cost jelly 8 %) with 4 blocks for the fluid one. In f64 the same
// bounds made the step 18-33 % slower (its doubles spill), so f64 keeps the earlier ones.
// -DG2P2G_MIN_BLOCKS=0 leaves the general kernel to ptxas, -DG2P2G_FLUID_MIN_BLOCKS=N sets the
// fluid kernel's bound.
#ifdef RTMPM_F64
#define G2P2G_DEFAULT_MIN_BLOCKS 0
#define G2P2G_DEFAULT_FLUID_MIN_BLOCKS 4
#else
#define G2P2G_DEFAULT_MIN_BLOCKS 5
#define G2P2G_DEFAULT_FLUID_MIN_BLOCKS 5
#endif
#ifndef G2P2G_FLUID_MIN_BLOCKS
#define G2P2G_FLUID_MIN_BLOCKS G2P2G_DEFAULT_FLUID_MIN_BLOCKS
#endif
#ifndef G2P2G_MIN_BLOCKS
#define G2P2G_MIN_BLOCKS G2P2G_DEFAULT_MIN_BLOCKS
#endif
#if G2P2G_MIN_BLOCKS > 0
#define G2P2G_BOUNDS 128, G2P2G_MIN_BLOCKS
#else
#define G2P2G_BOUNDS 128
#endif

// Lanes that do not scatter (past the warp's count, or leaving their free zone) keep their
// P2G quantities unset except the stencil base (compile-time, default 0: all zeroed, as
// before; the CUDA option `lean_lanes=on`). The same sums: such a lane's values reach no atomic.
#ifndef RTMPM_G2P2G_LEAN_LANES
#define RTMPM_G2P2G_LEAN_LANES 0
#endif

// One entry w of the warp list, by every lane of a warp: the G2P of step n of its particles
// (lane < count) and the P2G of step n+1 of those that stay in their free zone.
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_warp(const Ctx& c, unsigned w, unsigned lane, unsigned* speed) {
    unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
    // G2P of step n; the particle's P2G quantities of step n+1 from the new state.
    bool scatter = false;
    unsigned key = P2G_KEY_NONE;
#if RTMPM_G2P2G_LEAN_LANES
    // Only the stencil base of a lane that does not scatter is set (the scatter then addresses
    // its gblock's own nodes instead, p2g_scatter_warp): the segmented reduction never adds an
    // inactive lane's values into a head's (an inactive lane is a segment boundary) and such a
    // lane is no head, so the other fields are left as they are instead of zeroed in every warp
    // entry.
    P2gParticle q;
    q.base[0] = q.base[1] = q.base[2] = 0;
#else
    P2gParticle q = p2g_particle_zero();
#endif
    if (lane < count) {
        unsigned p = first + lane;
        real m = state_ld(c.state, sidx(c.cap, F_MASS, p)), vol0 = state_ld(c.state, sidx(c.cap, F_VOL0, p));
        G2pResult r = g2p_particle<ALL_FLUID>(c, g, p);
        *speed = max(*speed, r.speed);
        if (!r.leave) {
            q = p2g_particle_of<ALL_FLUID>(c, r.x, m, vol0, r.v, r.C, r.F, r.plastic, r.material);
            key = p2g_sort_key(c, g, q.base);
            scatter = true;
        }
    }
    // P2G of step n+1, as in p2g.cu: in-warp sort (the particles change lanes by shuffles,
    // only when the warp is out of order), segmented reduction, atomics into grid_next.
    if (c.warp_sort) {
        unsigned src = p2g_warp_sort(key, lane, &scatter);
        if (__any_sync(0xffffffffu, src != lane)) q = p2g_particle_from_lane(q, src);
    }
    p2g_scatter_warp(c, g, q, scatter, lane, c.grid_next);
}

// The warp loop's values as warp-uniform ones (compile-time, default 1): the error flag by a vote,
// the warp count and the first entry by warp reductions. Every lane of a warp reads the same words
// and runs the same trips either way (the scatter's shuffles need the whole warp); written so,
// ptxas can see it, and drops the divergence checks (BRA.DIV and its slow path) before every
// shuffle of the G2P2G body: the same arithmetic, a reduction round 27 instructions instead of 29,
// g2p2g_fluid 1,840 -> 1,376 SASS instructions and g2p2g's spills 36/44 -> 4/4 bytes (ptxas 13.0).
// 0: the loop as before (the CUDA option `uniform_loop=off`, compile.rs).
#ifndef RTMPM_G2P2G_UNIFORM
#define RTMPM_G2P2G_UNIFORM 1
#endif

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks).
template <bool ALL_FLUID>
__device__ __forceinline__ void g2p2g_body(const Ctx& c) {
    step_kernel_entry();
#if RTMPM_G2P2G_UNIFORM
    if (__any_sync(0xffffffffu, c.ctl[CTL_ERROR] != 0)) return;
    unsigned n_warps = __reduce_max_sync(0xffffffffu, c.ctl[CTL_WARPS]), stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = __reduce_max_sync(0xffffffffu, thread_index() >> 5); w < n_warps; w += stride) g2p2g_warp<ALL_FLUID>(c, w, lane, &speed);
#else
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) g2p2g_warp<ALL_FLUID>(c, w, lane, &speed);
#endif
    report_max_speed(c, speed);
}

// Every scene.
extern "C" __global__ void __launch_bounds__(G2P2G_BOUNDS) g2p2g(Ctx c) { g2p2g_body<false>(c); }
// Scenes whose materials are all fluids (see ALL_FLUID in g2p_particle.cuh).
extern "C" __global__ void __launch_bounds__(128, G2P2G_FLUID_MIN_BLOCKS) g2p2g_fluid(Ctx c) { g2p2g_body<true>(c); }
