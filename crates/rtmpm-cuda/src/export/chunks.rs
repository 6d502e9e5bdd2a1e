//! Host side of `export_chunk` (kernels/export.cu): a frame's columns in original particle order,
//! chunk by chunk, for the streamed frame writers ([`rtmpm_io::chunks`]). Each chunk is
//! gathered on the device into a scratch array of the chunk's size (every slot's original index
//! is read once per chunk; no index array of the whole state) and copied into page-locked host
//! memory from [`CudaBackend::chunk_host_memory`], which the sink then hands to a writer thread:
//! the copy of the next chunk overlaps the encoding of this one.

use crate::backend::CudaBackend;
use crate::contract::StateLayout;
use crate::error::err;
use crate::kernels::Kernel;
use cudarc::driver::{CudaSlice, PinnedHostSlice, PushKernelArg};
use rtmpm_io::chunks::{Column, FrameColumns, HostBuffer};
use rtmpm_sim::{ChunkSink, SimError};

/// Page-locked host memory for frame chunks.
pub struct PinnedWords {
    /// Keeps the allocation alive.
    _mem: PinnedHostSlice<u32>,
    ptr: *mut u32,
    len: usize,
}

// SAFETY: the pointer is that of the page-locked allocation owned by `_mem` (which is Send), used
// by one owner at a time.
unsafe impl Send for PinnedWords {}

impl HostBuffer for PinnedWords {
    fn words(&self) -> &[u32] {
        // SAFETY: `ptr` and `len` describe `_mem`, alive as long as self. The export waits for
        // its copies (stream synchronize) before it hands a chunk on, so no copy is writing.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
    fn words_mut(&mut self) -> &mut [u32] {
        // SAFETY: as in `words`, and `&mut self` makes the access exclusive.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

/// Export code of an absent field (zeros: a fluid layout's plastic word); `EXPORT_ZERO` in
/// `kernels/state.cuh`, like the three below.
pub const EXPORT_ZERO: i32 = -1;
/// Export code of component 0 of the decoded C (column-major, 9).
pub const EXPORT_C: i32 = -32;
/// Export code of component 0 of the decoded F (column-major, 9).
pub const EXPORT_F: i32 = -48;

/// The export codes of the chunk's words (`export_word` in `kernels/state.cuh`), in
/// [`FrameColumns::layout`] order: a state word of `l` (>= 0), or a component of a field that
/// `l` does not store as plain words (decoded on the device).
pub fn chunk_fields(cols: FrameColumns, l: StateLayout) -> Vec<i32> {
    let mut out = Vec::new();
    for c in cols.layout() {
        let words = |first: usize| (first..first + c.components()).map(|f| f as i32).collect();
        let codes = |base: i32| (0..c.components() as i32).map(|k| base + k).collect();
        let col: Vec<i32> = match c {
            Column::X => words(l.x()),
            Column::V => words(l.v()),
            Column::Material => words(l.material()),
            Column::Plastic => l.plastic().map_or(vec![EXPORT_ZERO], words),
            Column::Mass => words(l.mass()),
            Column::Vol0 => words(l.vol0()),
            Column::F if l.fluid() => codes(EXPORT_F),
            Column::F => words(l.f()),
            Column::C if l.compact() => codes(EXPORT_C),
            Column::C => words(l.c()),
        };
        out.extend(col);
    }
    out
}

impl CudaBackend {
    /// Page-locked host memory of `words` words for frame chunks.
    pub fn chunk_host_memory(&self, words: usize) -> Result<PinnedWords, SimError> {
        // SAFETY: written by the copies (or zero) before it is read; plain page-locked memory
        // (not write-combined: the host reads it).
        let mut mem = unsafe {
            self.stream
                .context()
                .alloc_pinned_with_flags::<u32>(words.max(1), 0)
        }
        .map_err(err("allocate page-locked memory for frame chunks"))?;
        let slice = mem.as_mut_slice().map_err(err("page-locked memory"))?;
        slice.fill(0);
        let (ptr, len) = (slice.as_mut_ptr(), slice.len());
        Ok(PinnedWords {
            _mem: mem,
            ptr,
            len,
        })
    }

    /// [`rtmpm_sim::Backend::export_frame`]: chunk by chunk, gathered on the device and
    /// copied into the sink's (page-locked) chunks. Synchronises.
    pub fn export_chunks(&mut self, sink: &mut dyn ChunkSink) -> Result<(), SimError> {
        let n = self.n;
        if n == 0 {
            return Ok(());
        }
        let fields = chunk_fields(sink.columns(), self.layout);
        let nw = fields.len();
        let stream = self.stream.clone();
        let d_fields = stream
            .clone_htod(&fields)
            .map_err(err("upload the export fields"))?;
        let mut bad = stream
            .alloc_zeros::<u32>(1)
            .map_err(err("allocate the export flag"))?;
        let mut scratch: Option<CudaSlice<u32>> = None;
        let cap = self.ctx.cap;
        let mut start = 0usize;
        while start < n {
            let mut chunk = sink.take()?;
            let ccap = chunk.cap;
            let len = ccap.min(n - start);
            let host = chunk.buf.words_mut();
            if ccap == 0 || host.len() < ccap * nw || u32::try_from(ccap).is_err() {
                return Err(SimError::Backend(
                    "CUDA: frame chunk memory too small".into(),
                ));
            }
            if scratch.as_ref().is_none_or(|s| s.len() < ccap * nw) {
                // The smaller array goes first (device memory may be tight).
                drop(scratch.take());
                let s = stream
                    .alloc_zeros::<u32>(ccap * nw)
                    .map_err(err("allocate the frame chunk scratch"))?;
                scratch = Some(s);
            }
            let Some(dev) = scratch.as_mut() else {
                return Err(SimError::Backend("CUDA: no chunk scratch".into()));
            };
            let (n32, lo, len32, nw32, stride) =
                (n as u32, start as u32, len as u32, nw as i32, ccap as u32);
            // SAFETY: the kernel reads slots 0..n of the state (stride cap), nw export codes
            // (state words below the layout's, or decoded fields), and writes rows w < nw of `dev` (nw x ccap words) at columns < len
            // <= ccap.
            unsafe {
                stream
                    .launch_builder(&self.kernels[Kernel::ExportChunk])
                    .arg(&self.buffers.state)
                    .arg(&cap)
                    .arg(&n32)
                    .arg(&lo)
                    .arg(&len32)
                    .arg(&d_fields)
                    .arg(&nw32)
                    .arg(&mut *dev)
                    .arg(&stride)
                    .arg(&mut bad)
                    .launch(self.kernels.wave(n, 256))
            }
            .map_err(err("frame chunk kernel"))?;
            if len == ccap {
                stream
                    .memcpy_dtoh(&dev.slice(0..ccap * nw), &mut host[..ccap * nw])
                    .map_err(err("copy a frame chunk"))?;
            } else {
                for w in 0..nw {
                    let row = w * ccap;
                    stream
                        .memcpy_dtoh(&dev.slice(row..row + len), &mut host[row..row + len])
                        .map_err(err("copy a frame chunk"))?;
                }
            }
            stream
                .synchronize()
                .map_err(err("wait for a frame chunk"))?;
            chunk.start = start;
            chunk.len = len;
            sink.put(chunk)?;
            start += len;
        }
        let mut flag = [0u32];
        stream
            .memcpy_dtoh(&bad, &mut flag)
            .map_err(err("read the export flag"))?;
        stream.synchronize().map_err(err("synchronize"))?;
        if flag[0] != 0 {
            return Err(SimError::Backend(
                "CUDA: a particle's original index is out of range".into(),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The words of a chunk name the state fields of the columns, in the core's layout order.
    #[test]
    fn chunk_fields_follow_the_layout() {
        let ply = FrameColumns {
            v: true,
            material: true,
            plastic: true,
            ..FrameColumns::default()
        };
        // Today's 29-word layout.
        assert_eq!(
            chunk_fields(ply, StateLayout::Full),
            vec![0, 1, 2, 3, 4, 5, 27, 24]
        );
        // The fluid layout: no plastic word (zeros), the material at 18.
        assert_eq!(
            chunk_fields(ply, StateLayout::Fluid),
            vec![0, 1, 2, 3, 4, 5, 18, EXPORT_ZERO]
        );
        // Compact: the velocity in plain words (f32 in every layout), material at 23.
        assert_eq!(
            chunk_fields(ply, StateLayout::Compact),
            vec![0, 1, 2, 3, 4, 5, 23, 20]
        );
        let all_cols = FrameColumns::all();
        for l in StateLayout::ALL {
            let all = chunk_fields(all_cols, l);
            assert_eq!(all.len(), all_cols.words(), "{l:?}");
            let f = all[all_cols.row(Column::F).unwrap_or(0)];
            let c = all[all_cols.row(Column::C).unwrap_or(0)];
            assert_eq!(f, if l.fluid() { EXPORT_F } else { l.f() as i32 });
            assert_eq!(c, if l.compact() { EXPORT_C } else { l.c() as i32 });
            assert!(
                all.iter()
                    .all(|&f| f < l.words() as i32 && f != l.id() as i32 && f >= EXPORT_F),
                "{l:?}: {all:?}"
            );
        }
        // The device's codes are these.
        let state_cuh = include_str!("../../kernels/state.cuh");
        for (name, v) in [
            ("EXPORT_ZERO", EXPORT_ZERO),
            ("EXPORT_C", EXPORT_C),
            ("EXPORT_F", EXPORT_F),
        ] {
            assert!(
                state_cuh.contains(&format!("#define {name} ({v})")),
                "{name}"
            );
        }
    }
}
