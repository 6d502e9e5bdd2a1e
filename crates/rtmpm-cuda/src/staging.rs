//! Page-locked buffers that uploads go through ([`StagingRing`]): a batch's puts, its rigid
//! bodies' table and its worlds' moving collider poses (`batch/`), a backend's step parameters
//! and collider poses when they change (`backend/mod.rs`).

use crate::error::err;
use crate::waits::{HostWaits, WaitReason, old_waits};
use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::{CudaEvent, CudaStream, DevicePtrMut, PinnedHostSlice};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// One page-locked buffer of a ring and the event after the last copy out of it.
struct Slot {
    pinned: PinnedHostSlice<u8>,
    done: CudaEvent,
    /// A copy out of it was queued (`done` recorded after it).
    queued: bool,
}

impl Slot {
    /// No copy still reads it (an error of the query counts as busy: waited for later).
    fn free(&self) -> bool {
        !self.queued || self.done.try_is_complete().unwrap_or(false)
    }
}

/// Page-locked buffers that uploads go through: a copy from one is asynchronous and returns at
/// once even while work is queued ahead of it on the stream (a copy from pageable memory may
/// wait for the stream to reach it). An upload takes a buffer whose last copy is done (asked of
/// its event, no wait), else a new buffer while there are fewer than the ring's most, else
/// waits for the oldest (a [`WaitReason::Staging`] wait: the host that many uploads ahead of
/// the device). With `in_turn` (`RTMPM_BATCH_WAITS=old`) the buffers are used in turn, each
/// waited for before it is written, as before.
pub(crate) struct StagingRing {
    slots: Vec<Slot>,
    /// The buffer the next upload looks at first (the oldest in use).
    next: usize,
    /// The most buffers.
    most: usize,
    in_turn: bool,
}

impl StagingRing {
    /// A ring of at most `most` buffers (`old`: `old` of them, used in turn, with
    /// `RTMPM_BATCH_WAITS=old`); none allocated before the first upload.
    pub(crate) fn new(most: usize, old: usize) -> StagingRing {
        let in_turn = old_waits();
        StagingRing {
            slots: Vec::new(),
            next: 0,
            most: if in_turn { old.max(1) } else { most.max(1) },
            in_turn,
        }
    }

    /// At least `count` buffers of `len` bytes (no more than the ring's most) allocated now (each
    /// an [`WaitReason::Alloc`] wait), so that uploads that far ahead of the device find one
    /// free instead of allocating it then.
    pub(crate) fn reserve(
        &mut self,
        stream: &Arc<CudaStream>,
        count: usize,
        len: usize,
        waits: &HostWaits,
    ) -> Result<(), SimError> {
        while self.slots.len() < count.min(self.most) {
            self.slots.push(new_slot(stream, len, waits)?);
        }
        Ok(())
    }

    /// Copy `bytes` to the start of `dst` (at least as long) on `stream` through a buffer of
    /// the ring (written once its previous copy is done; grown to fit), the host's waits
    /// counted in `waits`.
    pub(crate) fn copy_to_device(
        &mut self,
        stream: &Arc<CudaStream>,
        bytes: &[u8],
        dst: &mut impl DevicePtrMut<u8>,
        waits: &HostWaits,
    ) -> Result<(), SimError> {
        let len = bytes.len();
        assert!(dst.len() >= len, "a staged copy past its destination");
        let k = self.slot_for(stream, len, waits)?;
        let slot = &mut self.slots[k];
        let host = slot
            .pinned
            .as_mut_slice()
            .map_err(err("page-locked memory for an upload"))?;
        host[..len].copy_from_slice(bytes);
        stream
            .context()
            .bind_to_thread()
            .map_err(err("upload through page-locked memory"))?;
        let (ptr, _written) = dst.device_ptr_mut(stream);
        // SAFETY: `ptr` holds at least `len` bytes (checked above); `host[..len]` stays alive and
        // unwritten until the event recorded next has passed: a slot is written, grown or
        // dropped only once its event is complete (`Slot::free`, waited for otherwise).
        unsafe { cudarc::driver::result::memcpy_htod_async(ptr, &host[..len], stream.cu_stream()) }
            .map_err(err("upload through page-locked memory"))?;
        slot.done
            .record(stream)
            .map_err(err("record the upload's event"))?;
        slot.queued = true;
        self.next = (k + 1) % self.slots.len();
        Ok(())
    }

    /// The buffer the next upload of `len` bytes goes through: a free one (from the oldest on;
    /// in turn: the next, waited for), else a new one, else the oldest waited for; grown to
    /// `len` when smaller.
    fn slot_for(
        &mut self,
        stream: &Arc<CudaStream>,
        len: usize,
        waits: &HostWaits,
    ) -> Result<usize, SimError> {
        let n = self.slots.len();
        let found = if self.in_turn {
            (n == self.most).then_some(self.next)
        } else {
            (0..n)
                .map(|i| (self.next + i) % n)
                .find(|&k| self.slots[k].free())
        };
        let k = match found {
            Some(k) => k,
            None if n < self.most => {
                self.slots.push(new_slot(stream, len, waits)?);
                return Ok(n);
            }
            None => self.next,
        };
        let slot = &mut self.slots[k];
        if !slot.free() || self.in_turn {
            waits
                .wait(WaitReason::Staging, || slot.done.synchronize())
                .map_err(err("wait for an earlier upload's copy"))?;
        }
        slot.queued = false;
        if slot.pinned.len() < len {
            *slot = new_slot(stream, len, waits)?;
        }
        Ok(k)
    }
}

/// A buffer of `len` bytes (at least one) and its event (an [`WaitReason::Alloc`] wait).
fn new_slot(stream: &Arc<CudaStream>, len: usize, waits: &HostWaits) -> Result<Slot, SimError> {
    let ctx = stream.context();
    // SAFETY: bytes below `len` are written before a copy reads them. Plain page-locked memory
    // (the host writes it, the copy engine reads it).
    let pinned = waits
        .wait(WaitReason::Alloc, || unsafe {
            ctx.alloc_pinned_with_flags::<u8>(len.max(1), 0)
        })
        .map_err(err("allocate page-locked memory for an upload"))?;
    let done = ctx
        .new_event(Some(CUevent_flags::CU_EVENT_DISABLE_TIMING))
        .map_err(err("an upload's event"))?;
    Ok(Slot {
        pinned,
        done,
        queued: false,
    })
}

impl Drop for StagingRing {
    /// No buffer is freed while a copy may still read it.
    fn drop(&mut self) {
        for s in self.slots.iter().filter(|s| s.queued) {
            let _ = s.done.synchronize();
        }
    }
}
