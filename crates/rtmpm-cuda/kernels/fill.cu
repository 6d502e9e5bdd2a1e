// The particle state of sampled bodies filled on the device (host side: src/fill.rs): the host
// uploads only the positions, a piece of one body at a time, and a table of what every particle
// of a body shares (row layout FT_* in contract.cuh); each thread writes the 29 words of one
// particle, word for word what the host packing writes (src/state.rs, pack_bodies). The velocity
// v0 + w x (x - c) is computed in f32 with the host's operations in the host's order (glam's
// Vec3::cross), each rounded on its own: inline PTX add/sub/mul with .rn, never contracted into
// an fma, and without the flush-to-zero modifier, so that subnormals survive --use_fast_math as they do on the host.
#include "common.cuh"

__device__ __forceinline__ float fill_add(float a, float b) {
    float r;
    asm("add.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b));
    return r;
}
__device__ __forceinline__ float fill_sub(float a, float b) {
    float r;
    asm("sub.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b));
    return r;
}
__device__ __forceinline__ float fill_mul(float a, float b) {
    float r;
    asm("mul.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b));
    return r;
}
// An f32 value as a state word (the f64 widening is exact; a cvt that does not flush keeps subnormals).
__device__ __forceinline__ real fill_word(float a) {
#ifdef RTMPM_F64
    double r;
    asm("cvt.f64.f32 %0, %1;" : "=d"(r) : "f"(a));
    return r;
#else
    return a;
#endif
}
// An integer field's word (the inverse of state_bits: the bits in the low 32 bits of the word).
__device__ __forceinline__ real fill_bits(unsigned b) {
#ifdef RTMPM_F64
    return __longlong_as_double((long long)(unsigned long long)b);
#else
    return __uint_as_float(b);
#endif
}
__device__ __forceinline__ real fill_table_word(const unsigned* t, int w) { return fill_word(__uint_as_float(t[w])); }

// Particles offset..offset+len of body `body` (table row), whose positions are xs[3k..3k+3]
// (f32), into slots start+offset+k of the state (stride cap); their original index is their slot.
extern "C" __global__ void fill_body(real* __restrict__ s, unsigned cap, const unsigned* __restrict__ table, int body,
                                     unsigned long long offset, unsigned len, const float* __restrict__ xs) {
    const unsigned* t = table + (unsigned long long)body * FILL_WORDS;
    unsigned long long start = (unsigned long long)t[FT_START] | ((unsigned long long)t[FT_START + 1] << 32);
    float v0[3], w[3], c[3];
    for (int a = 0; a < 3; ++a) {
        v0[a] = __uint_as_float(t[FT_V0 + a]);
        w[a] = __uint_as_float(t[FT_W + a]);
        c[a] = __uint_as_float(t[FT_CENTRE + a]);
    }
    for (unsigned k = blockIdx.x * blockDim.x + threadIdx.x; k < len; k += gridDim.x * blockDim.x) {
        unsigned i = (unsigned)(start + offset + k);
        float x[3], d[3];
        for (int a = 0; a < 3; ++a) {
            x[a] = xs[3ull * k + a];
            d[a] = fill_sub(x[a], c[a]);
        }
        // glam: w.cross(d) = (w.y d.z - d.y w.z, w.z d.x - d.z w.x, w.x d.y - d.x w.y).
        float r[3] = {fill_sub(fill_mul(w[1], d[2]), fill_mul(d[1], w[2])),
                      fill_sub(fill_mul(w[2], d[0]), fill_mul(d[2], w[0])),
                      fill_sub(fill_mul(w[0], d[1]), fill_mul(d[0], w[1]))};
        for (int a = 0; a < 3; ++a) {
            s[sidx(cap, F_X + a, i)] = fill_word(x[a]);
            s[sidx(cap, F_V + a, i)] = fill_word(fill_add(v0[a], r[a]));
        }
        for (int e = 0; e < 9; ++e) {
            s[sidx(cap, F_C + e, i)] = fill_table_word(t, FT_C + e);
            s[sidx(cap, F_F + e, i)] = fill_table_word(t, FT_F + e);
        }
        s[sidx(cap, F_PLASTIC, i)] = fill_table_word(t, FT_PLASTIC);
        s[sidx(cap, F_MASS, i)] = fill_table_word(t, FT_MASS);
        s[sidx(cap, F_VOL0, i)] = fill_table_word(t, FT_VOL0);
        s[sidx(cap, F_MAT, i)] = fill_bits(t[FT_MAT]);
        s[sidx(cap, F_ID, i)] = fill_bits(i);
    }
}
