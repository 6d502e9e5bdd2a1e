//! The words of the fields that a layout keeps in other forms than plain reals (C in the
//! compact format, F in one word in a fluid layout), packed and read back.

use super::word::Word;
use crate::contract::StateLayout;
use crate::state::codec;
use rtmpm_physics::math::{Mat3, Vec3};

/// A fluid layout holds fluids only; a compact one is single precision.
pub(super) fn check_layout(fluid: &[bool], layout: StateLayout, f64: bool) -> Result<(), String> {
    if layout.fluid() && !fluid.iter().all(|f| *f) {
        return Err("CUDA backend: the fluid state layout needs every material a fluid".into());
    }
    if layout.compact() && f64 {
        return Err("CUDA backend: the compact particle state is single precision only".into());
    }
    Ok(())
}

/// A fluid particle's F in its packed form, J^(1/3) I; a solid's as it is.
pub(crate) fn packed_f(f: Mat3, fluid: bool) -> Mat3 {
    if fluid {
        Mat3::from_diagonal(Vec3::splat(f.determinant().cbrt()))
    } else {
        f
    }
}

/// The words of a velocity (3 reals in every layout), and how many there are.
pub(super) fn v_words<W: Word>(_l: StateLayout, v: Vec3) -> ([W; 3], usize) {
    (v.to_array().map(W::from_f32), 3)
}

/// The words of C (column-major) in `l`, and how many there are.
pub(super) fn c_words<W: Word>(l: StateLayout, c: Mat3) -> ([W; 9], usize) {
    if l.compact() {
        let w = codec::encode_c(c.to_cols_array());
        let mut out = [W::default(); 9];
        for (o, w) in out.iter_mut().zip(w) {
            *o = W::from_id(w);
        }
        (out, 5)
    } else {
        (c.to_cols_array().map(W::from_f32), 9)
    }
}

/// The words of a packed F in `l` (a fluid layout: its diagonal value), and how many.
pub(super) fn f_words<W: Word>(l: StateLayout, f: Mat3) -> ([W; 9], usize) {
    let a = f.to_cols_array().map(W::from_f32);
    (a, l.f_words())
}

/// The velocity from its words (`g(k)`: word k of the field).
pub(super) fn read_v<W: Word>(_l: StateLayout, g: impl Fn(usize) -> W) -> Vec3 {
    Vec3::new(g(0).to_f32(), g(1).to_f32(), g(2).to_f32())
}

/// The velocity from its words, unrounded (f64 words stay f64).
pub(super) fn read_v_f64<W: Word>(_l: StateLayout, g: impl Fn(usize) -> W) -> [f64; 3] {
    [g(0).to_f64(), g(1).to_f64(), g(2).to_f64()]
}

/// C from its words.
pub(super) fn read_c<W: Word>(l: StateLayout, g: impl Fn(usize) -> W) -> Mat3 {
    if l.compact() {
        Mat3::from_cols_array(&codec::decode_c(std::array::from_fn(|k| g(k).id())))
    } else {
        Mat3::from_cols_array(&std::array::from_fn(|e| g(e).to_f32()))
    }
}

/// F from its words (a fluid layout: J^(1/3) I from the one word).
pub(super) fn read_f<W: Word>(l: StateLayout, g: impl Fn(usize) -> W) -> Mat3 {
    if l.fluid() {
        Mat3::from_diagonal(Vec3::splat(g(0).to_f32()))
    } else {
        Mat3::from_cols_array(&std::array::from_fn(|e| g(e).to_f32()))
    }
}

/// The words that every particle of a body of a shape shares in `l`, as (state word, bits of the
/// word in the precision `W`: an f32 word's in the low 32 bits): C, F in its packed form
/// (`fluid`: J^(1/3) I with J = 1), the plastic word, mass, volume and material: exactly the
/// words `write_image` writes for such a body besides x, v and the id.
pub(super) fn body_words<W: Word>(
    l: StateLayout,
    b: &rtmpm_scene::sampling::BodyPositions,
    fluid: bool,
) -> Vec<(usize, u64)> {
    let bits = |w: W| {
        let mut out = [0u8; 8];
        w.put(&mut out);
        u64::from_le_bytes(out)
    };
    let mut out = Vec::new();
    let (c, nc) = c_words::<W>(l, b.c);
    let (f, nf) = f_words::<W>(l, packed_f(Mat3::IDENTITY, fluid));
    out.extend((0..nc).map(|e| (l.c() + e, bits(c[e]))));
    out.extend((0..nf).map(|e| (l.f() + e, bits(f[e]))));
    if let Some(pl) = l.plastic() {
        out.push((pl, bits(W::from_f32(b.plastic))));
    }
    out.push((l.mass(), bits(W::from_f32(b.mass))));
    out.push((l.vol0(), bits(W::from_f32(b.vol0))));
    out.push((l.material(), bits(W::from_id(b.material))));
    out
}
