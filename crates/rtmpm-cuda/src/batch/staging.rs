//! The page-locked memory a batch's uploads go through ([`PutStaging`]: the puts of `put.rs`, the
//! rigid bodies' table of `bodies.rs`) and the switch back to pageable memory ([`pageable_puts`]).

use crate::error::err;
use cudarc::driver::{CudaSlice, CudaStream, DevicePtrMut};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// The page-locked memory of the puts and the event after the last copy out of it.
#[derive(Default)]
pub(super) struct PutStaging {
    pub(super) pinned: Option<cudarc::driver::PinnedHostSlice<u8>>,
    pub(super) done: Option<cudarc::driver::CudaEvent>,
}

impl PutStaging {
    /// Wait until the last put's copy has read the page-locked memory (then it may be written
    /// or freed).
    pub(super) fn wait(&mut self) -> Result<(), SimError> {
        match self.done.take() {
            Some(done) => done
                .synchronize()
                .map_err(err("wait for the last put's copy")),
            None => Ok(()),
        }
    }
}

impl PutStaging {
    /// Copy `bytes` to the start of `dst` (at least as long) on `stream` through this page-locked
    /// memory: an asynchronous copy that returns at once even while work is queued ahead of it
    /// on the stream (a copy from pageable memory waits for the stream to reach it). The memory
    /// is written once the previous copy out of it is done, and grown (reallocated) to fit.
    pub(super) fn copy_to_device(
        &mut self,
        stream: &Arc<CudaStream>,
        bytes: &[u8],
        dst: &mut CudaSlice<u8>,
    ) -> Result<(), SimError> {
        let len = bytes.len();
        assert!(dst.len() >= len, "a staged copy past its destination");
        self.wait()?;
        if self.pinned.as_ref().is_none_or(|p| p.len() < len) {
            self.pinned = None;
            // SAFETY: bytes below `len` are written below before the copy reads them. Plain
            // page-locked memory (the host writes it, the copy engine reads it).
            let pinned = unsafe {
                stream
                    .context()
                    .alloc_pinned_with_flags::<u8>(len.max(1), 0)
            }
            .map_err(err("allocate page-locked memory for an upload"))?;
            self.pinned = Some(pinned);
        }
        let Some(pinned) = self.pinned.as_mut() else {
            return Ok(());
        };
        let host = pinned
            .as_mut_slice()
            .map_err(err("page-locked memory for an upload"))?;
        host[..len].copy_from_slice(bytes);
        let (ptr, _written) = dst.device_ptr_mut(stream);
        // SAFETY: `ptr` holds at least `len` bytes (checked above); `host[..len]` stays alive and
        // unwritten until the event recorded next has passed: the next copy through this
        // memory, its growth and its drop all wait for it first (`PutStaging::wait`).
        unsafe { cudarc::driver::result::memcpy_htod_async(ptr, &host[..len], stream.cu_stream()) }
            .map_err(err("upload through page-locked memory"))?;
        self.done = Some(
            stream
                .record_event(None)
                .map_err(err("record the upload's event"))?,
        );
        Ok(())
    }
}

impl Drop for PutStaging {
    /// The memory is not freed while a copy may still read it.
    fn drop(&mut self) {
        let _ = self.wait();
    }
}

/// Puts go to the device from pageable memory, as before the page-locked upload
/// (`RTMPM_BATCH_PAGEABLE_PUT=1`; for comparing the two: bench/python_batch_gpu.py). Read once.
pub(super) fn pageable_puts() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("RTMPM_BATCH_PAGEABLE_PUT").is_ok_and(|v| v.trim() == "1"))
}
