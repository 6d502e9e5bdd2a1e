//! The chunk protocol of [`crate::backend::Backend::export_frame`]: a sink hands out empty chunks
//! ([`rtmpm_io::chunks::FrameChunk`]) and takes them back filled, and the fills of host-side
//! backends.

use crate::error::SimError;
use rayon::prelude::*;
use rtmpm_io::chunks::{Column, FrameChunk, FrameColumns, ParticleRow};
use rtmpm_physics::Particles;

/// Where [`crate::backend::Backend::export_frame`] puts the chunks: it hands out empty chunks and
/// takes the filled ones (e.g. to a writer thread).
pub trait ChunkSink {
    /// The columns wanted.
    fn columns(&self) -> FrameColumns;
    /// An empty chunk of capacity [`FrameChunk::cap`] (may wait until a writer gives one back).
    fn take(&mut self) -> Result<FrameChunk, SimError>;
    /// A filled chunk, `start` and `len` set.
    fn put(&mut self, chunk: FrameChunk) -> Result<(), SimError>;
}

/// Fill chunks of `n` particles from `row(original index, columns)`, in parallel, and give
/// them to `sink` in order: the export of host-side backends. `row` need only set the fields
/// of the columns asked (the others are not read): each is a random access into storage order.
pub fn fill_chunks(
    n: usize,
    sink: &mut dyn ChunkSink,
    row: impl Fn(usize, FrameColumns) -> ParticleRow + Sync,
) -> Result<(), SimError> {
    let cols = sink.columns();
    let layout = cols.layout();
    let mut start = 0;
    while start < n {
        let mut chunk = sink.take()?;
        let len = chunk.cap.min(n - start);
        if chunk.cap == 0 || chunk.buf.words().len() < chunk.cap * cols.words() {
            return Err(SimError::Backend(
                "frame chunk smaller than its size".into(),
            ));
        }
        let cap = chunk.cap;
        // Each task fills a range of particles of every row.
        const TASK: usize = 1 << 14;
        let words = chunk.buf.words_mut();
        let mut rows: Vec<&mut [u32]> = words.chunks_mut(cap).take(cols.words()).collect();
        let mut per_task: Vec<Vec<&mut [u32]>> = (0..len.div_ceil(TASK)).map(|_| vec![]).collect();
        for r in rows.iter_mut() {
            let r: &mut [u32] = std::mem::take(r);
            for (t, piece) in r[..len].chunks_mut(TASK).enumerate() {
                per_task[t].push(piece);
            }
        }
        per_task
            .into_par_iter()
            .enumerate()
            .for_each(|(t, mut rows)| {
                let first = start + t * TASK;
                for j in 0..rows[0].len() {
                    let p = row(first + j, cols);
                    let mut r = 0;
                    for col in &layout {
                        let mut put = |w: u32| {
                            rows[r][j] = w;
                            r += 1;
                        };
                        let floats = |put: &mut dyn FnMut(u32), vals: &[f32]| {
                            vals.iter().for_each(|v| put(v.to_bits()))
                        };
                        match col {
                            Column::X => floats(&mut put, &p.x),
                            Column::V => floats(&mut put, &p.v),
                            // The integer itself, not through a float.
                            Column::Material => put(p.material),
                            Column::Plastic => put(p.plastic.to_bits()),
                            Column::Mass => put(p.mass.to_bits()),
                            Column::Vol0 => put(p.vol0.to_bits()),
                            Column::F => floats(&mut put, &p.f),
                            Column::C => floats(&mut put, &p.c),
                        }
                    }
                }
            });
        chunk.start = start;
        chunk.len = len;
        sink.put(chunk)?;
        start += len;
    }
    Ok(())
}

/// The chunks of particles already in original order on the host (the default export: after
/// [`crate::backend::Backend::read_particles`]).
pub fn export_particles(p: &Particles, sink: &mut dyn ChunkSink) -> Result<(), SimError> {
    if rtmpm_io::check_particles(p).is_err() {
        return Err(SimError::Backend(
            "particle arrays of unequal lengths".into(),
        ));
    }
    fill_chunks(p.len(), sink, |i, _| ParticleRow {
        x: p.x[i].to_array(),
        v: p.v[i].to_array(),
        material: p.material[i],
        plastic: p.plastic[i],
        mass: p.mass[i],
        vol0: p.vol0[i],
        f: p.f[i].to_cols_array(),
        c: p.c[i].to_cols_array(),
    })
}

/// The inverse of a permutation `ids` (storage slot -> original index): original index ->
/// slot; an error when `ids` is not a permutation of `0..ids.len()`.
pub fn invert_ids(ids: &[u32]) -> Result<Vec<u32>, SimError> {
    let n = ids.len();
    let mut slot = vec![u32::MAX; n];
    for (i, &id) in ids.iter().enumerate() {
        match slot.get_mut(id as usize) {
            Some(s) if *s == u32::MAX => *s = i as u32,
            _ => return Err(SimError::Backend(format!("corrupt particle id {id}"))),
        }
    }
    Ok(slot)
}
