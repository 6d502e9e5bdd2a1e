//! Host side of `kernels/export.cu`: positions or velocities of every particle in original order,
//! as float32 in NumPy's `(n, 3)` layout, for the Python package. The GPU puts each slot's three
//! words at its original index (no host scatter); the array comes to the host in chunks through
//! pinned memory, each chunk copied out by several threads while the next one crosses the bus.

use crate::backend::{CudaBackend, err};
use crate::contract::*;
use crate::kernels::Kernel;
use cudarc::driver::PushKernelArg;
use rayon::prelude::*;
use rtmpm_core::sim::SimError;

/// Floats per chunk of the device-to-host copy (2 MiB): the last chunk's host copy is not hidden.
const CHUNK: usize = 1 << 19;

impl CudaBackend {
    /// The three fields from `first` (`F_X` or `F_V`) of every particle, in original particle
    /// order, as `3 n` float32 (x0, y0, z0, x1, ...); f64 state is rounded to f32. Synchronises.
    pub fn read_vec3_ordered(&mut self, first: usize) -> Result<Vec<f32>, SimError> {
        let mut out = vec![0f32; 3 * self.n];
        self.read_vec3_ordered_into(first, &mut out)?;
        Ok(out)
    }

    /// [`CudaBackend::read_vec3_ordered`] into `out` (`3 n` floats), e.g. memory that is reused
    /// between reads, so that no page of it is mapped during the copy.
    pub fn read_vec3_ordered_into(
        &mut self,
        first: usize,
        out: &mut [f32],
    ) -> Result<(), SimError> {
        if out.len() != 3 * self.n {
            return Err(SimError::Backend(format!(
                "CUDA: {} floats given for the 3 x {} of the export",
                out.len(),
                self.n
            )));
        }
        if first + 3 > NFIELDS {
            return Err(SimError::Backend(format!(
                "CUDA: field index out of range (0..{NFIELDS})"
            )));
        }
        let (n, cap) = (self.n, self.ctx.cap);
        let len = 3 * n;
        if self.staging.ordered.as_ref().is_none_or(|o| o.len() < len) {
            self.staging.ordered = None;
            let o = self
                .stream
                .alloc_zeros::<f32>(len.max(1))
                .map_err(err("allocate the export array"))?;
            self.staging.ordered = Some(o);
        }
        if self.staging.bad.is_none() {
            let b = self
                .stream
                .alloc_zeros::<u32>(1)
                .map_err(err("allocate the export flag"))?;
            self.staging.bad = Some(b);
        }
        self.pinned(len * 4)?;
        let stream = self.stream.clone();
        let (Some(ordered), Some(bad), Some(pinned)) = (
            self.staging.ordered.as_mut(),
            self.staging.bad.as_mut(),
            self.staging.pinned.as_mut(),
        ) else {
            return Err(SimError::Backend("CUDA: no export memory".into()));
        };
        stream
            .memset_zeros(bad)
            .map_err(err("clear the export flag"))?;
        let (n32, first32) = (n as u32, first as i32);
        // SAFETY: the kernel reads slots 0..n of the state (stride cap) and writes 3 n floats of
        // `ordered` (at least that long) at ids checked against n.
        unsafe {
            stream
                .launch_builder(&self.kernels[Kernel::ExportVec3])
                .arg(&self.buffers.state)
                .arg(&cap)
                .arg(&n32)
                .arg(&first32)
                .arg(&mut *ordered)
                .arg(&mut *bad)
                .launch(self.kernels.wave(n, 256))
        }
        .map_err(err("export kernel"))?;
        let host = pinned.as_mut_slice().map_err(err("pinned memory"))?;
        let host: &mut [f32] = bytemuck::try_cast_slice_mut(&mut host[..len * 4])
            .map_err(|e| SimError::Backend(format!("CUDA: pinned memory alignment: {e}")))?;
        let mut events = Vec::new();
        for (c, dst) in host.chunks_mut(CHUNK).enumerate() {
            let src = ordered.slice(c * CHUNK..c * CHUNK + dst.len());
            stream
                .memcpy_dtoh(&src, dst)
                .map_err(err("read the export array"))?;
            events.push(stream.record_event(None).map_err(err("record an event"))?);
        }
        for ((src, dst), ev) in host.chunks(CHUNK).zip(out.chunks_mut(CHUNK)).zip(&events) {
            ev.synchronize().map_err(err("wait for a chunk"))?;
            dst.par_chunks_mut(1 << 15)
                .zip(src.par_chunks(1 << 15))
                .for_each(|(d, s)| d.copy_from_slice(s));
        }
        // Read after the chunks: a copy into pageable memory waits for the whole stream.
        let mut flag = [0u32];
        stream
            .memcpy_dtoh(&*bad, &mut flag)
            .map_err(err("read the export flag"))?;
        if flag[0] != 0 {
            return Err(SimError::Backend(
                "CUDA: a particle's original index is out of range".into(),
            ));
        }
        Ok(())
    }
}
