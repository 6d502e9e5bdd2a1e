//! The particle state of sampled bodies, filled on the device, so that a big scene starts fast: the
//! host uploads only the positions (12 bytes a particle, a piece at a time through two page-locked
//! buffers, so the copy of one piece overlaps the gathering of the next) and a table of one row per
//! body ([`table`]: its index range and what all its particles share), and `fill_body`
//! (`kernels/fill.cu`) writes every word of the state, word for word what
//! [`crate::state::pack_bodies`] writes on the host. Bodies read from points files
//! (`SampledBody::Points`) are packed on the host as before, and their rows copied into place.
//!
//! Deferred bodies ([`rtmpm_scene::deferred`]) upload nothing: their positions are drawn
//! on the device into the same buffers ([`crate::setup::sample`]).
//!
//! The host never holds the state image (116 bytes a particle in f32): the set-up of 500M
//! particles no longer packs 58 GB on the host, and the host's peak is the positions.

use crate::contract::*;
use crate::error::err;
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaEvent, CudaSlice, CudaStream, PinnedHostSlice, PushKernelArg};
use rayon::prelude::*;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::sampling::{BodyPositions, SampledBody};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Particles of one piece of the upload (at most): 48 MB of positions per page-locked buffer.
pub const PIECE: usize = 1 << 22;

/// The fill table: [`FILL_WORDS`] words per body, in body order (layout `FT_*` in
/// [`crate::contract`]): the body's range (its first particle is the sum of the counts before
/// it), v0, w and c of its velocity field, and the words every particle of it shares in
/// `layout` and precision `f64` ([`crate::state::body_constant_words`]: all but x, v and the
/// id). Rows of points bodies hold their range only (the device does not fill
/// them). `fluid`: one entry per material; a body's material must be in range (else the error
/// of [`crate::state::pack_bodies`]).
pub fn table(
    bodies: &[SampledBody],
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
) -> Result<Vec<u32>, String> {
    let mut rows = vec![0u32; FILL_WORDS * bodies.len()];
    let mut start = 0u64;
    for (body, row) in bodies.iter().zip(rows.chunks_exact_mut(FILL_WORDS)) {
        let count = body.len() as u64;
        row[FT_START] = start as u32;
        row[FT_START + 1] = (start >> 32) as u32;
        row[FT_COUNT] = count as u32;
        row[FT_COUNT + 1] = (count >> 32) as u32;
        let shared = match body {
            SampledBody::Shape(b) => Some(b),
            SampledBody::Deferred(d) => Some(&d.shared),
            SampledBody::Points(_) => None,
        };
        if let Some(b) = shared {
            let is_fluid = match fluid.get(b.material as usize) {
                Some(f) => *f,
                None if b.count == 0 => false,
                None => {
                    return Err(format!(
                        "particle {start} has material {} out of range",
                        b.material
                    ));
                }
            };
            for a in 0..3 {
                row[FT_V0 + a] = b.velocity[a].to_bits();
                row[FT_W + a] = b.angular_velocity[a].to_bits();
                row[FT_CENTRE + a] = b.centre[a].to_bits();
            }
            let words = crate::state::body_constant_words(layout, f64, b, is_fluid);
            row[FT_NCONST] = words.len() as u32;
            for (k, (w, bits)) in words.into_iter().enumerate() {
                let at = FT_CONST + 3 * k;
                row[at] = w as u32;
                row[at + 1] = bits as u32;
                row[at + 2] = (bits >> 32) as u32;
            }
        }
        start += count;
    }
    Ok(rows)
}

/// One piece of the upload: particles `offset..offset + len` of body `body` (a body of a shape).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Piece {
    /// Index of the body.
    pub body: usize,
    /// First particle of the piece within the body.
    pub offset: usize,
    /// Particles of the piece (1 to `max`).
    pub len: usize,
}

/// The pieces of the bodies of shapes (deferred or not), in order, each of at most `max` particles: every such
/// body cut into consecutive pieces (whatever the chunks of its walk), the last one shorter.
pub fn pieces(bodies: &[SampledBody], max: usize) -> Vec<Piece> {
    let max = max.max(1);
    let mut out = Vec::new();
    for (body, b) in bodies.iter().enumerate() {
        let count = match b {
            SampledBody::Shape(_) | SampledBody::Deferred(_) => b.len(),
            SampledBody::Points(_) => 0,
        };
        let mut offset = 0;
        while offset < count {
            let len = max.min(count - offset);
            out.push(Piece { body, offset, len });
            offset += len;
        }
    }
    out
}

/// Copy the positions `offset..offset + len` of `b` (its chunks concatenated) as 3 f32 each into
/// `out` (at least `3 len` long), in parallel.
pub fn gather(b: &BodyPositions, offset: usize, len: usize, out: &mut [f32]) {
    // The pieces of the chunks that overlap the range, with where they go.
    let mut parts: Vec<(&[Vec3], &mut [f32])> = Vec::new();
    let mut rest = &mut out[..3 * len];
    let mut at = 0usize;
    for c in &b.chunks {
        let (lo, hi) = (at, at + c.len());
        at = hi;
        if hi <= offset {
            continue;
        }
        if lo >= offset + len {
            break;
        }
        let from = offset.max(lo) - lo;
        let to = (offset + len).min(hi) - lo;
        let (dst, tail) = rest.split_at_mut(3 * (to - from));
        parts.push((&c[from..to], dst));
        rest = tail;
    }
    parts.into_par_iter().for_each(|(src, dst)| {
        for (x, d) in src.iter().zip(dst.chunks_exact_mut(3)) {
            d.copy_from_slice(&x.to_array());
        }
    });
}

/// Seconds of the phases of [`fill`].
#[derive(Clone, Copy, Debug, Default)]
pub struct FillTimes {
    /// Gathering positions into page-locked memory (host, overlapped with the copies).
    pub gather: f64,
    /// Counting the deferred bodies' rows on the device ([`crate::setup::sample`], waited for).
    pub count: f64,
    /// The whole fill: table, page-locked buffers, uploads, kernels, points bodies (waited for).
    pub total: f64,
}

/// Fill the state (stride `cap`, zero past the particles) with the particles of `bodies` on the
/// device: `table_rows` from [`table`], the shapes' positions uploaded in [`pieces`], the points
/// bodies packed on the host. Waits for the device before it returns.
#[allow(clippy::too_many_arguments)]
pub(crate) fn fill(
    stream: &Arc<CudaStream>,
    kernels: &Kernels,
    state: &mut CudaSlice<u8>,
    cap: usize,
    bodies: &[SampledBody],
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
) -> Result<FillTimes, SimError> {
    let t0 = std::time::Instant::now();
    let mut times = FillTimes::default();
    let rows = table(bodies, fluid, layout, f64).map_err(SimError::Backend)?;
    let table_dev = stream.clone_htod(&rows).map_err(err("upload fill table"))?;
    let pieces = pieces(bodies, PIECE);
    let piece_max = pieces.iter().map(|p| p.len).max().unwrap_or(0);
    // The deferred bodies' rows counted on the device (checked against the host's counts).
    let t = std::time::Instant::now();
    let counted = bodies
        .iter()
        .enumerate()
        .map(|(i, b)| match b {
            SampledBody::Deferred(d) => {
                crate::setup::sample::count(stream, kernels, d, i).map(Some)
            }
            _ => Ok(None),
        })
        .collect::<Result<Vec<_>, _>>()?;
    times.count = t.elapsed().as_secs_f64();
    if piece_max > 0 {
        let fill = FillBody {
            table: &table_dev,
            cap: cap as u32,
            words: (layout.x() as i32, layout.v() as i32, layout.id() as i32),
        };
        let mut buffers = PieceBuffers::new(stream, bodies, &pieces, piece_max)?;
        let mut rows_scratch = None;
        for (k, p) in pieces.iter().enumerate() {
            let (h, d) = (&mut buffers.host[k % 2], &mut buffers.dev[k % 2]);
            match (&bodies[p.body], &counted[p.body]) {
                // Drawn on the device: no host memory, no copy.
                (SampledBody::Deferred(_), Some(c)) => crate::setup::sample::draw(
                    stream,
                    kernels,
                    c,
                    p.offset as u64,
                    p.len,
                    d,
                    &mut rows_scratch,
                )?,
                (SampledBody::Shape(b), _) => {
                    // The copy of two pieces ago out of this buffer is over.
                    let done = &buffers.done[k % 2];
                    done.synchronize().map_err(err("wait for a fill copy"))?;
                    let slice = h.as_mut_slice().map_err(err("page-locked fill buffer"))?;
                    let g = std::time::Instant::now();
                    gather(b, p.offset, p.len, slice);
                    times.gather += g.elapsed().as_secs_f64();
                    stream
                        .memcpy_htod(&*h, &mut *d)
                        .map_err(err("upload positions"))?;
                    done.record(stream).map_err(err("record a fill copy"))?;
                }
                _ => continue,
            }
            fill.launch(stream, kernels, state, p, d)?;
        }
        // The page-locked buffers are freed here: no copy may still read them.
        stream.synchronize().map_err(err("fill"))?;
    }
    copy_points_bodies(stream, state, cap, bodies, fluid, layout, f64)?;
    stream.synchronize().map_err(err("fill"))?;
    times.total = t0.elapsed().as_secs_f64();
    Ok(times)
}

/// The positions of two pieces at a time: page-locked host buffers (gathered into by the host)
/// and device buffers (read by `fill_body`), so that the copy of one piece overlaps the
/// gathering of the next, and an event per pair that marks the end of its copy.
struct PieceBuffers {
    host: Vec<PinnedHostSlice<f32>>,
    dev: Vec<CudaSlice<f32>>,
    done: Vec<CudaEvent>,
}

impl PieceBuffers {
    /// Buffers for pieces of up to `piece_max` particles (host memory only when a body of a shape
    /// is uploaded: drawn bodies need none).
    fn new(
        stream: &Arc<CudaStream>,
        bodies: &[SampledBody],
        pieces: &[Piece],
        piece_max: usize,
    ) -> Result<PieceBuffers, SimError> {
        let words = 3 * piece_max;
        // Write-combined page-locked memory: the host only writes it.
        // SAFETY: each buffer is written (gathered) before it is copied.
        // (Drawn bodies need none.)
        let host_words = if pieces
            .iter()
            .any(|p| matches!(bodies[p.body], SampledBody::Shape(_)))
        {
            words
        } else {
            1
        };
        let host = (0..2)
            .map(|_| unsafe { stream.context().alloc_pinned::<f32>(host_words) })
            .collect::<Result<Vec<_>, _>>()
            .map_err(err("page-locked memory of the fill"))?;
        let dev = (0..2)
            .map(|_| stream.alloc_zeros::<f32>(words))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err("device memory of the fill"))?;
        // The backend's context tracks no events (one stream), so the page-locked buffers'
        // own events are never recorded: the copy out of each buffer gets an event of ours,
        // waited for before the buffer is written again.
        let done = (0..2)
            .map(|_| stream.context().new_event(None))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err("fill events"))?;
        Ok(PieceBuffers { host, dev, done })
    }
}

/// The launch of `fill_body` (`kernels/fill.cu`): the fill table on the device, the state's
/// stride, and the layout's words of x, v and the id.
struct FillBody<'a> {
    table: &'a CudaSlice<u32>,
    cap: u32,
    words: (i32, i32, i32),
}

impl FillBody<'_> {
    /// Write the particles of piece `p`, whose positions are in `d`, into `state`.
    fn launch(
        &self,
        stream: &Arc<CudaStream>,
        kernels: &Kernels,
        state: &mut CudaSlice<u8>,
        p: &Piece,
        d: &CudaSlice<f32>,
    ) -> Result<(), SimError> {
        let (x_word, v_word, id_word) = self.words;
        let (body, offset, len) = (p.body as i32, p.offset as u64, p.len as u32);
        // SAFETY: the kernel reads 3 len floats of `d` and the table's row `body`, and
        // writes slots start + offset .. + len (below the particle count) of the state of
        // stride cap, at the layout's words (below its count).
        unsafe {
            stream
                .launch_builder(&kernels[Kernel::FillBody])
                .arg(&mut *state)
                .arg(&self.cap)
                .arg(self.table)
                .arg(&body)
                .arg(&offset)
                .arg(&len)
                .arg(d)
                .arg(&x_word)
                .arg(&v_word)
                .arg(&id_word)
                .launch(kernels.wave(p.len, 256))
        }
        .map_err(err("fill kernel"))?;
        Ok(())
    }
}

/// Bodies from points files: packed on the host, rows copied into place.
fn copy_points_bodies(
    stream: &Arc<CudaStream>,
    state: &mut CudaSlice<u8>,
    cap: usize,
    bodies: &[SampledBody],
    fluid: &[bool],
    layout: StateLayout,
    f64: bool,
) -> Result<(), SimError> {
    let wb = crate::state::word_bytes(f64);
    let mut start = 0usize;
    for body in bodies {
        if let SampledBody::Points(p) = body {
            let k = p.len();
            if k == 0 {
                continue;
            }
            let ids: Vec<u32> = (start..start + k).map(|i| i as u32).collect();
            let packed = crate::state::pack(p, fluid, layout, f64, k, Some(&ids))
                .map_err(SimError::Backend)?;
            for (f, row) in packed.chunks_exact(k * wb).enumerate().take(layout.words()) {
                let at = (f * cap + start) * wb;
                stream
                    .memcpy_htod(row, &mut state.slice_mut(at..at + k * wb))
                    .map_err(err("upload particles of a points body"))?;
            }
        }
        start += body.len();
    }
    Ok(())
}

#[cfg(test)]
mod tests;
