//! The health check's control words without needless waits: a caller that checks steps later
//! (the lockstep driver's deferred checks, `rtmpm_sim::Worlds::queue_check`) has the words copied
//! to page-locked memory right behind those steps ([`CudaBackend::queue_check`]; a copy at each
//! frame end inside a call and one at its end), so each check waits for its copy's event alone,
//! not for what was queued since (the next steps, a reset's upload and launches); and the
//! control words are written by a device memset, not a copy from pageable memory (which the
//! driver may make wait for the stream). `RTMPM_BATCH_WAITS=old` ([`crate::waits::old_waits`])
//! keeps the paths before both, for comparisons.

use super::CudaBackend;
use super::check_copies::WordsCopy;
use crate::contract::{CTL_BAD_INDEX, CTL_BAD_REASON, CTL_ERROR, CTL_WORDS, bad_particle};
use crate::error::err;
use crate::waits::WaitReason;
use crate::waits::old_waits;
use cudarc::driver::DevicePtrMut;
use cudarc::driver::sys::CUevent_flags;
use rtmpm_sim::{BadParticle, SimError};

impl CudaBackend {
    /// Queue a copy of the control words behind the steps queued so far, into page-locked
    /// memory, with an event after it (`true`): the next check ([`rtmpm_sim::Backend::check`])
    /// reads the oldest copy queued, waiting for its event alone rather than reading the words
    /// then (a wait for everything queued by then: the next steps, a reset's upload and
    /// launches). For a caller that checks steps later, each copy by the clock it was queued at
    /// (the lockstep driver's deferred checks: a frame's end inside a call, the call's end).
    /// `false` with `RTMPM_BATCH_WAITS=old`: nothing queued, the checks read the words when made.
    pub fn queue_check(&mut self) -> Result<bool, SimError> {
        if old_waits() {
            return Ok(false);
        }
        let copy = match self.check_copies.free.pop() {
            Some(c) => c,
            None => {
                let ctx = self.stream.context();
                // SAFETY: the copy below writes every word before the host reads any (after
                // its event).
                let words = self
                    .waits
                    .wait(WaitReason::Alloc, || unsafe {
                        ctx.alloc_pinned_with_flags::<u32>(CTL_WORDS, 0)
                    })
                    .map_err(err("allocate page-locked memory for the check"))?;
                let done = ctx
                    .new_event(Some(CUevent_flags::CU_EVENT_DISABLE_TIMING))
                    .map_err(err("the check's event"))?;
                WordsCopy { words, done }
            }
        };
        let mut copy = copy;
        self.stream
            .memcpy_dtoh(&self.buffers.ctl, &mut copy.words)
            .map_err(err("copy the control words for the check"))?;
        copy.done
            .record(&self.stream)
            .map_err(err("record the check's event"))?;
        self.check_copies.queued.push_back(copy);
        Ok(true)
    }

    /// Whether [`CudaBackend::queue_check`] queues copies (not with `RTMPM_BATCH_WAITS=old`).
    pub fn queues_checks(&self) -> bool {
        !old_waits()
    }

    /// The words the check reads: the oldest copy [`CudaBackend::queue_check`] queued (a wait
    /// for its event), else the control words read now (a wait for the stream).
    fn checked_words(&mut self) -> Result<Vec<u32>, SimError> {
        let Some(copy) = self.check_copies.queued.pop_front() else {
            return self.ctl_words_for(WaitReason::Check);
        };
        let read = self
            .waits
            .wait(WaitReason::Check, || copy.done.synchronize())
            .map_err(err("wait for the check's control words"))
            .and_then(|()| {
                copy.words
                    .as_slice()
                    .map(<[u32]>::to_vec)
                    .map_err(err("the check's page-locked words"))
            });
        self.check_copies.free.push(copy);
        read
    }

    /// [`rtmpm_sim::Backend::check`]: the errors the device reported, then the first bad
    /// particle since the last check (its words reset for the next), from
    /// [`CudaBackend::checked_words`]; a bad particle or an error drops the later copies.
    pub(crate) fn check_now(&mut self) -> Result<Option<BadParticle>, SimError> {
        let c = self.checked_words()?;
        let bad = bad_particle(c[CTL_BAD_INDEX]);
        if c[CTL_ERROR] != 0 || bad.is_some() {
            self.check_copies.discard();
        }
        self.error_check(&c)?;
        let Some(bad) = bad else {
            return Ok(None);
        };
        if old_waits() {
            let reset = [u32::MAX, 0];
            let mut view = self.buffers.ctl.slice_mut(CTL_BAD_INDEX..CTL_BAD_INDEX + 2);
            self.waits.wait(WaitReason::Pageable, || ());
            self.stream
                .memcpy_htod(&reset, &mut view)
                .map_err(err("reset bad particle"))?;
        } else {
            self.set_ctl_word(CTL_BAD_INDEX, u32::MAX)?;
            self.set_ctl_word(CTL_BAD_REASON, 0)?;
        }
        Ok(Some(bad))
    }

    /// Every control word, read now (a wait for the stream, counted as `why`).
    pub(crate) fn ctl_words_for(&mut self, why: WaitReason) -> Result<Vec<u32>, SimError> {
        self.waits
            .wait(why, || self.stream.clone_dtoh(&self.buffers.ctl))
            .map_err(err("read control words"))
    }

    /// Write one control word, on the compute stream: a device memset (no host memory, no
    /// wait); with `RTMPM_BATCH_WAITS=old` a copy from pageable memory, as before.
    pub(crate) fn set_ctl_word(&mut self, word: usize, value: u32) -> Result<(), SimError> {
        let mut view = self.buffers.ctl.slice_mut(word..word + 1);
        if old_waits() {
            self.waits.wait(WaitReason::Pageable, || ());
            return self
                .stream
                .memcpy_htod(&[value], &mut view)
                .map_err(err("write control word"));
        }
        self.stream
            .context()
            .bind_to_thread()
            .map_err(err("write control word"))?;
        let (ptr, _written) = view.device_ptr_mut(&self.stream);
        // SAFETY: `ptr` is one u32 word of the control words, alive with the backend.
        unsafe { cudarc::driver::sys::cuMemsetD32Async(ptr, value, 1, self.stream.cu_stream()) }
            .result()
            .map_err(err("write control word"))
    }
}
