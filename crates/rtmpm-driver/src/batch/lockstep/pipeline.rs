//! Pipelined calls (deferred checks, [`LockstepRun::set_deferred_checks`]): a call queues its
//! steps before it waits for the last call's check, so the device goes from the last call's
//! steps to this call's without waiting for the host. The call keeps its bodies and its rewind
//! point (in the backend's second slot, [`Worlds::save_next_point`]: the last call's point stays
//! what a rewind for that call goes back to) and queues its steps as a deferred call does, its
//! own check left pending; then it makes the last call's check. When that passes, this call's
//! point is made current ([`Worlds::use_next_point`]) and its check stays pending. When it finds
//! a blow-up, this call's steps are dropped ([`Worlds::drop_queued_steps`], its records too), the
//! last call is put back and stepped again as [`LockstepRun::settle`] does (the resets and poses
//! made since made again), and this call is advanced again from there: the worlds, statuses and
//! frozen lists end as without pipelining, bit for bit on a backend that is bit-reproducible.
//!
//! Only where the backend queues what each check reads behind its steps
//! ([`Worlds::queues_checks`]: a check must read the last call's words, not this call's), keeps
//! a second rewind point, and has no cheap check made after each step; otherwise a call settles
//! first, as before. `RTMPM_BATCH_PIPELINE=off` (or [`LockstepRun::set_pipelined`]) turns it off
//! for an A/B in one binary.

use super::LockstepRun;
use super::deferred::Ahead;
use anyhow::{Context, Result, bail};
use rtmpm_sim::Worlds;

/// `RTMPM_STEP_TIMING=1`: a pipelined call's host time, printed to stderr every 100 such calls:
/// the work ahead (bodies, next point), the steps queued (with this call's record), and the last
/// call's check (its wait for the device to end that call's steps; a rewind when it finds one).
static PIPELINE_TIMING: rtmpm_sim::timing::PartTimes<3> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_STEP_TIMING",
    "pipelined call",
    "calls",
    ["work ahead", "steps queued", "last check"],
);

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// Queue a call's steps before the last call's check is made (`true`, the default unless
    /// `RTMPM_BATCH_PIPELINE=off`), where the checks are deferred and the backend allows it
    /// (the module's doc); `false`: each call makes the last call's check first, then queues.
    pub fn set_pipelined(&mut self, on: bool) {
        self.pipeline = on;
    }

    /// Whether calls are pipelined where they can be ([`LockstepRun::set_pipelined`]).
    pub fn pipelined(&self) -> bool {
        self.pipeline
    }

    /// Whether this call can queue its steps before the pending check: pipelining on, a check
    /// pending and nothing found outside a call, and a backend that queues its checks' reads
    /// and makes no check after each step.
    pub(super) fn can_pipeline(&self) -> bool {
        let b = &self.sim.backend;
        self.pipeline
            && self.pending.is_some()
            && self.found.is_empty()
            && b.queues_checks()
            && !b.cheap_check()
    }

    /// [`LockstepRun::advance_steps`] pipelined (the module's doc): the worlds frozen (found by
    /// the last call's check).
    pub(super) fn advance_pipelined(&mut self, steps: u64) -> Result<Vec<usize>> {
        let t0 = std::time::Instant::now();
        let point = self.work_ahead()?;
        if !point {
            // No second slot for this call's point: the last call's check first.
            let rewound = self.settle_found()?;
            let mut frozen = std::mem::take(&mut self.found);
            if self.running() > 0 {
                let ahead = (!rewound).then_some(Ahead {
                    point: false,
                    take_up: false,
                });
                frozen.extend(self.advance_deferred(steps, ahead)?);
            }
            return Ok(frozen);
        }
        let last = self
            .pending
            .take()
            .context("no pending check to pipeline after")?;
        let t1 = std::time::Instant::now();
        let ahead = Ahead {
            point: true,
            take_up: false,
        };
        let queued = self.advance_deferred(steps, Some(ahead))?;
        if !queued.is_empty() {
            // Only a check made inside the call freezes a world, which a backend that queues its
            // checks' reads does not make (`can_pipeline`).
            bail!(
                "a pipelined call froze worlds {queued:?} before the last call's check: the \
                 backend `{}` made a check inside the call although it queues its checks' reads \
                 (`Worlds::queues_checks`)\n  fix: RTMPM_BATCH_PIPELINE=off",
                self.sim.backend.name()
            );
        }
        let this = self.pending.take();
        let t2 = std::time::Instant::now();
        let failed = self.check_record(last, true)?;
        let mut frozen = std::mem::take(&mut self.found);
        if !failed {
            self.sim
                .backend
                .use_next_point()
                .context("taking up the call's rewind point")?;
            self.pending = this;
            PIPELINE_TIMING.record(1, [t0, t1, t2], std::time::Instant::now());
            return Ok(frozen);
        }
        // The last call rewound and stepped again (the changes since made again): this call's
        // steps and records dropped, and the call made again from there.
        if let Some(p) = this {
            self.spare = Some(p);
        }
        if self.running() > 0 {
            frozen.extend(self.advance_deferred(steps, None)?);
        }
        Ok(frozen)
    }
}
