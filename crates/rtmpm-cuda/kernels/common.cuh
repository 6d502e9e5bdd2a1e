// Shared device structures of the rtmpm CUDA pipeline (Fei, Huang & Gao, "Real-Time Simulation of
// MPM on Modern GPUs", GTC 2022). The constants come from the Rust contract (contract.cuh, generated
// by src/contract/headers.rs), and every struct here has a Rust twin there whose field offsets the end of
// the program asserts one by one.
#pragma once
#include "contract.cuh"
#include "math.cuh"
#include "shape.cuh"
#include "stencil.cuh"

#define EMPTY_KEY 0xffffffffffffffffull
#define EMPTY_ID 0xffffffffu

// One material: its model's parameters (read as the model's <Name>Params struct, generated in
// material/registry.cuh) and its kind code (MATERIAL_*).
struct MaterialGpu {
    real p[MATERIAL_PARAMS];
    unsigned kind, pad;
};

struct GpuCollider {
    unsigned kind;  // SHAPE_* (geometry/registry.cuh)
    unsigned cond;  // COND_*
    float friction;
    unsigned mesh_offset;
    float pivot[3];    // in the rest pose (velocities: ColliderPoses)
    float p[8];        // shape parameters in the rest pose (geometry/<name>.cuh)
    unsigned dims[3];  // mesh: grid dims
    unsigned pad;
};

// The precision-dependent constants of a run (constant memory: scalars(c)).
struct Scalars {
    real origin[3];  // grid origin: the domain minimum minus 4 cells
    real dx, inv_dx;
    real domain_min[3], domain_max[3];
    real wall_friction[6];
    real flip;  // FLIP fraction of the classic transfers
};

// Parameters of one step (constant memory: step_params(c)), uploaded when they change.
struct StepParams {
    real dt, t;
    real gravity[3];
    real damping;  // settling damping factor on grid velocities (1 = off)
};

// Collider poses at the step's time (constant memory: poses(c)); geometry is float, as on the CPU.
struct ColliderPoses {
    float rot[RTMPM_MAX_COLLIDERS][9];  // rest -> world rotation at t (column-major)
    float pivot[RTMPM_MAX_COLLIDERS][3];
    float velocity[RTMPM_MAX_COLLIDERS][3];  // of the pivot at t (constant or keyframed)
    float omega[RTMPM_MAX_COLLIDERS][3];     // angular velocity at t (world frame)
};

// One collider's pose at the step's time: a row of a batch's per-world table (c_batch.poses,
// worlds x n_colliders rows; crate::contract::GpuColliderPose).
struct GpuColliderPose {
    float rot[9];  // rest -> world rotation at t (column-major)
    float pivot[3], velocity[3], omega[3];
};

// A rigid body at the step's time (rtmpm_rigid::BodyState; constant memory: body_at(c, b)):
// its shape about the centre of mass as a collider shape (pivot 0) with its boundary rule.
struct GpuBody {
    GpuCollider shape;
    float rot[9];  // rest -> world (column-major)
    float center[3], velocity[3], omega[3];
    float bound;   // radius of a sphere about the centre holding the body
    unsigned dynamic;  // moved by its impulses (host side; every body's reaction is summed)
};

// The user's tool (a live view's drag; constant memory: tool_at(c)), written when it changes: a
// separating collider moving at `velocity`, its shape in world coordinates (pivot 0, not rotated).
struct GpuTool {
    GpuCollider shape;
    float velocity[3];
    unsigned active;  // 0: no tool
};

// Constant for the life of the backend; passed by value to every kernel.
struct Ctx {
    real* state;              // RTMPM_NFIELDS reals per particle (material and id: state_bits)
    real* scratch;
    real* grid;               // 4 reals per node: mass, momentum (velocity after grid update)
    real* grid_next;          // G2P2G (g2p/g2p2g.cu): the grid the fused kernel scatters the next
                              // step into (null: G2P and P2G are separate kernels)
    real* grid_aux;           // classic MPM transfers and CK-MPM (else null), 4 reals per node:
                              // unused, dt f_i after P2G, v_old after the grid update, MUSL
                              // re-mapped v; CK-MPM: the nodes of its second grid (as grid's)
    real* grid_aux_next;      // CK-MPM with G2P2G (g2p/ck.cu): the second grid of the next step
    unsigned* ctl;
    const Scalars* scalars;   // global copies of the constant-memory parameters
    const StepParams* step;   // (read with -DRTMPM_PARAMS_GLOBAL)
    const ColliderPoses* poses;
    const MaterialGpu* materials;
    const GpuCollider* colliders;
    const float* mesh_values;
    unsigned long long* hash_keys;
    unsigned* hash_values;
    int* block_coords;        // 3 ints per pblock
    unsigned* neighbors;      // 27 per gblock
    unsigned* hist;           // gblock_cap * 64 + 1 bucket counts / offsets
    unsigned* scan_sums;      // block sums of the scan
    unsigned* pkey;           // per particle: bucket
    unsigned* prank;          // per particle: rank in bucket
    unsigned* warps;          // 3 per warp: gblock, first, count
    unsigned* boundary;       // per gblock: 1 if a neighbour block is shared with another GPU
    unsigned* shared_pblock;  // per pblock: the GPUs holding it if several do, else 0
    const GpuBody* bodies;    // global copy of c_bodies
    double* body_exchange;    // rigid bodies: impulse, angular impulse (6 doubles) per body, in
                              // BODY_EXCHANGE_SLOTS copies (grid_update.cu: couple_bodies)
    const GpuTool* tool;      // global copy of c_tool
    int n_cells[3];
    int wall_thickness;
    unsigned wall_cond[6];    // COND_* of x min, x max, y min, ...
    unsigned n, cap, gblock_cap, pblock_cap, hash_cap, warp_cap, n_colliders, n_buckets;
    unsigned warp_reduce, warp_sort;
    unsigned transfer, update;  // TRANSFER_*, UPDATE_*
    unsigned always_rebuild;    // rebuild every step (free zone or mixed sorting off)
    unsigned n_bodies;          // rigid bodies coupled in the grid update
};

// Read-only parameters in constant memory (the GPU MPM/GIMP port: "constant memory is used for
// read-only input data"): they are read by every thread with (mostly) warp-uniform addresses,
// which the constant cache broadcasts. The host writes both these symbols and the global copies
// behind Ctx::scalars/step/poses/materials/colliders; compiling with -DRTMPM_PARAMS_GLOBAL
// (RTMPM_KERNEL_DEFINES) reads the global copies instead, to measure the difference.
__constant__ Scalars c_scalars;
__constant__ StepParams c_step;
__constant__ ColliderPoses c_poses;
__constant__ MaterialGpu c_materials[RTMPM_MAX_MATERIALS];
__constant__ GpuCollider c_colliders[RTMPM_MAX_COLLIDERS];
__constant__ GpuBody c_bodies[RTMPM_MAX_BODIES];
__constant__ GpuTool c_tool;

#ifdef RTMPM_PARAMS_GLOBAL
#define RTMPM_PARAM(global, constant) (global)
#else
#define RTMPM_PARAM(global, constant) (constant)
#endif
__device__ __forceinline__ const Scalars& scalars(const Ctx& c) { return RTMPM_PARAM(*c.scalars, c_scalars); }
__device__ __forceinline__ const StepParams& step_params(const Ctx& c) { return RTMPM_PARAM(*c.step, c_step); }
__device__ __forceinline__ const ColliderPoses& poses(const Ctx& c) { return RTMPM_PARAM(*c.poses, c_poses); }
__device__ __forceinline__ const MaterialGpu& material_at(const Ctx& c, unsigned id) {
#ifdef RTMPM_BATCH
    return c.materials[id];  // a row per world and material: more than constant memory holds
#else
    return RTMPM_PARAM(c.materials[id], c_materials[id]);
#endif
}
__device__ __forceinline__ const GpuCollider& collider_at(const Ctx& c, unsigned k) {
    return RTMPM_PARAM(c.colliders[k], c_colliders[k]);
}
__device__ __forceinline__ const GpuBody& body_at(const Ctx& c, unsigned b) {
    return RTMPM_PARAM(c.bodies[b], c_bodies[b]);
}
__device__ __forceinline__ const GpuTool& tool_at(const Ctx& c) { return RTMPM_PARAM(*c.tool, c_tool); }

__device__ __forceinline__ unsigned long long spread3(unsigned v) {
    unsigned long long x = v & 0x7ffffull;
    x = (x | (x << 32)) & 0x001f00000000ffffull;
    x = (x | (x << 16)) & 0x001f0000ff0000ffull;
    x = (x | (x << 8)) & 0x100f00f00f00f00full;
    x = (x | (x << 4)) & 0x10c30c30c30c30c3ull;
    x = (x | (x << 2)) & 0x1249249249249249ull;
    return x;
}
__device__ __forceinline__ unsigned compact3(unsigned long long c) {
    unsigned long long x = c & 0x1249249249249249ull;
    x = (x | (x >> 2)) & 0x10c30c30c30c30c3ull;
    x = (x | (x >> 4)) & 0x100f00f00f00f00full;
    x = (x | (x >> 8)) & 0x001f0000ff0000ffull;
    x = (x | (x >> 16)) & 0x001f00000000ffffull;
    x = (x | (x >> 32)) & 0x7ffffull;
    return (unsigned)x;
}
// Block code as rtmpm_physics::grid::codes::block_code.
__device__ __forceinline__ unsigned long long block_code(int bi, int bj, int bk) {
    return (spread3((unsigned)bi) << 2) | (spread3((unsigned)bj) << 1) | spread3((unsigned)bk);
}
__device__ __forceinline__ int cell_code(int i, int j, int k) { return ((i & 3) << 4) | ((j & 3) << 2) | (k & 3); }
__device__ __forceinline__ int nb_slot(int di, int dj, int dk) { return (di + 1) * 9 + (dj + 1) * 3 + (dk + 1); }

// The word of field f of slot i in the state arrays (structure of arrays, stride cap). Computed in
// 64 bits when the arrays hold 2^32 words or more (the host then defines RTMPM_STATE_64, for
// capacities above 148M particles); in 32 bits otherwise, as cheap as before.
#ifdef RTMPM_STATE_64
typedef unsigned long long state_index_t;
#else
typedef unsigned state_index_t;
#endif
__device__ __forceinline__ state_index_t sidx(unsigned cap, int f, unsigned i) { return (state_index_t)f * cap + i; }

// Loads and stores of the particle state's words (compile-time RTMPM_STATE_STREAM, default 0):
// 0 plain; 1 with the streaming cache hint (ld.global.cs / st.global.cs: evict first), since
// a step reads and writes each word once and the grid's nodes are what the caches should keep.
// With the resident grid: 3-7 % faster on the H200 (bench/RESULTS.md), not yet run through the tests.
#ifndef RTMPM_STATE_STREAM
#define RTMPM_STATE_STREAM 0
#endif
__device__ __forceinline__ real state_ld(const real* s, state_index_t w) {
#if RTMPM_STATE_STREAM
    return __ldcs(s + w);
#else
    return s[w];
#endif
}
__device__ __forceinline__ void state_st(real* s, state_index_t w, real v) {
#if RTMPM_STATE_STREAM
    __stcs(s + w, v);
#else
    s[w] = v;
#endif
}

__device__ __forceinline__ vec3 load_v3(const real* s, unsigned cap, int f, unsigned i) {
    return make_v3(state_ld(s, sidx(cap, f, i)), state_ld(s, sidx(cap, f + 1, i)), state_ld(s, sidx(cap, f + 2, i)));
}
__device__ __forceinline__ void store_v3(real* s, unsigned cap, int f, unsigned i, vec3 v) {
    state_st(s, sidx(cap, f, i), v.x); state_st(s, sidx(cap, f + 1, i), v.y); state_st(s, sidx(cap, f + 2, i), v.z);
}
__device__ __forceinline__ mat3 load_m3(const real* s, unsigned cap, int f, unsigned i) {
    mat3 m; for (int c = 0; c < 9; ++c) m.m[c] = state_ld(s, sidx(cap, f + c, i)); return m;
}
__device__ __forceinline__ void store_m3(real* s, unsigned cap, int f, unsigned i, const mat3& m) {
    for (int c = 0; c < 9; ++c) state_st(s, sidx(cap, f + c, i), m.m[c]);
}

// Integer field of the state (material id, original index): its bits in the low 32 bits of the word.
__device__ __forceinline__ unsigned state_bits(real w) {
#ifdef RTMPM_F64
    return (unsigned)__double_as_longlong(w);
#else
    return __float_as_uint(w);
#endif
}

#include "state.cuh"

// Many worlds in one set of arrays (-DRTMPM_BATCH; crate::batch): particles keep their world's
// coordinates, world w's grid lies w stride + origin cells along x from the grid's origin (its
// own blocks and block codes, a gap to the next world's), and a particle's world is its
// material row / the materials of a world. Without RTMPM_BATCH a particle's world is 0 and
// nothing is read for it: the kernels of one world are unchanged.
#ifdef RTMPM_BATCH
struct BatchParams {
    unsigned worlds, materials, stride, origin;
    const real* gravity;  // 3 per world
    // Worlds with colliders of their own (crate::batch::colliders): n_colliders records and
    // n_colliders poses per world (row world * n_colliders + k; the poses at the step's time,
    // uploaded each step while a collider of some world moves); null: every world's are the
    // scene's (c_colliders, c_poses).
    const GpuCollider* colliders;
    const GpuColliderPose* poses;
};
static_assert(sizeof(BatchParams) == 40, "BatchParams: crate::batch::BatchParams");
__constant__ BatchParams c_batch;
__device__ __forceinline__ unsigned material_world(unsigned material) { return material / c_batch.materials; }
__device__ __forceinline__ unsigned particle_world(const Ctx& c, unsigned p) {
    return material_world(state_bits(c.state[sidx(c.cap, F_MAT, p)]));
}
// The world of a node from its x grid index (each world's nodes lie in its stripe).
__device__ __forceinline__ unsigned node_world(int gi_x) { return (unsigned)gi_x / c_batch.stride; }
__device__ __forceinline__ int world_cells(unsigned world) { return (int)(world * c_batch.stride + c_batch.origin); }
#else
#define material_world(material) 0u
#define particle_world(c, p) 0u
#endif

// Grid coordinate, stencil base and fractional offset of a position (shape.rs) of a particle of
// world `world` (RTMPM_BATCH; else 0).
__device__ __forceinline__ void stencil_of(const Ctx& c, vec3 x, unsigned world, int base[3], real fx[3]) {
    const Scalars& sc = scalars(c);
    real xg[3] = {(x.x - sc.origin[0]) * sc.inv_dx, (x.y - sc.origin[1]) * sc.inv_dx, (x.z - sc.origin[2]) * sc.inv_dx};
    for (int a = 0; a < 3; ++a) {
        real b = floor(xg[a] - (real)0.5);
        base[a] = (int)b;
        fx[a] = xg[a] - b;
    }
#ifdef RTMPM_BATCH
    base[0] += world_cells(world);
#endif
}
// Stencil of a particle for the active transfer: base node, fractional offset, per-axis weights
// w[axis][node] and derivatives d[axis][node] (d w / d fx). Weight of node (i, j, k):
// w[0][i] w[1][j] w[2][k]; its gradient: shape_grad(w, d, i, j, k) * inv_dx. The per-(particle,
// node) interface every P2G/G2P variant can use (rtmpm_physics::shape_function::Stencil::for_transfer).
__device__ __forceinline__ void particle_stencil(const Ctx& c, vec3 x, unsigned world, int base[3], real fx[3], real w[3][3],
                                                 real d[3][3]) {
    stencil_of(c, x, world, base, fx);
    for (int a = 0; a < 3; ++a) shape_1d(c.transfer, fx[a], w[a], d[a]);
}

// Hash lookup of a block code; EMPTY_ID if absent.
__device__ __forceinline__ unsigned hash_find(const Ctx& c, unsigned long long key) {
    unsigned mask = c.hash_cap - 1;
    unsigned h = (unsigned)((key * 0x9E3779B97F4A7C15ull) >> 32) & mask;
    for (unsigned probe = 0; probe < c.hash_cap; ++probe) {
        unsigned long long k = c.hash_keys[h];
        if (k == key) return c.hash_values[h];
        if (k == EMPTY_KEY) return EMPTY_ID;
        h = (h + 1) & mask;
    }
    return EMPTY_ID;
}
// Insert a key (atomicCAS open addressing, linear probing). Sets ERR_HASH when full.
__device__ __forceinline__ void hash_insert(const Ctx& c, unsigned long long key) {
    unsigned mask = c.hash_cap - 1;
    unsigned h = (unsigned)((key * 0x9E3779B97F4A7C15ull) >> 32) & mask;
    for (unsigned probe = 0; probe < c.hash_cap; ++probe) {
        unsigned long long prev = atomicCAS(&c.hash_keys[h], EMPTY_KEY, key);
        if (prev == EMPTY_KEY || prev == key) return;
        h = (h + 1) & mask;
    }
    atomicOr(&c.ctl[CTL_ERROR], ERR_HASH);
}
__device__ __forceinline__ unsigned thread_index() { return blockIdx.x * blockDim.x + threadIdx.x; }

// Programmatic dependent launch (Hopper, compute capability 9.0+; `--cuda-options pdl=on`, which
// defines RTMPM_PDL only when the GPU has it). The host launches the step's kernels after the
// first (`p2g`, `grid_update`, the G2P and G2P2G kernels, crate::kernels::Kernels::launch_step)
// with the attribute CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION: such a kernel's blocks
// may start while the kernel before it still runs, so every one of them calls `step_kernel_entry`
// as its first statement, on every path, before any read or write of device memory (each first
// reads c.ctl, which the kernel before writes; a kernel's parameter `c` and the __constant__
// symbols, written before the step, are no dependency). `griddepcontrol.wait` returns when the
// kernels this one depends on have completed and their writes are visible; since every kernel of
// the chain waits before it ends, a kernel's completion implies that of every kernel before it.
// `griddepcontrol.launch_dependents` then lets the next kernel's blocks be scheduled as this
// kernel's blocks drain (they wait in their own entry until this kernel completes). Both are
// no-ops in a kernel launched without the attribute; without RTMPM_PDL both are left out.
// RTMPM_PDL_TRIGGER=0 (an experiment, through RTMPM_KERNEL_DEFINES) leaves the trigger out: the
// next kernel's blocks are then scheduled as this kernel's blocks exit.
#ifndef RTMPM_PDL_TRIGGER
#define RTMPM_PDL_TRIGGER 1
#endif
#if defined(RTMPM_PDL) && defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 900
__device__ __forceinline__ void step_kernel_entry() {
    asm volatile("griddepcontrol.wait;" ::: "memory");
#if RTMPM_PDL_TRIGGER
    asm volatile("griddepcontrol.launch_dependents;" ::: "memory");
#endif
}
#else
__device__ __forceinline__ void step_kernel_entry() {}
#endif

// G2P2G: does this step's grid still need its P2G (and the clear before it)? Always without
// G2P2G; with it only after a rebuild (new mapping) or when the host asked (first step, new dt):
// otherwise the previous step's fused kernel has already scattered the particles into it.
// Read only in kernels launched after the one that sets CTL_REBUILT_NOW.
__device__ __forceinline__ bool grid_needs_p2g(const Ctx& c) {
    return !c.grid_next || c.ctl[CTL_REBUILT_NOW] || c.ctl[CTL_P2G_PENDING];
}
