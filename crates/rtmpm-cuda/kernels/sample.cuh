// The walk of a deferred body, drawn on the device (host side: src/setup/sample/mod.rs): the positions the
// host's walk finds (rtmpm-scene/src/walk.rs, `Lattice::rows`), in the same order, bit for
// bit. Row r of the body's sub-cell lattice is (j, k) = (j0 + r % ny, k0 + r / ny); its points
// are i = i0 .. i0 + nx, at origin + (i + 1/2, j + 1/2, k + 1/2) h, each moved (jittered
// sampling) by (u - 1/2) h with three draws u of the body's PCG 128/64 stream (O'Neill 2014;
// rtmpm-scene/src/pcg.rs), which a row starts 3 r nx draws in (Brown's jump, 1994); a point
// is kept when it is inside the shape (its own test, geometry/<name>.cuh, in SpArith). Every f32
// operation is rounded on its own as on the host (never contracted into an fma, no flush to
// zero), so that --use_fast_math changes nothing. This header compiles for the CPU too (the unit
// tests of src/setup/sample/tests.rs: the walk, and every shape's distance, inside test and
// normal, against the host's).
#pragma once
#include "geometry/registry.cuh"

#if defined(__CUDACC__)
#define SP_FN __device__ __forceinline__
SP_FN float sp_add(float a, float b) { float r; asm("add.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN float sp_sub(float a, float b) { float r; asm("sub.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN float sp_mul(float a, float b) { float r; asm("mul.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN float sp_sqrt(float a) { float r; asm("sqrt.rn.f32 %0, %1;" : "=f"(r) : "f"(a)); return r; }
SP_FN float sp_max(float a, float b) { float r; asm("max.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN float sp_min(float a, float b) { float r; asm("min.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN float sp_abs(float a) { float r; asm("abs.f32 %0, %1;" : "=f"(r) : "f"(a)); return r; }
SP_FN float sp_i2f(long long a) { float r; asm("cvt.rn.f32.s64 %0, %1;" : "=f"(r) : "l"(a)); return r; }
SP_FN float sp_u2f(unsigned a) { float r; asm("cvt.rn.f32.u32 %0, %1;" : "=f"(r) : "r"(a)); return r; }
SP_FN unsigned long long sp_mulhi(unsigned long long a, unsigned long long b) { return __umul64hi(a, b); }
SP_FN float sp_bits(unsigned u) { return __uint_as_float(u); }
SP_FN float sp_div(float a, float b) { float r; asm("div.rn.f32 %0, %1, %2;" : "=f"(r) : "f"(a), "f"(b)); return r; }
SP_FN unsigned sp_u32_of(float f) { return __float_as_uint(f); }
// Comparisons and the float-to-integer conversion without the flush to zero that fast math gives
// them (a subnormal is compared as itself, as on the host).
#define SP_CMP(name, op)                                                                              \
    SP_FN bool name(float a, float b) {                                                               \
        unsigned r;                                                                                   \
        asm("{ .reg .pred p; setp." op ".f32 p, %1, %2; selp.u32 %0, 1, 0, p; }" : "=r"(r) : "f"(a), "f"(b)); \
        return r != 0;                                                                                \
    }
SP_CMP(sp_lt, "lt")
SP_CMP(sp_le, "le")
SP_CMP(sp_gt, "gt")
SP_CMP(sp_ge, "ge")
SP_CMP(sp_ne, "neu")
SP_FN unsigned sp_f2u(float a) { unsigned r; asm("cvt.rzi.u32.f32 %0, %1;" : "=r"(r) : "f"(a)); return r; }
SP_FN float sp_floor(float a) { float r; asm("cvt.rmi.f32.f32 %0, %1;" : "=f"(r) : "f"(a)); return r; }
#else
// The CPU twin: compile with -ffp-contract=off (and without -ffast-math).
#include <cmath>
#include <cstring>
#define SP_FN static inline
SP_FN float sp_add(float a, float b) { return a + b; }
SP_FN float sp_sub(float a, float b) { return a - b; }
SP_FN float sp_mul(float a, float b) { return a * b; }
SP_FN float sp_sqrt(float a) { return std::sqrt(a); }
SP_FN float sp_max(float a, float b) { return std::fmax(a, b); }
SP_FN float sp_min(float a, float b) { return std::fmin(a, b); }
SP_FN float sp_abs(float a) { return std::fabs(a); }
SP_FN float sp_i2f(long long a) { return (float)a; }
SP_FN float sp_u2f(unsigned a) { return (float)a; }
SP_FN unsigned long long sp_mulhi(unsigned long long a, unsigned long long b) {
    return (unsigned long long)(((unsigned __int128)a * b) >> 64);
}
SP_FN float sp_bits(unsigned u) {
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}
SP_FN float sp_div(float a, float b) { return a / b; }
SP_FN bool sp_lt(float a, float b) { return a < b; }
SP_FN bool sp_le(float a, float b) { return a <= b; }
SP_FN bool sp_gt(float a, float b) { return a > b; }
SP_FN bool sp_ge(float a, float b) { return a >= b; }
SP_FN bool sp_ne(float a, float b) { return a != b; }
SP_FN unsigned sp_f2u(float a) { return (unsigned)a; }
SP_FN unsigned sp_u32_of(float f) {
    unsigned u;
    std::memcpy(&u, &f, 4);
    return u;
}
SP_FN float sp_floor(float a) { return std::floor(a); }
#endif

typedef unsigned long long sp_u64;

// A 128-bit number, low and high words.
struct SpU128 {
    sp_u64 lo, hi;
};
SP_FN SpU128 sp_mul128(SpU128 a, SpU128 b) { return {a.lo * b.lo, sp_mulhi(a.lo, b.lo) + a.lo * b.hi + a.hi * b.lo}; }
SP_FN SpU128 sp_add128(SpU128 a, SpU128 b) {
    sp_u64 lo = a.lo + b.lo;
    return {lo, a.hi + b.hi + (lo < a.lo ? 1ull : 0ull)};
}

// PCG 128/64 (XSL RR): the state and the increment of rand_pcg's Lcg128Xsl64.
struct SpStream {
    SpU128 state, inc;
};
SP_FN SpU128 sp_pcg_multiplier() { return {0x4385DF649FCCF645ull, 0x2360ED051FC65DA4ull}; }

// Jump `delta` steps ahead: Brown, "Random number generation with arbitrary strides" (1994).
SP_FN void sp_advance(SpStream& s, sp_u64 delta) {
    SpU128 acc_mult = {1, 0}, acc_plus = {0, 0};
    SpU128 cur_mult = sp_pcg_multiplier(), cur_plus = s.inc;
    while (delta > 0) {
        if (delta & 1) {
            acc_mult = sp_mul128(acc_mult, cur_mult);
            acc_plus = sp_add128(sp_mul128(acc_plus, cur_mult), cur_plus);
        }
        cur_plus = sp_mul128(sp_add128(cur_mult, {1, 0}), cur_plus);
        cur_mult = sp_mul128(cur_mult, cur_mult);
        delta >>= 1;
    }
    s.state = sp_add128(sp_mul128(acc_mult, s.state), acc_plus);
}

// Step, then the XSL RR output of the new state.
SP_FN sp_u64 sp_next_u64(SpStream& s) {
    s.state = sp_add128(sp_mul128(s.state, sp_pcg_multiplier()), s.inc);
    unsigned rot = (unsigned)(s.state.hi >> 58);
    sp_u64 xsl = s.state.hi ^ s.state.lo;
    return rot == 0 ? xsl : (xsl >> rot) | (xsl << (64 - rot));
}

// rand 0.9's f32 in [0, 1): the top 24 of the low 32 bits, times 2^-24 (exact).
SP_FN float sp_next_f32(SpStream& s) {
    return sp_mul(sp_u2f((unsigned)sp_next_u64(s) >> 8), 1.0f / 16777216.0f);
}

// A recipe (the words SP_* of contract.cuh) as numbers.
struct SpRecipe {
    float origin[3], h;
    long long first[3];
    sp_u64 nx, ny;
    int jitter;
    SpStream rng;
    unsigned shape;  // SHAPE_* (geometry/registry.cuh)
    float p[8];
    unsigned dims[3];
    unsigned kind;
    float hi[3];
    sp_u64 tries;
    // A mesh's distances (x fastest), else null.
    const float* sdf;
};

SP_FN float sp_f32(const unsigned* w, int at) { return sp_bits(w[at]); }
SP_FN sp_u64 sp_word64(const unsigned* w, int at) { return (sp_u64)w[at] | ((sp_u64)w[at + 1] << 32); }

SP_FN SpRecipe sp_load(const unsigned* w, const float* sdf) {
    SpRecipe r;
    r.sdf = sdf;
    r.kind = w[SP_KIND];
    for (int a = 0; a < 3; ++a) r.hi[a] = sp_f32(w, SP_HI + a);
    r.tries = sp_word64(w, SP_TRIES);
    for (int a = 0; a < 3; ++a) {
        r.origin[a] = sp_f32(w, SP_ORIGIN + a);
        r.first[a] = (long long)sp_word64(w, SP_FIRST + 2 * a);
    }
    r.h = sp_f32(w, SP_H);
    r.nx = sp_word64(w, SP_NX);
    r.ny = sp_word64(w, SP_NY);
    r.jitter = (int)w[SP_JITTER];
    r.rng.state = {sp_word64(w, SP_STATE), sp_word64(w, SP_STATE + 2)};
    r.rng.inc = {sp_word64(w, SP_INC), sp_word64(w, SP_INC + 2)};
    r.shape = w[SP_SHAPE];
    for (int a = 0; a < 8; ++a) r.p[a] = sp_f32(w, SP_PARAMS + a);
    for (int a = 0; a < 3; ++a) r.dims[a] = w[SP_DIMS + a];
    return r;
}

// The sampler's arithmetic for the shapes' formulas (geometry/geometry.cuh): f32, each
// operation rounded on its own as on the host.
struct SpArith {
    typedef float T;
    static GEO_MEMBER float add(float a, float b) { return sp_add(a, b); }
    static GEO_MEMBER float sub(float a, float b) { return sp_sub(a, b); }
    static GEO_MEMBER float mul(float a, float b) { return sp_mul(a, b); }
    static GEO_MEMBER float div(float a, float b) { return sp_div(a, b); }
    static GEO_MEMBER float sqrt(float a) { return sp_sqrt(a); }
    static GEO_MEMBER float abs(float a) { return sp_abs(a); }
    static GEO_MEMBER float max(float a, float b) { return sp_max(a, b); }
    static GEO_MEMBER float min(float a, float b) { return sp_min(a, b); }
    static GEO_MEMBER float floor(float a) { return sp_floor(a); }
    static GEO_MEMBER bool lt(float a, float b) { return sp_lt(a, b); }
    static GEO_MEMBER bool le(float a, float b) { return sp_le(a, b); }
    static GEO_MEMBER bool gt(float a, float b) { return sp_gt(a, b); }
    static GEO_MEMBER bool ge(float a, float b) { return sp_ge(a, b); }
    static GEO_MEMBER bool ne(float a, float b) { return sp_ne(a, b); }
    static GEO_MEMBER float of(float a) { return a; }
    static GEO_MEMBER float of_u(unsigned a) { return sp_u2f(a); }
    static GEO_MEMBER unsigned to_u(float a) { return sp_f2u(a); }
};

// Shape::contains (rtmpm-geometry/src/shape/<name>.rs) of the recipe's shape, with the host's
// rounding: the shape's own test (geometry/<name>.cuh).
SP_FN bool sp_inside(const SpRecipe& R, const float* x) {
    GeoShape g;
    g.p = R.p;
    g.dims = R.dims;
    g.values = R.sdf;
    return shape_contains_of<SpArith>(R.shape, g, x);
}

// The points of row r inside the shape, in order: emit(x) for each. Random tries
// (rtmpm-scene/src/walk.rs, `RandomTries`): try t draws u (three f32 from 3 t draws in) and
// tries x = lo + u (hi - lo).
template <class Emit>
SP_FN void sp_row(const SpRecipe& R, sp_u64 r, Emit emit) {
    if (R.kind == SAMPLE_RANDOM) {
        sp_u64 t0 = r * SAMPLE_TRIES_PER_ROW;
        sp_u64 t1 = t0 + SAMPLE_TRIES_PER_ROW < R.tries ? t0 + SAMPLE_TRIES_PER_ROW : R.tries;
        SpStream rng = R.rng;
        sp_advance(rng, 3ull * t0);
        float ext[3] = {sp_sub(R.hi[0], R.origin[0]), sp_sub(R.hi[1], R.origin[1]), sp_sub(R.hi[2], R.origin[2])};
        for (sp_u64 t = t0; t < t1; ++t) {
            float x[3];
            for (int a = 0; a < 3; ++a) x[a] = sp_next_f32(rng);
            for (int a = 0; a < 3; ++a) x[a] = sp_add(R.origin[a], sp_mul(x[a], ext[a]));
            if (sp_inside(R, x)) emit(x);
        }
        return;
    }
    long long k = R.first[2] + (long long)(r / R.ny);
    long long j = R.first[1] + (long long)(r % R.ny);
    SpStream rng = R.rng;
    if (R.jitter) sp_advance(rng, 3ull * r * R.nx);
    float yk[2] = {sp_add(R.origin[1], sp_mul(sp_add(sp_i2f(j), 0.5f), R.h)),
                   sp_add(R.origin[2], sp_mul(sp_add(sp_i2f(k), 0.5f), R.h))};
    for (sp_u64 m = 0; m < R.nx; ++m) {
        long long i = R.first[0] + (long long)m;
        float x[3] = {sp_add(R.origin[0], sp_mul(sp_add(sp_i2f(i), 0.5f), R.h)), yk[0], yk[1]};
        if (R.jitter) {
            float u[3];
            for (int a = 0; a < 3; ++a) u[a] = sp_sub(sp_next_f32(rng), 0.5f);
            for (int a = 0; a < 3; ++a) x[a] = sp_add(x[a], sp_mul(u[a], R.h));
        }
        if (sp_inside(R, x)) emit(x);
    }
}
