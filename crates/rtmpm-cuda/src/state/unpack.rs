//! Particles back from the device image, in original order (the id word of each slot): the
//! whole state ([`unpack`]), the rows of every state word read into pooled host memory,
//! unpacked by every core ([`unpack_rows`]), one GPU's share of several ([`scatter_f32`]), or
//! positions and velocities unrounded ([`unpack_x_v_f64`]).

use super::fields::*;
use super::word::Word;
use crate::contract::StateLayout;
use rayon::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// Particles per task of [`unpack_rows`].
const UNPACK_CHUNK: usize = 16 * 1024;

/// Particles in original order from the device image of `n` particles (stride `cap`).
pub fn unpack(
    bytes: &[u8],
    n: usize,
    cap: usize,
    layout: StateLayout,
    f64: bool,
    out: &mut Particles,
) -> Result<(), String> {
    if f64 {
        unpack_words::<f64>(bytes, n, cap, layout, out)
    } else {
        unpack_words::<f32>(bytes, n, cap, layout, out)
    }
}

fn unpack_words<W: Word>(
    bytes: &[u8],
    n: usize,
    cap: usize,
    l: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    if cap < n || bytes.len() < l.words() * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    *out = Particles::default();
    resize_particles(out, n);
    scatter_words(
        |f, i| W::read(&bytes[(f * cap + i) * W::BYTES..]),
        n,
        l,
        out,
    )
}

/// Particles in original order from `rows`, the `n` words of every state word of `layout` in
/// slot order (`rows[w]`: word `w` of slots `0..n`, as [`crate::CudaBackend::read_fields`]
/// reads them): the slot of each original index first, then every particle read from its slot
/// by all cores. The same particles as [`unpack`] of the whole image; an id out of range or
/// given to two slots is an error.
pub fn unpack_rows(
    rows: &[&[u8]],
    n: usize,
    layout: StateLayout,
    f64: bool,
    out: &mut Particles,
) -> Result<(), String> {
    if f64 {
        rows_words::<f64>(rows, n, layout, out)
    } else {
        rows_words::<f32>(rows, n, layout, out)
    }
}

fn rows_words<W: Word>(
    rows: &[&[u8]],
    n: usize,
    l: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    if rows.len() < l.words() || rows.iter().any(|r| r.len() < n * W::BYTES) {
        return Err(format!(
            "CUDA: {} rows of state words for {} words of {n} particles",
            rows.len(),
            l.words()
        ));
    }
    let g = |f: usize, i: usize| W::read(&rows[f][i * W::BYTES..]);
    // The slot of each original index (ids are a permutation of 0..n).
    let mut slot = vec![u32::MAX; n];
    for i in 0..n {
        let id = g(l.id(), i).id() as usize;
        match slot.get_mut(id) {
            Some(s) if *s == u32::MAX => *s = i as u32,
            Some(_) => return Err(format!("CUDA: particle id {id} held by two slots")),
            None => return Err(format!("CUDA: corrupt particle id {id}")),
        }
    }
    *out = Particles::default();
    resize_particles(out, n);
    let r = |f: usize, i: usize| g(f, i).to_f32();
    let Particles {
        x,
        v,
        c,
        f,
        plastic,
        mass,
        vol0,
        material,
    } = out;
    (
        x.par_iter_mut(),
        v.par_iter_mut(),
        c.par_iter_mut(),
        f.par_iter_mut(),
        plastic.par_iter_mut(),
        mass.par_iter_mut(),
        vol0.par_iter_mut(),
        material.par_iter_mut(),
    )
        .into_par_iter()
        .zip(slot.par_iter())
        .with_min_len(UNPACK_CHUNK)
        .for_each(|((x, v, c, f, plastic, mass, vol0, material), &i)| {
            let i = i as usize;
            let xw = l.x();
            *x = Vec3::new(r(xw, i), r(xw + 1, i), r(xw + 2, i));
            *v = read_v(l, |k| g(l.v() + k, i));
            *c = read_c(l, |k| g(l.c() + k, i));
            *f = read_f(l, |k| g(l.f() + k, i));
            *plastic = l.plastic().map_or(0.0, |p| r(p, i));
            *mass = r(l.mass(), i);
            *vol0 = r(l.vol0(), i);
            *material = g(l.material(), i).id();
        });
    Ok(())
}

/// Size every column of `out` for `n` particles (zeros).
pub fn resize_particles(out: &mut Particles, n: usize) {
    out.x.resize(n, Vec3::ZERO);
    out.v.resize(n, Vec3::ZERO);
    out.c.resize(n, Mat3::ZERO);
    out.f.resize(n, Mat3::ZERO);
    out.plastic.resize(n, 0.0);
    out.mass.resize(n, 0.0);
    out.vol0.resize(n, 0.0);
    out.material.resize(n, 0);
}

/// Put the `n` particles of a single-precision state image (SoA with stride `cap`, as stored on
/// one GPU of several) at their original index in `out` (already sized for every particle).
pub fn scatter_f32(
    host: &[f32],
    n: usize,
    cap: usize,
    layout: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    if cap < n || host.len() < layout.words() * cap {
        return Err(format!("CUDA: state of {} words is too short", host.len()));
    }
    scatter_words(|f, i| host[f * cap + i], n, layout, out)
}

/// Put `n` particles, read word by word with `g(field, particle)`, at their original index
/// (the id field) in `out`, which is already sized.
fn scatter_words<W: Word>(
    g: impl Fn(usize, usize) -> W,
    n: usize,
    l: StateLayout,
    out: &mut Particles,
) -> Result<(), String> {
    let total = out.x.len();
    let r = |f: usize, i: usize| g(f, i).to_f32();
    for i in 0..n {
        let id = g(l.id(), i).id() as usize;
        if id >= total {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        let x = l.x();
        out.x[id] = Vec3::new(r(x, i), r(x + 1, i), r(x + 2, i));
        out.v[id] = read_v(l, |k| g(l.v() + k, i));
        out.c[id] = read_c(l, |k| g(l.c() + k, i));
        out.f[id] = read_f(l, |k| g(l.f() + k, i));
        out.plastic[id] = l.plastic().map_or(0.0, |p| r(p, i));
        out.mass[id] = r(l.mass(), i);
        out.vol0[id] = r(l.vol0(), i);
        out.material[id] = g(l.material(), i).id();
    }
    Ok(())
}

/// Positions and velocities in original order, unrounded (f64 words stay f64): for tests that
/// compare double-precision states.
pub fn unpack_x_v_f64(
    bytes: &[u8],
    n: usize,
    cap: usize,
    layout: StateLayout,
    f64: bool,
) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if f64 {
        x_v_words::<f64>(bytes, n, cap, layout)
    } else {
        x_v_words::<f32>(bytes, n, cap, layout)
    }
}

fn x_v_words<W: Word>(
    bytes: &[u8],
    n: usize,
    cap: usize,
    l: StateLayout,
) -> Result<Vec<[[f64; 3]; 2]>, String> {
    if cap < n || bytes.len() < l.words() * cap * W::BYTES {
        return Err(format!("CUDA: state of {} bytes is too short", bytes.len()));
    }
    let g = |f: usize, i: usize| W::read(&bytes[(f * cap + i) * W::BYTES..]);
    let v3 = |f: usize, i: usize| [g(f, i).to_f64(), g(f + 1, i).to_f64(), g(f + 2, i).to_f64()];
    let mut out = vec![[[0.0; 3]; 2]; n];
    for i in 0..n {
        let id = g(l.id(), i).id() as usize;
        if id >= n {
            return Err(format!("CUDA: corrupt particle id {id}"));
        }
        out[id] = [v3(l.x(), i), read_v_f64(l, |k| g(l.v() + k, i))];
    }
    Ok(out)
}
