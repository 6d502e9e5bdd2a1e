// Shared-exponent codec of the compact particle state (twin of src/state/codec/mod.rs, bit for bit when
// denormals are not flushed): N signed B-bit mantissas q_i and one 8-bit exponent code, value
// q_i 2^(e - B + 1). APIC C: N = 9, B = 16 in 5 words (the velocity stays f32: src/state/codec/mod.rs). The
// exponent e (the largest component < 2^e, at least B - 127, bumped once when the largest mantissa
// rounds past 2^(B-1) - 1) is stored as e - (B - 127); code 255: a component was not finite
// (every component decodes as NaN). Round to nearest even. Error of each component, finite input:
// |x' - x| <= max(max_j |x_j| / (2^(B-1) - 1), 2^-126).
// Pure float/integer code, no Ctx: compiled on its own by the codec test.
#pragma once

#define CODEC_NONFINITE 255u

// 2^k for -126 <= k <= 127.
__device__ __forceinline__ float codec_pow2(int k) { return __uint_as_float((unsigned)(k + 127) << 23); }

// Encode n values (B-bit mantissas) into q[] and return the exponent code.
template <int N, int B>
__device__ __forceinline__ unsigned codec_encode(const float* x, int* q) {
    const int qmax = (1 << (B - 1)) - 1, emin = B - 127;
    float m = 0.0f;
    bool finite = true;
    for (int i = 0; i < N; ++i) {
        finite = finite && isfinite(x[i]);
        m = fmaxf(m, fabsf(x[i]));
    }
    if (!finite) {
        for (int i = 0; i < N; ++i) q[i] = 0;
        return CODEC_NONFINITE;
    }
    int e = max((int)((__float_as_uint(m) >> 23) & 0xffu) - 126, emin);
    for (int pass = 0; pass < 2; ++pass) {
        float s = codec_pow2(B - 1 - e);
        int big = 0;
        for (int i = 0; i < N; ++i) {
            q[i] = (int)rintf(x[i] * s);
            big = max(big, abs(q[i]));
        }
        if (big <= qmax) break;
        if (pass == 1 || e >= 128) {  // only next to FLT_MAX: saturate
            for (int i = 0; i < N; ++i) q[i] = max(-qmax, min(qmax, q[i]));
            break;
        }
        ++e;
    }
    return (unsigned)(e - emin);
}

// The values of exponent code `code` and mantissas q[].
template <int N, int B>
__device__ __forceinline__ void codec_decode(unsigned code, const int* q, float* x) {
    if (code == CODEC_NONFINITE) {
        for (int i = 0; i < N; ++i) x[i] = __uint_as_float(0x7fc00000u);
        return;
    }
    float s = codec_pow2((int)code - 126);  // 2^(e - B + 1), e = code + B - 127
    for (int i = 0; i < N; ++i) x[i] = (float)q[i] * s;
}

// C: 5 words; word 0: the code (bits 0-7) and q0 (bits 16-31); word k = 1..4: q(2k-1) in bits 0-15,
// q(2k) in bits 16-31 (16-bit two's complement).
// The same words as codec_encode<9, 16> / codec_decode<9, 16> give, without the float-integer
// conversions (a quarter of the FP32 rate on the GPU; the compact state's cost in the fused
// kernel): rounding by the float adder, t = y + 1.5 2^23 holds 2^22 + rint_even(y) in its
// mantissa for |y| < 2^22, so its low 16 bits are q's two's complement; a mantissa overflows iff
// m s >= 2^15 - 1/2 (the largest |q| is rint_even(m s)); decoding puts the biased mantissa
// q + 2^15 = bits ^ 0x8000 under the exponent of 2^23 and subtracts 2^23 + 2^15 (exact).
#define CODEC_ROUND_MAGIC 12582912.0f  // 1.5 2^23
#define CODEC_DECODE_BIAS 8421376.0f   // 2^23 + 2^15
__device__ __forceinline__ unsigned codec_q16(float y) {
    return __float_as_uint(y + CODEC_ROUND_MAGIC) & 0xffffu;
}
__device__ __forceinline__ float codec_from16(unsigned h) {
    return __uint_as_float(0x4b000000u | ((h & 0xffffu) ^ 0x8000u)) - CODEC_DECODE_BIAS;
}
__device__ __forceinline__ void codec_encode_c(const float c[9], unsigned w[5]) {
    const int emin = 16 - 127;
    float m = 0.0f;
    bool finite = true;
    for (int i = 0; i < 9; ++i) {
        finite = finite && isfinite(c[i]);
        m = fmaxf(m, fabsf(c[i]));
    }
    if (!finite) {
        for (int k = 0; k < 5; ++k) w[k] = 0u;
        w[0] = CODEC_NONFINITE;
        return;
    }
    int e = max((int)((__float_as_uint(m) >> 23) & 0xffu) - 126, emin);
    float s = codec_pow2(15 - e);
    if (m * s >= 32767.5f) {
        if (e >= 128) {  // only next to FLT_MAX: the generic path saturates
            int q[9];
            unsigned code = codec_encode<9, 16>(c, q);
            w[0] = code | ((unsigned)(q[0] & 0xffff) << 16);
            for (int k = 1; k < 5; ++k) w[k] = (unsigned)(q[2 * k - 1] & 0xffff) | ((unsigned)(q[2 * k] & 0xffff) << 16);
            return;
        }
        ++e;
        s = codec_pow2(15 - e);
    }
    w[0] = (unsigned)(e - emin) | (codec_q16(c[0] * s) << 16);
    for (int k = 1; k < 5; ++k) w[k] = codec_q16(c[2 * k - 1] * s) | (codec_q16(c[2 * k] * s) << 16);
}
__device__ __forceinline__ void codec_decode_c(const unsigned w[5], float c[9]) {
    unsigned code = w[0] & 0xffu;
    if (code == CODEC_NONFINITE) {
        for (int i = 0; i < 9; ++i) c[i] = __uint_as_float(0x7fc00000u);
        return;
    }
    float s = codec_pow2((int)code - 126);
    c[0] = codec_from16(w[0] >> 16) * s;
    for (int k = 1; k < 5; ++k) {
        c[2 * k - 1] = codec_from16(w[k]) * s;
        c[2 * k] = codec_from16(w[k] >> 16) * s;
    }
}
