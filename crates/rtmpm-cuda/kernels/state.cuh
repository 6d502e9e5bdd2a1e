// Field accessors of the particle state, for every layout (src/contract/state_layout.rs; the
// prelude defines F_*, RTMPM_NFIELDS, RTMPM_STATE_FLUID and RTMPM_STATE_COMPACT). Kernels read and
// write the particle's fields through these only (x, mass, vol0, material and id are plain words
// of every layout: load_v3 / sidx).
//
// RTMPM_STATE_FLUID (every material a fluid, whose F is J^(1/3) I: fluid_project, src/state/fields.rs):
// F is the one word J^(1/3) (F's diagonal), there is no plastic word. Storing F's diagonal value,
// not J, keeps every kernel path bit-identical to the 29-word layout (the general kernel variants
// also run fluid scenes when G2P2G is off) and costs no cube root on load.
// RTMPM_STATE_COMPACT: C in the shared-exponent words of codec.cuh (f32 only).
#pragma once
#include "codec.cuh"

__device__ __forceinline__ unsigned state_word_bits(const real* s, unsigned cap, int f, unsigned i) {
    return state_bits(state_ld(s, sidx(cap, f, i)));
}
#if RTMPM_STATE_COMPACT
__device__ __forceinline__ void state_set_bits(real* s, unsigned cap, int f, unsigned i, unsigned b) {
    state_st(s, sidx(cap, f, i), __uint_as_float(b));
}
#endif

// Velocity: 3 reals in every layout (the compact state keeps v in f32: src/state/codec/mod.rs says why).
__device__ __forceinline__ vec3 load_vel(const real* s, unsigned cap, unsigned i) { return load_v3(s, cap, F_V, i); }
// Store v; returns the velocity a load now gives.
__device__ __forceinline__ vec3 store_vel(real* s, unsigned cap, unsigned i, vec3 v) {
    store_v3(s, cap, F_V, i, v);
    return v;
}

// APIC C (or the classic transfers' velocity gradient).
__device__ __forceinline__ mat3 load_affine(const real* s, unsigned cap, unsigned i) {
#if RTMPM_STATE_COMPACT
    unsigned w[5];
    for (int k = 0; k < 5; ++k) w[k] = state_word_bits(s, cap, F_C + k, i);
    mat3 m;
    codec_decode_c(w, m.m);
    return m;
#else
    return load_m3(s, cap, F_C, i);
#endif
}
// Store C; returns what a load now gives.
__device__ __forceinline__ mat3 store_affine(real* s, unsigned cap, unsigned i, const mat3& c) {
#if RTMPM_STATE_COMPACT
    unsigned w[5];
    codec_encode_c(c.m, w);
    for (int k = 0; k < 5; ++k) state_set_bits(s, cap, F_C + k, i, w[k]);
    mat3 m;
    codec_decode_c(w, m.m);
    return m;
#else
    store_m3(s, cap, F_C, i, c);
    return c;
#endif
}

// The deformation gradient of particle i. A fluid's F is always J^(1/3) I (fluid_project; the
// host uploads it in that form, src/state/fields.rs), so the kernel variant for scenes that are all
// fluid (ALL_FLUID in g2p/particle.cuh) reads one word of F and writes the three diagonal ones
// (the zero off-diagonal words are never touched): 4 words moved for F per step instead of 18.
// In a fluid layout F is that one word, for every variant.
__device__ __forceinline__ mat3 load_deformation(const real* s, unsigned cap, unsigned i, bool fluid) {
#if RTMPM_STATE_FLUID
    (void)fluid;
    return mat3_diag(make_v3s(state_ld(s, sidx(cap, F_F, i))));
#else
    if (fluid) return mat3_diag(make_v3s(state_ld(s, sidx(cap, F_F, i))));
    return load_m3(s, cap, F_F, i);
#endif
}
__device__ __forceinline__ void store_deformation(real* s, unsigned cap, unsigned i, const mat3& f, bool fluid) {
#if RTMPM_STATE_FLUID
    (void)fluid;
    state_st(s, sidx(cap, F_F, i), f.m[0]);
#else
    if (fluid) {
        state_st(s, sidx(cap, F_F, i), f.m[0]);
        state_st(s, sidx(cap, F_F + 4, i), f.m[4]);
        state_st(s, sidx(cap, F_F + 8, i), f.m[8]);
    } else {
        store_m3(s, cap, F_F, i, f);
    }
#endif
}

// The plastic scalar (0 in a fluid layout, which has no plastic word).
__device__ __forceinline__ real load_plastic(const real* s, unsigned cap, unsigned i) {
#if RTMPM_STATE_FLUID
    (void)s; (void)cap; (void)i;
    return (real)0;
#else
    return state_ld(s, sidx(cap, F_PLASTIC, i));
#endif
}
__device__ __forceinline__ void store_plastic(real* s, unsigned cap, unsigned i, real p) {
#if RTMPM_STATE_FLUID
    (void)s; (void)cap; (void)i; (void)p;
#else
    state_st(s, sidx(cap, F_PLASTIC, i), p);
#endif
}

// Export codes (src/export/chunks.rs: chunk_fields): a word of a frame column. code >= 0: the
// state word `code` as float bits (an f64 state rounded to nearest), or the material's integer
// bits for F_MAT; code < 0: EXPORT_C + k or EXPORT_F + k for component k of the decoded C or F,
// EXPORT_ZERO for an absent field (a fluid layout's plastic word).
#define EXPORT_ZERO (-1)
#define EXPORT_C (-32)
#define EXPORT_F (-48)
__device__ __forceinline__ unsigned export_word(const real* s, unsigned cap, unsigned i, int code) {
    if (code >= 0) {
        real v = s[sidx(cap, code, i)];
        return code == F_MAT ? state_bits(v) : __float_as_uint((float)v);
    }
    if (code >= EXPORT_C && code < EXPORT_C + 9) return __float_as_uint((float)load_affine(s, cap, i).m[code - EXPORT_C]);
    if (code >= EXPORT_F && code < EXPORT_F + 9) return __float_as_uint((float)load_deformation(s, cap, i, false).m[code - EXPORT_F]);
    return 0u;
}
