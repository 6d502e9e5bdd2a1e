//! The words an edit of the particles between steps writes ([`edit_rows`]): positions,
//! velocities, C and F of every particle in each field's form of the layout (C in the compact
//! format, a fluid's F as J^(1/3) I), as the packing writes them.

use super::fields::{c_words, f_words, packed_f, v_words};
use super::word::Word;
use crate::contract::StateLayout;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_sim::ParticleEdit;

/// The state words `edit` writes, each as (state word, its `n` words in storage order as
/// little-endian bytes), for the `n` slots of one GPU holding every particle, whose original
/// indices are `ids` and materials `material` (`fluid`: one entry per material, true for a
/// fluid). Errors: a column of another length than `n`, an id or a material out of range.
pub fn edit_rows(
    edit: &ParticleEdit,
    ids: &[usize],
    material: &[u32],
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
) -> Result<Vec<(usize, Vec<u8>)>, String> {
    if f64 {
        rows::<f64>(edit, ids, material, fluid, layout)
    } else {
        rows::<f32>(edit, ids, material, fluid, layout)
    }
}

fn rows<W: Word>(
    edit: &ParticleEdit,
    ids: &[usize],
    material: &[u32],
    fluid: &[bool],
    l: StateLayout,
) -> Result<Vec<(usize, Vec<u8>)>, String> {
    let n = ids.len();
    edit.check_lengths(n).map_err(|e| e.to_string())?;
    if let Some(&id) = ids.iter().find(|&&id| id >= n) {
        return Err(format!(
            "CUDA: a particle's original index ({id}) is out of range"
        ));
    }
    if material.len() != n {
        return Err(format!(
            "CUDA: {} materials for {n} particles",
            material.len()
        ));
    }
    let mut out = Vec::new();
    // (first state word, words of the field, the words of slot i)
    let mut field =
        |first: usize, count: usize, words: &dyn Fn(usize) -> Result<[W; 9], String>| {
            let mut rows = vec![vec![0u8; n * W::BYTES]; count];
            for i in 0..n {
                let w = words(i)?;
                for (k, row) in rows.iter_mut().enumerate() {
                    w[k].put(&mut row[i * W::BYTES..]);
                }
            }
            out.extend(rows.into_iter().enumerate().map(|(k, r)| (first + k, r)));
            Ok::<(), String>(())
        };
    let pad =
        |a: [W; 3]| -> [W; 9] { std::array::from_fn(|k| if k < 3 { a[k] } else { W::default() }) };
    if let Some(x) = edit.x {
        field(l.x(), 3, &|i| {
            Ok(pad(x[ids[i]].to_array().map(W::from_f32)))
        })?;
    }
    if let Some(v) = edit.v {
        field(l.v(), v_words::<W>(l, Vec3::ZERO).1, &|i| {
            Ok(pad(v_words::<W>(l, v[ids[i]]).0))
        })?;
    }
    if let Some(c) = edit.c {
        field(l.c(), c_words::<W>(l, Mat3::ZERO).1, &|i| {
            Ok(c_words::<W>(l, c[ids[i]]).0)
        })?;
    }
    if let Some(f) = edit.f {
        field(l.f(), l.f_words(), &|i| {
            let m = material[i] as usize;
            let is_fluid = *fluid
                .get(m)
                .ok_or_else(|| format!("CUDA: particle material {m} out of range"))?;
            Ok(f_words::<W>(l, packed_f(f[ids[i]], is_fluid)).0)
        })?;
    }
    Ok(out)
}
