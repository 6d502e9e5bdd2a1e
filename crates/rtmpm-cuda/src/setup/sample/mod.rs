//! Deferred bodies drawn on the device, so that a big scene starts fast (`kernels/sample.cu`):
//! the host counted such a body's particles and kept none ([`rtmpm_scene::deferred`]);
//! here the GPU walks the body's lattice row by row (or its random tries,
//! [`SAMPLE_TRIES_PER_ROW`] a row), one thread a row, and draws the positions the host's walk
//! finds, bit for bit and in order (`kernels/sample.cuh`). `sample_count` counts each row's
//! points, the host sums them into each row's first particle (and checks the total against its
//! own count), and `sample_write` writes the positions of one piece of the body, which the device
//! fill ([`crate::setup::fill`]) turns into particles. The host then needs no memory per particle.

use crate::contract::*;
use crate::error::err;
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaSlice, CudaStream, PushKernelArg};
use rtmpm_geometry::Use;
use rtmpm_scene::deferred::{DeferredBody, DeferredWalk};
use rtmpm_scene::sampling::SampledBody;
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Rows counted or drawn by one launch (at most).
const ROW_BATCH: u64 = 1 << 20;

/// The recipe of `d`'s walk as device words (layout `SP_*` in [`crate::contract`]) and, for a
/// mesh, its distance grid's values; `None` for a shape the device does not draw.
pub fn recipe(d: &DeferredBody) -> Option<(Vec<u32>, Vec<f32>)> {
    let mut w = vec![0u32; SAMPLE_WORDS];
    let put64 = |w: &mut [u32], at: usize, v: u64| {
        w[at] = v as u32;
        w[at + 1] = (v >> 32) as u32;
    };
    match &d.walk {
        DeferredWalk::Lattice(l) => {
            w[SP_KIND] = SAMPLE_LATTICE;
            for a in 0..3 {
                w[SP_ORIGIN + a] = l.origin[a].to_bits();
                put64(&mut w, SP_FIRST + 2 * a, l.first[a] as u64);
            }
            w[SP_H] = l.h.to_bits();
            put64(&mut w, SP_NX, l.count[0]);
            put64(&mut w, SP_NY, l.count[1]);
            w[SP_JITTER] = l.jitter as u32;
        }
        DeferredWalk::Random(r) => {
            w[SP_KIND] = SAMPLE_RANDOM;
            for a in 0..3 {
                w[SP_ORIGIN + a] = r.lo[a].to_bits();
                w[SP_HI + a] = r.hi[a].to_bits();
            }
            put64(&mut w, SP_TRIES, r.tries);
        }
    }
    let s = d.stream();
    for (at, v) in [(SP_STATE, s.state), (SP_INC, s.increment)] {
        put64(&mut w, at, v as u64);
        put64(&mut w, at + 2, (v >> 64) as u64);
    }
    let info = d.shape.info();
    if !(info.device && info.allows(Use::Body)) {
        return None;
    }
    let g = d.shape.gpu();
    w[SP_SHAPE] = d.shape.code();
    for (k, v) in g.p.iter().enumerate() {
        w[SP_PARAMS + k] = v.to_bits();
    }
    w[SP_DIMS..SP_DIMS + 3].copy_from_slice(&g.dims);
    Some((w, g.values.to_vec()))
}

/// Rows of `d`'s walk on the device: the lattice's rows, or its random tries in rows of
/// [`SAMPLE_TRIES_PER_ROW`].
pub fn rows(d: &DeferredBody) -> u64 {
    match &d.walk {
        DeferredWalk::Lattice(l) => l.rows_count(),
        DeferredWalk::Random(r) => r.tries.div_ceil(SAMPLE_TRIES_PER_ROW),
    }
}

/// `bodies` with every deferred body walked on the host (for the paths that need positions: the
/// host packing, the reverse map's stencil bases).
pub fn walked(bodies: &[SampledBody]) -> Vec<SampledBody> {
    bodies
        .iter()
        .map(|b| match b {
            SampledBody::Deferred(d) => SampledBody::Shape(d.positions()),
            SampledBody::Shape(s) => SampledBody::Shape(s.clone()),
            SampledBody::Points(p) => SampledBody::Points(p.clone()),
        })
        .collect()
}

/// A deferred body ready to be drawn: its recipe on the device and the first particle of every
/// row (`rows + 1` entries, the last the body's count).
pub(crate) struct Counted {
    recipe: CudaSlice<u32>,
    sdf: CudaSlice<f32>,
    offsets: Vec<u64>,
}

/// The rows overlapping particles `lo .. hi` of a body whose rows start at `offsets` (`rows + 1`
/// entries): rows `r` with `offsets[r] < hi` and `offsets[r + 1] > lo`.
pub fn rows_of(offsets: &[u64], lo: u64, hi: u64) -> std::ops::Range<usize> {
    let rows = offsets.len().saturating_sub(1);
    let first = offsets[1..].partition_point(|&o| o <= lo);
    let end = offsets[..rows].partition_point(|&o| o < hi);
    first..end.max(first)
}

/// Count body `index`'s rows on the device; the sum must be the host's count.
pub(crate) fn count(
    stream: &Arc<CudaStream>,
    kernels: &Kernels,
    d: &DeferredBody,
    index: usize,
) -> Result<Counted, SimError> {
    let (words, mut sdf) = recipe(d).ok_or_else(|| {
        SimError::Backend(format!(
            "body {index}: its shape cannot be drawn on the GPU (internal)"
        ))
    })?;
    let recipe = stream
        .clone_htod(&words)
        .map_err(err("upload a body's recipe"))?;
    if sdf.is_empty() {
        sdf.push(0.0);
    }
    let sdf = stream
        .clone_htod(&sdf)
        .map_err(err("upload a mesh body's distances"))?;
    let rows = rows(d);
    let mut offsets = Vec::with_capacity(rows as usize + 1);
    offsets.push(0u64);
    let mut counts = stream
        .alloc_zeros::<u64>(ROW_BATCH.min(rows.max(1)) as usize)
        .map_err(err("row counts of a body"))?;
    let mut row0 = 0u64;
    while row0 < rows {
        let n = ROW_BATCH.min(rows - row0) as u32;
        // SAFETY: the kernel reads the recipe (SAMPLE_WORDS words), the mesh's distances (its
        // dims' product, a mesh only) and writes counts[0..n].
        unsafe {
            stream
                .launch_builder(&kernels[Kernel::SampleCount])
                .arg(&recipe)
                .arg(&sdf)
                .arg(&row0)
                .arg(&n)
                .arg(&mut counts)
                .launch(kernels.wave(n as usize, 128))
        }
        .map_err(err("count a body's rows"))?;
        let host = stream
            .clone_dtoh(&counts.slice(0..n as usize))
            .map_err(err("download a body's row counts"))?;
        for c in host {
            let last = *offsets.last().unwrap_or(&0);
            offsets.push(last + c);
        }
        row0 += n as u64;
    }
    let drawn = *offsets.last().unwrap_or(&0);
    if drawn != d.accepted {
        return Err(SimError::Backend(format!(
            "body {index}: the GPU's walk finds {drawn} particles where the host's found {}; \
             sample it on the host with --cuda-options sample=host (and report this)",
            d.accepted
        )));
    }
    Ok(Counted {
        recipe,
        sdf,
        offsets,
    })
}

/// Draw particles `lo .. lo + len` of a counted body into `out` (3 f32 each); `scratch` holds
/// the rows' first particles (grown as needed).
pub(crate) fn draw(
    stream: &Arc<CudaStream>,
    kernels: &Kernels,
    c: &Counted,
    lo: u64,
    len: usize,
    out: &mut CudaSlice<f32>,
    scratch: &mut Option<CudaSlice<u64>>,
) -> Result<(), SimError> {
    let rows = rows_of(&c.offsets, lo, lo + len as u64);
    let len32 = len as u32;
    let mut r = rows.start;
    while r < rows.end {
        let n = (ROW_BATCH as usize).min(rows.end - r);
        if scratch.as_ref().is_none_or(|s| s.len() < n) {
            *scratch = Some(
                stream
                    .alloc_zeros::<u64>(n)
                    .map_err(err("row offsets of a body"))?,
            );
        }
        let dev = scratch
            .as_mut()
            .ok_or_else(|| SimError::Backend("row offsets of a body: no buffer".into()))?;
        stream
            .memcpy_htod(&c.offsets[r..r + n], &mut dev.slice_mut(0..n))
            .map_err(err("upload row offsets"))?;
        let (row0, n32) = (r as u64, n as u32);
        // SAFETY: the kernel reads the recipe and offsets[0..n], and writes out[0..3 len] (the
        // particles lo .. lo + len of the rows only).
        unsafe {
            stream
                .launch_builder(&kernels[Kernel::SampleWrite])
                .arg(&c.recipe)
                .arg(&c.sdf)
                .arg(&row0)
                .arg(&n32)
                .arg(&*dev)
                .arg(&lo)
                .arg(&len32)
                .arg(&mut *out)
                .launch(kernels.wave(n, 128))
        }
        .map_err(err("draw a body's positions"))?;
        r += n;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
