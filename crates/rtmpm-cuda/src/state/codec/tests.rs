use super::*;
use proptest::prelude::*;

/// The generic block codec on three components with 18-bit mantissas (a velocity-like vector):
/// the routine C's format uses, tested at another width.
const V_BITS: u32 = 18;
fn round_v(v: [f32; 3]) -> [f32; 3] {
    let (code, q) = encode(&v, V_BITS);
    decode(code, &q)
}
fn code_v(v: [f32; 3]) -> u32 {
    encode(&v, V_BITS).0
}

/// Every component of `x'` within the stated bound of `x`.
fn within<const N: usize>(x: &[f32; N], y: &[f32; N], b: u32) -> Result<(), String> {
    let m = x.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let tol = bound(m, b);
    for (a, r) in x.iter().zip(y) {
        let err = (*a as f64 - *r as f64).abs();
        if err > tol || !r.is_finite() {
            return Err(format!("{x:?} -> {y:?}: error {err:e} > {tol:e}"));
        }
    }
    Ok(())
}

#[test]
fn bounds_are_as_documented() {
    // 7.63e-6 and 3.05e-5 of the largest magnitude.
    assert!((bound(1.0, V_BITS) - 1.0 / 131071.0).abs() < 1e-15);
    assert!((bound(1.0, C_BITS) - 1.0 / 32767.0).abs() < 1e-15);
    assert_eq!(bound(0.0, V_BITS), 2f64.powi(-126));
}

#[test]
fn zeros_and_exact_values_round_trip_exactly() {
    assert_eq!(round_v([0.0; 3]), [0.0; 3]);
    assert_eq!(round_c([0.0; 9]), [0.0; 9]);
    // -0 decodes as +0.
    assert_eq!(round_v([-0.0; 3])[0].to_bits(), 0);
    // Values with few significant bits at the largest's scale are exact.
    assert_eq!(round_v([1.0, -0.5, 0.25]), [1.0, -0.5, 0.25]);
    assert_eq!(round_v([3.0, 0.0, -2.0]), [3.0, 0.0, -2.0]);
    let c = [1.0, -2.0, 0.5, 0.0, 4.0, -0.125, 3.0, 0.0, -1.0];
    assert_eq!(round_c(c), c);
    // The largest magnitude keeps its value when it has at most B-1 significant bits.
    assert_eq!(round_v([131071.0, 1.0, 0.0])[0], 131071.0);
}

#[test]
fn known_errors() {
    // 1 + 2^-20 at the scale of 1 (steps of 2^-16): rounds to 1.
    let v = round_v([1.0 + 2f32.powi(-20), 0.0, 0.0]);
    assert_eq!(v[0], 1.0);
    // A small component next to a large one loses its low bits: 1e-7 next to 1 is 0.
    assert_eq!(round_v([1.0, 1e-7, 0.0])[1], 0.0);
    // Rounding past the largest mantissa bumps the exponent: 2 - 2^-20 -> 2.
    let v = round_v([2.0 - 2f32.powi(-20), 0.0, 0.0]);
    assert_eq!(v[0], 2.0);
    within(&[2.0 - 2f32.powi(-20), 0.0, 0.0], &v, V_BITS).unwrap();
    // Round half to even: 1 + 2^-16 is half a step (2^-15 at the scale of 2) above 1.
    let x = [2.0, 1.0 + 2f32.powi(-16), 0.0];
    let v = round_v(x);
    assert_eq!(v[1], 1.0);
}

#[test]
fn denormal_huge_and_extreme_values() {
    let tiny = f32::from_bits(1); // 2^-149
    for x in [
        [tiny, -tiny, 0.0],
        [f32::MIN_POSITIVE, tiny, -f32::MIN_POSITIVE / 3.0],
        [1e-30, -3e-31, 7e-32],
        [1e30, -2e29, 5.0],
        [f32::MAX, -f32::MAX, 1.0],
        [3.0e38, 1.0, -3.0e38],
        [f32::MAX / 2.0, f32::MAX / 4.0, 0.0],
    ] {
        within(&x, &round_v(x), V_BITS).unwrap();
    }
    let mut c = [0.0f32; 9];
    c[4] = f32::MAX;
    c[7] = -1e38;
    within(&c, &round_c(c), C_BITS).unwrap();
    c = [tiny; 9];
    within(&c, &round_c(c), C_BITS).unwrap();
    // Denormals alone decode to the 2^-126 grid: within 2^-127.
    assert_eq!(round_v([tiny, 0.0, 0.0])[0], 0.0);
}

#[test]
fn non_finite_components_make_every_component_nan() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert!(round_v([1.0, bad, 0.0]).iter().all(|v| v.is_nan()));
        let mut c = [0.5f32; 9];
        c[8] = bad;
        assert!(round_c(c).iter().all(|v| v.is_nan()));
    }
    assert_eq!(code_v([f32::NAN, 0.0, 0.0]), NONFINITE);
}

#[test]
fn the_formats_fill_the_documented_bits() {
    // -1 at scale 2^(1 - 18 + 1): e = 1, code = 1 - (18 - 127) = 110.
    assert_eq!(code_v([-1.0, 1.0, -0.75]), 110);
    let c = encode_c([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]);
    assert_eq!(c[0] & 0xff, 112); // e = 1: 1 - (16 - 127)
    assert_eq!(c[0] >> 16, 1 << 14);
    assert_eq!(c[4] >> 16, (1 << 16) - (1 << 14)); // q8 = -16384
    assert_eq!(c[0] >> 8 & 0xff, 0); // bits 8-15 unused
}

proptest! {
    #[test]
    fn three_component_round_trip_within_bound(
        a in prop::num::f32::ANY, b in prop::num::f32::ANY, c in prop::num::f32::ANY,
        scale in -40i32..40,
    ) {
        let x = [a, b, c].map(|v| if v.is_finite() { v } else { 0.0 });
        // Mixed magnitudes: a second vector scaled by 2^scale per component (finite only).
        let y = [x[0], x[1] * 2f32.powi(scale), x[2] * 2f32.powi(-scale)];
        for v in [x, y] {
            if v.iter().all(|e| e.is_finite()) {
                prop_assert!(within(&v, &round_v(v), V_BITS).is_ok(), "{:?}", within(&v, &round_v(v), V_BITS));
                // Encoding is idempotent: a decoded vector encodes to the same words.
                prop_assert_eq!(encode(&round_v(v), V_BITS), encode(&v, V_BITS));
            }
        }
    }

    #[test]
    fn affine_round_trip_within_bound(
        m in prop::array::uniform9(-1.0e4f32..1.0e4),
        e in -60i32..60,
    ) {
        let c = m.map(|v| v * 2f32.powi(e));
        prop_assert!(within(&c, &round_c(c), C_BITS).is_ok(), "{:?}", within(&c, &round_c(c), C_BITS));
        prop_assert_eq!(encode_c(round_c(c)), encode_c(c));
    }
}
