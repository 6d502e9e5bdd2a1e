//! The control words copied for checks made later ([`CheckCopies`]; `check.rs` queues and reads
//! them).

use cudarc::driver::{CudaEvent, PinnedHostSlice};
use std::collections::VecDeque;

/// The control words copied behind steps queued, oldest first (`CudaBackend::queue_check`),
/// for the checks made later, and the copies' memory kept for the next.
#[derive(Default)]
pub(crate) struct CheckCopies {
    pub(super) queued: VecDeque<WordsCopy>,
    pub(super) free: Vec<WordsCopy>,
}

/// Page-locked room for the control words and the event after the copy into it.
pub(super) struct WordsCopy {
    pub(super) words: PinnedHostSlice<u32>,
    pub(super) done: CudaEvent,
}

impl CheckCopies {
    /// Every queued copy dropped (their memory kept): a check found a bad particle or an error,
    /// so what the later copies say is of steps taken again after the rewind.
    pub(super) fn discard(&mut self) {
        self.free.extend(self.queued.drain(..));
    }
}

impl Drop for CheckCopies {
    /// No page-locked memory is freed while a queued copy may still write it (a check left
    /// pending as the backend goes).
    fn drop(&mut self) {
        for c in &self.queued {
            let _ = c.done.synchronize();
        }
    }
}
