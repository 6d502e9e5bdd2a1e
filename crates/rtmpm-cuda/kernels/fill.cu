// The particle state of sampled bodies filled on the device (host side: src/setup/fill/mod.rs): the host
// uploads only the positions, a piece of one body at a time, and a table of what every particle
// of a body shares (row layout FT_* in contract.cuh); each thread writes the 29 words of one
// particle, word for word what the host packing writes (src/state/pack.rs, pack_bodies). The velocity
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
// A word from its bits in the state's precision (an f32 word's in the low 32 bits).
__device__ __forceinline__ real fill_raw(unsigned lo, unsigned hi) {
#ifdef RTMPM_F64
    return __longlong_as_double((long long)(((unsigned long long)hi << 32) | lo));
#else
    return __uint_as_float(lo);
#endif
}

// Particles offset..offset+len of body `body` (table row), whose positions are xs[3k..3k+3]
// (f32), into slots start+offset+k of the state (stride cap); their original index is their slot.
// The layout's words: x at x_word.., the velocity at v_word.. (3 reals in every layout), the id
// at id_word; every other word is one of the row's constants (FT_NCONST of them from FT_CONST:
// word, low bits, high bits).
extern "C" __global__ void fill_body(real* __restrict__ s, unsigned cap, const unsigned* __restrict__ table, int body,
                                     unsigned long long offset, unsigned len, const float* __restrict__ xs, int x_word,
                                     int v_word, int id_word) {
    const unsigned* t = table + (unsigned long long)body * FILL_WORDS;
    unsigned long long start = (unsigned long long)t[FT_START] | ((unsigned long long)t[FT_START + 1] << 32);
    float v0[3], w[3], c[3];
    for (int a = 0; a < 3; ++a) {
        v0[a] = __uint_as_float(t[FT_V0 + a]);
        w[a] = __uint_as_float(t[FT_W + a]);
        c[a] = __uint_as_float(t[FT_CENTRE + a]);
    }
    int nconst = (int)t[FT_NCONST];
    for (unsigned k = blockIdx.x * blockDim.x + threadIdx.x; k < len; k += gridDim.x * blockDim.x) {
        unsigned i = (unsigned)(start + offset + k);
        float x[3];
        for (int a = 0; a < 3; ++a) {
            x[a] = xs[3ull * k + a];
            s[sidx(cap, x_word + a, i)] = fill_word(x[a]);
        }
        float d[3];
        for (int a = 0; a < 3; ++a) d[a] = fill_sub(x[a], c[a]);
        // glam: w.cross(d) = (w.y d.z - d.y w.z, w.z d.x - d.z w.x, w.x d.y - d.x w.y).
        float r[3] = {fill_sub(fill_mul(w[1], d[2]), fill_mul(d[1], w[2])),
                      fill_sub(fill_mul(w[2], d[0]), fill_mul(d[2], w[0])),
                      fill_sub(fill_mul(w[0], d[1]), fill_mul(d[0], w[1]))};
        for (int a = 0; a < 3; ++a) s[sidx(cap, v_word + a, i)] = fill_word(fill_add(v0[a], r[a]));
        for (int e = 0; e < nconst; ++e) {
            const unsigned* q = t + FT_CONST + 3 * e;
            s[sidx(cap, (int)q[0], i)] = fill_raw(q[1], q[2]);
        }
        s[sidx(cap, id_word, i)] = fill_bits(i);
    }
}
