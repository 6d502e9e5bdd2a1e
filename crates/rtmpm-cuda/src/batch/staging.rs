//! The page-locked memory a batch's puts go through ([`PutStaging`], used by `put.rs`).

use crate::error::err;
use rtmpm_sim::SimError;

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

impl Drop for PutStaging {
    /// The memory is not freed while a copy may still read it.
    fn drop(&mut self) {
        let _ = self.wait();
    }
}
