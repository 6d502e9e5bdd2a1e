// Shared device structures of the rtmpm CUDA pipeline (seed 000). Must match src/layout.rs.
#pragma once
#include "math.cuh"
#include "shape.cuh"
#include "material/materials.cuh"

#define RTMPM_MAX_COLLIDERS 16
#define RTMPM_NFIELDS 29
// Field offsets of the particle state (structure of arrays: field f of particle i is at
// state[f * cap + i]; every field is 32 bits).
#define F_X 0
#define F_V 3
#define F_C 6
#define F_F 15
#define F_PLASTIC 24
#define F_MASS 25
#define F_VOL0 26
#define F_MAT 27
#define F_ID 28

// Control words (unsigned ctl[]).
#define CTL_NEED_REBUILD 0
#define CTL_GBLOCKS 1
#define CTL_PBLOCKS 2
#define CTL_ERROR 3
#define CTL_BAD_INDEX 4
#define CTL_BAD_REASON 5
#define CTL_MAX_SPEED 6
#define CTL_REBUILDS 7
#define CTL_WARPS 8
#define CTL_EXTRA 9
#define CTL_PREV_GBLOCKS 10
#define CTL_REBUILT_NOW 11
#define CTL_SHARED 12
#define CTL_SHARED_CAP 13
#define CTL_BARRIER_COUNT 14  // grid barrier of rb_fused (rebuild.cu): blocks arrived
#define CTL_BARRIER_GEN 15    // grid barrier of rb_fused: generation
#define CTL_P2G_PENDING 16    // G2P2G: the grid of this step still needs a P2G (first step, new dt)
#define CTL_WORDS 17

#define ERR_HASH 1u
#define ERR_GBLOCKS 2u
#define ERR_PBLOCKS 4u
#define ERR_WARPS 8u
#define ERR_P2G_MAP 16u  // reverse map of the gather P2G full (p2g_reverse_map.cu)
#define ERR_SHARED 32u  // more blocks shared between GPUs than the reduction holds (reduce_shared.cu)
#define ERR_BARRIER 64u  // the inter-GPU spin barrier timed out: another GPU never arrived (barrier.cu)

#define EMPTY_KEY 0xffffffffffffffffull
#define EMPTY_ID 0xffffffffu

// Materials: the ported constitutive models (kernels/material/), one MaterialGpu each.
typedef MaterialGpu GpuMaterial;

struct GpuCollider {
    unsigned kind;  // 0 half-space, 1 box, 2 sphere, 3 cylinder, 4 mesh
    unsigned cond;  // 0 sticky, 1 slip, 2 separate
    float friction;
    unsigned mesh_offset;
    float velocity[3];
    float angular_velocity[3];
    float pivot[3];
    float p[8];        // shape parameters in the rest pose
    unsigned dims[3];  // mesh: grid dims
    unsigned pad;
};

// Precision: the scalars the step computes with exist in both widths, so that the host has one
// layout for both (src/layout.rs); kernels read those of their precision under the plain name
// (`c.dx`), the others carry a suffix. Collider geometry stays float, as on the CPU.
#ifdef RTMPM_F64
#define NAME_IF_F32(name) name##_f32
#define NAME_IF_F64(name) name
#else
#define NAME_IF_F32(name) name
#define NAME_IF_F64(name) name##_f64
#endif

// Written with an async host-to-device copy on the compute stream before every step.
struct StepParams {
    float NAME_IF_F32(dt), t;
    float NAME_IF_F32(gravity)[3];
    unsigned always_rebuild;
    float damping;  // settling damping factor on grid velocities (1 = off)
    unsigned pad;
    float rot[RTMPM_MAX_COLLIDERS][9];    // rest -> world rotation at t (column-major)
    float pivot_t[RTMPM_MAX_COLLIDERS][3];
    double NAME_IF_F64(dt), NAME_IF_F64(gravity)[3];
};

// Constant for the life of the backend; passed by value to every kernel.
struct Ctx {
    real* state;              // RTMPM_NFIELDS reals per particle (material and id: state_bits)
    real* scratch;
    real* grid;               // 4 reals per node: mass, momentum (velocity after grid update)
    unsigned* ctl;
    const StepParams* step;
    const GpuMaterial* materials;
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
    real* grid_aux;           // classic MPM transfers only (else null), 4 reals per node: unused,
                              // dt f_i after P2G, v_old after the grid update, MUSL re-mapped v
    unsigned* boundary;       // per gblock: 1 if a neighbour block is shared with another GPU
    float NAME_IF_F32(origin)[3];
    float NAME_IF_F32(dx), NAME_IF_F32(inv_dx);
    float NAME_IF_F32(domain_min)[3], NAME_IF_F32(domain_max)[3];
    int n_cells[3];
    int wall_thickness;
    unsigned wall_cond[6];
    float NAME_IF_F32(wall_friction)[6];
    unsigned n, cap, gblock_cap, pblock_cap, hash_cap, warp_cap, n_colliders, n_buckets;
    unsigned warp_reduce, warp_sort;
    unsigned transfer, update;  // TRANSFER_*, UPDATE_* (shape.cuh)
    float flip;                 // FLIP fraction of the classic transfers
    real* grid_next;            // G2P2G (g2p2g.cu): the grid the fused kernel scatters the next
                                // step into (null: G2P and P2G are separate kernels)
    double NAME_IF_F64(origin)[3];
    double NAME_IF_F64(dx), NAME_IF_F64(inv_dx);
    double NAME_IF_F64(domain_min)[3], NAME_IF_F64(domain_max)[3];
    double NAME_IF_F64(wall_friction)[6];
};
static_assert(sizeof(Ctx) == 456 && sizeof(StepParams) == 832, "Ctx/StepParams must match src/layout.rs");

// Read-only parameters in constant memory (seed 001: "constant memory is used for read-only input
// data"): the step parameters, the materials table and the colliders are read by every thread with
// (mostly) warp-uniform addresses, which the constant cache broadcasts. The host writes both these
// symbols and the global copies behind Ctx::step/materials/colliders; compiling with
// -DRTMPM_PARAMS_GLOBAL (RTMPM_KERNEL_DEFINES) reads the global copies instead, to measure the
// difference (bench/RESULTS.md).
#define RTMPM_MAX_MATERIALS 64
__constant__ StepParams c_step;
__constant__ GpuMaterial c_materials[RTMPM_MAX_MATERIALS];
__constant__ GpuCollider c_colliders[RTMPM_MAX_COLLIDERS];

__device__ __forceinline__ const StepParams& step_params(const Ctx& c) {
#ifdef RTMPM_PARAMS_GLOBAL
    return *c.step;
#else
    return c_step;
#endif
}
__device__ __forceinline__ const GpuMaterial& material_at(const Ctx& c, unsigned id) {
#ifdef RTMPM_PARAMS_GLOBAL
    return c.materials[id];
#else
    return c_materials[id];
#endif
}
__device__ __forceinline__ const GpuCollider& collider_at(const Ctx& c, unsigned k) {
#ifdef RTMPM_PARAMS_GLOBAL
    return c.colliders[k];
#else
    return c_colliders[k];
#endif
}

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
// Block code as rtmpm_core::grid::codes::block_code.
__device__ __forceinline__ unsigned long long block_code(int bi, int bj, int bk) {
    return (spread3((unsigned)bi) << 2) | (spread3((unsigned)bj) << 1) | spread3((unsigned)bk);
}
__device__ __forceinline__ int cell_code(int i, int j, int k) { return ((i & 3) << 4) | ((j & 3) << 2) | (k & 3); }
__device__ __forceinline__ int nb_slot(int di, int dj, int dk) { return (di + 1) * 9 + (dj + 1) * 3 + (dk + 1); }

__device__ __forceinline__ vec3 load_v3(const real* s, unsigned cap, int f, unsigned i) {
    return make_v3(s[f * cap + i], s[(f + 1) * cap + i], s[(f + 2) * cap + i]);
}
__device__ __forceinline__ void store_v3(real* s, unsigned cap, int f, unsigned i, vec3 v) {
    s[f * cap + i] = v.x; s[(f + 1) * cap + i] = v.y; s[(f + 2) * cap + i] = v.z;
}
__device__ __forceinline__ mat3 load_m3(const real* s, unsigned cap, int f, unsigned i) {
    mat3 m; for (int c = 0; c < 9; ++c) m.m[c] = s[(f + c) * cap + i]; return m;
}
__device__ __forceinline__ void store_m3(real* s, unsigned cap, int f, unsigned i, const mat3& m) {
    for (int c = 0; c < 9; ++c) s[(f + c) * cap + i] = m.m[c];
}

// The deformation gradient of particle i. A fluid's F is always J^(1/3) I (fluid_project; the
// host uploads it in that form, src/state.rs), so the kernel variant for scenes that are all
// fluid (ALL_FLUID in g2p_particle.cuh) reads one word of F and writes the three diagonal ones
// (the zero off-diagonal words are never touched): 4 words moved for F per step instead of 18.
__device__ __forceinline__ mat3 load_deformation(const real* s, unsigned cap, unsigned i, bool fluid) {
    if (fluid) return mat3_diag(make_v3s(s[F_F * cap + i]));
    return load_m3(s, cap, F_F, i);
}
__device__ __forceinline__ void store_deformation(real* s, unsigned cap, unsigned i, const mat3& f, bool fluid) {
    if (fluid) {
        s[F_F * cap + i] = f.m[0];
        s[(F_F + 4) * cap + i] = f.m[4];
        s[(F_F + 8) * cap + i] = f.m[8];
    } else {
        store_m3(s, cap, F_F, i, f);
    }
}
// Integer field of the state (material id, original index): its bits in the low 32 bits of the word.
__device__ __forceinline__ unsigned state_bits(real w) {
#ifdef RTMPM_F64
    return (unsigned)__double_as_longlong(w);
#else
    return __float_as_uint(w);
#endif
}

// Grid coordinate, stencil base and fractional offset of a position (shape.rs).
__device__ __forceinline__ void stencil_of(const Ctx& c, vec3 x, int base[3], real fx[3]) {
    real xg[3] = {(x.x - c.origin[0]) * c.inv_dx, (x.y - c.origin[1]) * c.inv_dx, (x.z - c.origin[2]) * c.inv_dx};
    for (int a = 0; a < 3; ++a) {
        real b = floor(xg[a] - (real)0.5);
        base[a] = (int)b;
        fx[a] = xg[a] - b;
    }
}
// Stencil of a particle for the active transfer: base node, fractional offset, per-axis weights
// w[axis][node] and derivatives d[axis][node] (d w / d fx). Weight of node (i, j, k):
// w[0][i] w[1][j] w[2][k]; its gradient: shape_grad(w, d, i, j, k) * inv_dx. The per-(particle,
// node) interface every P2G/G2P variant can use (rtmpm_core::shape::Stencil::for_transfer).
__device__ __forceinline__ void particle_stencil(const Ctx& c, vec3 x, int base[3], real fx[3], real w[3][3], real d[3][3]) {
    stencil_of(c, x, base, fx);
    for (int a = 0; a < 3; ++a) shape_1d(c.transfer, fx[a], w[a], d[a]);
}

// Node addressing of one particle's 3x3x3 stencil, split per axis once (rtmpm_core's
// BlockLayout::stencil_nodes): node (i, j, k) lives at
// neighbors[27 g + slot[0][i] + slot[1][j] + slot[2][k]] * 64 + (cell[0][i] | cell[1][j] | cell[2][k]).
struct StencilIdx { int slot[3][3]; unsigned cell[3][3]; };
__device__ __forceinline__ StencilIdx stencil_idx(const int* bc, const int base[3]) {
    StencilIdx s;
    const int stride[3] = {9, 3, 1}, shift[3] = {4, 2, 0};
    for (int a = 0; a < 3; ++a)
        for (int n = 0; n < 3; ++n) {
            int r = base[a] + n - 4 * bc[a];
            s.slot[a][n] = ((r >> 2) + 1) * stride[a];
            s.cell[a][n] = (unsigned)(r & 3) << shift[a];
        }
    return s;
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

// G2P2G: does this step's grid still need its P2G (and the clear before it)? Always without
// G2P2G; with it only after a rebuild (new mapping) or when the host asked (first step, new dt):
// otherwise the previous step's fused kernel has already scattered the particles into it.
// Read only in kernels launched after the one that sets CTL_REBUILT_NOW.
__device__ __forceinline__ bool grid_needs_p2g(const Ctx& c) {
    return !c.grid_next || c.ctl[CTL_REBUILT_NOW] || c.ctl[CTL_P2G_PENDING];
}
