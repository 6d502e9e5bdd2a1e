//! The shared-exponent codec of the compact particle state (twin of `kernels/codec.cuh`, bit for
//! bit where the device does not flush denormals): `N` values as `N` signed `B`-bit mantissas
//! `q_i` and one 8-bit exponent code, value `q_i 2^(e - B + 1)` (the block floating point of
//! QuanTaichi's shared-exponent types: Hu et al., "QuanTaichi: A Compiler for Quantized
//! Simulations", SIGGRAPH 2021).
//!
//! - APIC C: `N` = 9, `B` = 16, in 5 words (word 0: code in bits 0-7, `q_0` in bits 16-31; word
//!   k = 1..4: `q_(2k-1)` in bits 0-15, `q_(2k)` in bits 16-31).
//!
//! The velocity stays in f32: a shared-exponent velocity (3 x 18 bits in 2 words, error 7.6e-6 of
//! the largest component) was measured and dropped: the particle carries v from step to step
//! (the grid adds only g dt in free fall), so its rounding error walks, and the free-fall
//! validation case missed its bound by 6 % on the H100 (position error 1.05e-3 m against
//! 0.99e-3 m; f32 0.98e-3 m; validation/RESULTS.md "Compact particle state").
//!
//! Encoding: `e` is the exponent with the largest magnitude `m < 2^e` (at least `B - 127`, so
//! that the decoding scale `2^(e - B + 1)` is a normal float), `q_i = round_ties_even(x_i 2^(B -
//! 1 - e))`; if the largest `|q_i|` is `2^(B-1)` (rounding up), `e` is bumped once (saturated
//! next to `f32::MAX`). Stored: `e - (B - 127)`; code 255: a component is NaN or infinite, and
//! every component decodes as NaN (the kernels' health check has flagged the particle already).
//!
//! **Error bound** (finite input, [`bound`]): every component
//! `|x'_i - x_i| <= max(m / (2^(B-1) - 1), 2^-126)`, `m` the largest magnitude: 3.05e-5 m for
//! C. Zero decodes as +0 exactly. On the device (`--use_fast_math` flushes denormals) a denormal input
//! reads as 0, within the same bound.

/// Exponent code of a non-finite vector.
pub const NONFINITE: u32 = 255;
/// Mantissa bits of C.
pub const C_BITS: u32 = 16;

/// 2^k, -126 <= k <= 127.
fn pow2(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

/// The mantissas (`q`) and exponent code of `x` with `b`-bit mantissas.
fn encode<const N: usize>(x: &[f32; N], b: u32) -> (u32, [i32; N]) {
    let qmax = (1i32 << (b - 1)) - 1;
    let emin = b as i32 - 127;
    let mut q = [0i32; N];
    if x.iter().any(|v| !v.is_finite()) {
        return (NONFINITE, q);
    }
    let m = x.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let mut e = ((((m.to_bits() >> 23) & 0xff) as i32) - 126).max(emin);
    for pass in 0..2 {
        let s = pow2(b as i32 - 1 - e);
        for (qi, xi) in q.iter_mut().zip(x) {
            *qi = (xi * s).round_ties_even() as i32;
        }
        let big = q.iter().map(|v| v.abs()).max().unwrap_or(0);
        if big <= qmax {
            break;
        }
        if pass == 1 || e >= 128 {
            for qi in &mut q {
                *qi = (*qi).clamp(-qmax, qmax);
            }
            break;
        }
        e += 1;
    }
    ((e - emin) as u32, q)
}

/// The values of exponent code `code` and mantissas `q`.
fn decode<const N: usize>(code: u32, q: &[i32; N]) -> [f32; N] {
    if code == NONFINITE {
        return [f32::NAN; N];
    }
    // 2^(e - B + 1) with e = code + B - 127.
    let s = pow2(code as i32 - 126);
    q.map(|v| v as f32 * s)
}

/// C's five words (`c` column-major).
pub fn encode_c(c: [f32; 9]) -> [u32; 5] {
    let (code, q) = encode(&c, C_BITS);
    let h = |v: i32| (v as u32) & 0xffff;
    let mut w = [code | h(q[0]) << 16, 0, 0, 0, 0];
    for k in 1..5 {
        w[k] = h(q[2 * k - 1]) | h(q[2 * k]) << 16;
    }
    w
}

/// C of five words.
pub fn decode_c(w: [u32; 5]) -> [f32; 9] {
    let mut q = [0i32; 9];
    q[0] = (w[0] as i32) >> 16;
    for k in 1..5 {
        q[2 * k - 1] = ((w[k] << 16) as i32) >> 16;
        q[2 * k] = (w[k] as i32) >> 16;
    }
    decode(w[0] & 0xff, &q)
}

/// The stated error bound of a component of a vector whose largest magnitude is `m`, with
/// `b`-bit mantissas: `max(m / (2^(b-1) - 1), 2^-126)`.
pub fn bound(m: f32, b: u32) -> f64 {
    (m as f64 / ((1u64 << (b - 1)) - 1) as f64).max(2f64.powi(-126))
}

/// `c` as the compact state keeps it.
pub fn round_c(c: [f32; 9]) -> [f32; 9] {
    decode_c(encode_c(c))
}

#[cfg(test)]
mod tests;
