//! Host side of `kernels/export.cu`: positions or velocities of every particle in original order,
//! as float32 in NumPy's `(n, 3)` layout, for the Python package. The GPU puts each slot's three
//! words at its original index (no host scatter); the array comes to the host in chunks through
//! pinned memory, each chunk copied out by several threads while the next one crosses the bus.
//! The same gather also fills a device array the caller keeps ([`OrderedDeviceVec3`]: a GPU
//! batch's `x_device` / `v_device` in the Python package), with no copy to the host.

use crate::backend::CudaBackend;
use crate::error::err;
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr, PinnedHostSlice, PushKernelArg};
use rayon::prelude::*;
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Floats per chunk of the device-to-host copy (2 MiB): the last chunk's host copy is not hidden.
const CHUNK: usize = 1 << 19;

impl CudaBackend {
    /// The positions (`first` = the layout's `x()`) or velocities (`v()`, decoded in a compact
    /// layout) of every particle, in original particle order, as `3 n` float32 (x0, y0, z0, x1,
    /// ...); f64 state is rounded to f32. Synchronises.
    pub fn read_vec3_ordered(&mut self, first: usize) -> Result<Vec<f32>, SimError> {
        let mut out = vec![0f32; 3 * self.n];
        self.read_vec3_ordered_into(first, &mut out)?;
        Ok(out)
    }

    /// Page-locked host memory for `len` floats, for [`CudaBackend::read_vec3_ordered_pinned`]
    /// (allocating it costs milliseconds: keep it for reuse).
    pub fn host_buffer(&self, len: usize) -> Result<PinnedHostSlice<f32>, SimError> {
        // SAFETY: the memory is written by the copy before it is read. Plain page-locked
        // memory (not write-combined: the host reads it).
        unsafe {
            self.stream
                .context()
                .alloc_pinned_with_flags::<f32>(len.max(1), 0)
        }
        .map_err(err("allocate page-locked memory"))
    }

    /// [`CudaBackend::read_vec3_ordered`] straight into page-locked memory of `3 n` floats (from
    /// [`CudaBackend::host_buffer`]): one copy at the bus's rate, no host copy.
    pub fn read_vec3_ordered_pinned(
        &mut self,
        first: usize,
        out: &mut PinnedHostSlice<f32>,
    ) -> Result<(), SimError> {
        self.gather_vec3(first, out.len())?;
        let stream = self.stream.clone();
        let (Some(ordered), Some(bad)) = (self.staging.ordered.as_ref(), self.staging.bad.as_ref())
        else {
            return Err(SimError::Backend("CUDA: no export memory".into()));
        };
        let len = 3 * self.n;
        stream
            .memcpy_dtoh(&ordered.slice(0..len), out)
            .map_err(err("read the export array"))?;
        check_flag(&stream, bad)?;
        out.as_slice().map_err(err("wait for the export"))?;
        Ok(())
    }

    /// The export kernel: the three fields from `first` of every particle into
    /// `staging.ordered` in original order. `out_len` is the caller's buffer length (3 n).
    fn gather_vec3(&mut self, first: usize, out_len: usize) -> Result<(), SimError> {
        self.check_vec3_export(first, out_len)?;
        let len = 3 * self.n;
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
        let (Some(ordered), Some(bad)) = (self.staging.ordered.as_mut(), self.staging.bad.as_mut())
        else {
            return Err(SimError::Backend("CUDA: no export memory".into()));
        };
        let (n, cap) = (self.n, self.ctx.cap);
        launch_export_vec3(
            &self.stream,
            &self.kernels,
            (&self.buffers.state, cap, n, first),
            ordered,
            bad,
        )
    }

    /// `first` names the positions or the velocities, and `out_len` is `3 n`.
    fn check_vec3_export(&self, first: usize, out_len: usize) -> Result<(), SimError> {
        if out_len != 3 * self.n {
            return Err(SimError::Backend(format!(
                "CUDA: {out_len} floats given for the 3 x {} of the export",
                self.n
            )));
        }
        if first != self.layout.x() && first != self.layout.v() {
            return Err(SimError::Backend(format!(
                "CUDA: word {first} is neither the positions ({}) nor the velocities ({})",
                self.layout.x(),
                self.layout.v()
            )));
        }
        Ok(())
    }

    /// [`CudaBackend::read_vec3_ordered`] into `out` (`3 n` floats), e.g. memory that is reused
    /// between reads, so that no page of it is mapped during the copy.
    pub fn read_vec3_ordered_into(
        &mut self,
        first: usize,
        out: &mut [f32],
    ) -> Result<(), SimError> {
        self.gather_vec3(first, out.len())?;
        let len = 3 * self.n;
        self.pinned(len * 4)?;
        let stream = self.stream.clone();
        let (Some(ordered), Some(bad), Some(pinned)) = (
            self.staging.ordered.as_ref(),
            self.staging.bad.as_ref(),
            self.staging.pinned.as_mut(),
        ) else {
            return Err(SimError::Backend("CUDA: no export memory".into()));
        };
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
        check_flag(&stream, bad)
    }
}

/// Positions or velocities of every particle in original order on the device: `3 n` float32,
/// row-major `(n, 3)` (NumPy's and PyTorch's contiguous layout), filled by
/// [`CudaBackend::gather_vec3_device`] and kept by the caller (its address stays the same for its
/// life, so views of it made once see every later gather).
pub struct OrderedDeviceVec3 {
    out: CudaSlice<f32>,
    bad: CudaSlice<u32>,
    stream: Arc<CudaStream>,
}

impl OrderedDeviceVec3 {
    /// Device address of float 0.
    pub fn ptr(&self) -> u64 {
        self.out.device_ptr(&self.stream).0
    }

    /// Floats (`3 n`).
    pub fn len(&self) -> usize {
        self.out.len()
    }

    /// Whether it holds no float (never: at least one is allocated).
    pub fn is_empty(&self) -> bool {
        self.out.len() == 0
    }

    /// CUDA device ordinal.
    pub fn device(&self) -> usize {
        self.stream.context().ordinal()
    }

    /// Overwrite rows `row..row + values.len() / 3` with `values` (float32, x0, y0, z0, x1, ...)
    /// from the host, e.g. a batch's frozen world whose host arrays keep its last good state.
    /// Synchronises.
    pub fn write_rows(&mut self, row: usize, values: &[f32]) -> Result<(), SimError> {
        let (at, end) = (3 * row, 3 * row + values.len());
        if !values.len().is_multiple_of(3) || end > self.out.len() {
            return Err(SimError::Backend(format!(
                "CUDA: {} floats from row {row} do not fit {} rows of 3",
                values.len(),
                self.out.len() / 3
            )));
        }
        let mut dst = self.out.slice_mut(at..end);
        self.stream
            .memcpy_htod(values, &mut dst)
            .map_err(err("write rows of an ordered device array"))?;
        self.stream
            .synchronize()
            .map_err(err("write rows of an ordered device array"))
    }
}

impl CudaBackend {
    /// A device array for [`CudaBackend::gather_vec3_device`]: `3 n` float32, zeros.
    pub fn ordered_device_vec3(&self) -> Result<OrderedDeviceVec3, SimError> {
        let out = self
            .stream
            .alloc_zeros::<f32>((3 * self.n).max(1))
            .map_err(err("allocate an ordered device array"))?;
        let bad = self
            .stream
            .alloc_zeros::<u32>(1)
            .map_err(err("allocate the export flag"))?;
        Ok(OrderedDeviceVec3 {
            out,
            bad,
            stream: self.stream.clone(),
        })
    }

    /// The positions (`first` = the layout's `x()`) or velocities (`v()`, decoded in a compact
    /// layout) of every particle into `out` on the device, in original particle order, float32
    /// (f64 state rounded to nearest, as [`CudaBackend::read_vec3_ordered`] gives them): the
    /// export kernel alone, nothing crosses the bus but its error flag. Synchronises.
    pub fn gather_vec3_device(
        &mut self,
        first: usize,
        out: &mut OrderedDeviceVec3,
    ) -> Result<(), SimError> {
        self.check_vec3_export(first, out.len())?;
        let (n, cap) = (self.n, self.ctx.cap);
        launch_export_vec3(
            &self.stream,
            &self.kernels,
            (&self.buffers.state, cap, n, first),
            &mut out.out,
            &mut out.bad,
        )?;
        let stream = &self.stream;
        self.waits.wait(crate::waits::WaitReason::Control, || {
            check_flag(stream, &out.bad)
        })
    }
}

/// Launch `export_vec3`: the three words from `first` of the `n` slots of `state` (stride `cap`)
/// into `out` (at least `3 n` floats) at each slot's original index; an index out of range sets
/// `bad` (cleared first). Queued on `stream`, not waited for.
fn launch_export_vec3(
    stream: &Arc<CudaStream>,
    kernels: &Kernels,
    (state, cap, n, first): (&CudaSlice<u8>, u32, usize, usize),
    out: &mut CudaSlice<f32>,
    bad: &mut CudaSlice<u32>,
) -> Result<(), SimError> {
    stream
        .memset_zeros(bad)
        .map_err(err("clear the export flag"))?;
    let (n32, first32) = (n as u32, first as i32);
    // SAFETY: the kernel reads slots 0..n of the state (stride cap) and writes 3 n floats of
    // `out` (at least that long: the callers' length checks) at ids checked against n.
    unsafe {
        stream
            .launch_builder(&kernels[Kernel::ExportVec3])
            .arg(state)
            .arg(&cap)
            .arg(&n32)
            .arg(&first32)
            .arg(&mut *out)
            .arg(&mut *bad)
            .launch(kernels.wave(n, 256))
    }
    .map_err(err("export kernel"))?;
    Ok(())
}

/// The export's error flag; read after the copies (a copy into pageable memory waits for the
/// whole stream).
fn check_flag(stream: &std::sync::Arc<CudaStream>, bad: &CudaSlice<u32>) -> Result<(), SimError> {
    let mut flag = [0u32];
    stream
        .memcpy_dtoh(bad, &mut flag)
        .map_err(err("read the export flag"))?;
    if flag[0] != 0 {
        return Err(SimError::Backend(
            "CUDA: a particle's original index is out of range".into(),
        ));
    }
    Ok(())
}
