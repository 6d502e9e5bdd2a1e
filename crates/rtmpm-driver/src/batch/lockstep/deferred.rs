//! Deferred checks ([`LockstepRun::set_deferred_checks`]): an advance returns with its steps
//! queued, before the health check of its last step, so the host goes on while the device steps;
//! [`LockstepRun::settle`] makes the check later and, when it finds a blow-up, puts the worlds
//! back as the advance would have, then makes again the resets and poses made meanwhile.
//!
//! The next call's host work that does not depend on that check is done before its wait
//! ([`LockstepRun::start_deferred_call`]): every world's bodies kept, the next rewind point
//! queued into the backend's second slot ([`Worlds::save_next_point`]: stream order makes it the
//! state after the last call's steps and the resets since), the first step's host preparation
//! ([`Worlds::prepare_steps`]); the device works on the last call's steps meanwhile. When the
//! check passes the call goes on from there (the point made current,
//! [`Worlds::use_next_point`]); when it finds a blow-up the rewind goes back to the last call's
//! point (untouched by the early save) and the call does that work again after it.

use super::{LockstepRun, Pending, Since, steps_of};
use anyhow::{Context, Result};
use rtmpm_physics::Particles;
use rtmpm_rigid::BodyPose;
use rtmpm_sim::{SimError, Worlds};

/// `RTMPM_STEP_TIMING=1`: where an advance with its check deferred (Python's `step` with
/// `overlap`) spends the host's time, printed to stderr every 100 advances (the means of keeping
/// every world's bodies, keeping the rewind point, queueing the steps, and keeping what a later
/// rewind needs); off by default. The check itself is made by `settle`, as the next call begins.
static DEFERRED_TIMING: rtmpm_sim::timing::PartTimes<4> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_STEP_TIMING",
    "deferred advance",
    "advances",
    ["bodies kept", "point kept", "steps queued", "pending kept"],
);

/// `RTMPM_STEP_TIMING=1`: how a call begins while the last call's check is pending (Python's
/// `step` with `overlap`), printed to stderr every 100 such calls: the host's work done ahead of
/// that check (bodies kept, the next point queued, the first step prepared) and the check itself
/// (its wait for the device to end the last call's steps, and a rewind when it finds one).
static AHEAD_TIMING: rtmpm_sim::timing::PartTimes<2> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_STEP_TIMING",
    "deferred call start",
    "calls",
    ["work ahead", "settle"],
);

/// What a call did ahead of the last call's check ([`LockstepRun::start_deferred_call`]):
/// every world's bodies kept, and, with `point`, the next rewind point in the backend's second
/// slot; `take_up`: the advance makes that point current as it begins (the check passed), else
/// the caller does once it passes (a pipelined call).
#[derive(Clone, Copy, Debug)]
pub(super) struct Ahead {
    pub(super) point: bool,
    pub(super) take_up: bool,
}

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// Return from [`LockstepRun::advance_steps`] with its steps queued, before the health
    /// check of their last step (`true`), or after it (`false`, the default). Deferred, the
    /// host goes on (a script's resets and poses for the next call, its own work) while the
    /// device steps; the check is made by [`LockstepRun::settle`], at the start of the next
    /// advance, [`LockstepRun::sync`] or checkpoint, or when the caller asks (a read of the
    /// worlds' status). What it finds is handled as if the call had found it: the world frozen,
    /// every world put back to the call's rewind point and its steps taken again, then every
    /// reset ([`LockstepRun::reset_worlds`]) and pose ([`LockstepRun::set_body_poses`]) made
    /// since made again, in order; the worlds frozen are returned by the next advance. Only
    /// for a fixed time step (a CFL step waits for each step's speed anyway) and a backend that
    /// keeps its rewind point (otherwise the calls check as before). Turning it off settles
    /// first.
    pub fn set_deferred_checks(&mut self, on: bool) -> Result<()> {
        if !on {
            self.settle()?;
        }
        self.defer = on;
        Ok(())
    }

    /// Whether [`LockstepRun::advance_steps`] returns before its last check.
    pub fn deferred_checks(&self) -> bool {
        self.defer
    }

    /// A check still to be made ([`LockstepRun::set_deferred_checks`]).
    pub fn check_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// As [`LockstepRun::advance_steps`] begins: where the last call's check is pending, the
    /// coming steps' host work that does not depend on it done first, while the device ends
    /// that call's steps (the bodies kept as the steps begin, the next rewind point queued, the
    /// first step's host preparation), then the check ([`LockstepRun::settle`]). What was done
    /// ahead (`None` when nothing was pending, or when the check rewound the worlds: the
    /// rewind changed what it kept, so the advance does it all again).
    pub(super) fn start_deferred_call(&mut self) -> Result<Option<Ahead>> {
        if self.pending.is_none() {
            self.settle()?;
            return Ok(None);
        }
        let t0 = std::time::Instant::now();
        let point = self.work_ahead()?;
        let t1 = std::time::Instant::now();
        let rewound = self.settle_found()?;
        AHEAD_TIMING.record(1, [t0, t1], std::time::Instant::now());
        Ok((!rewound).then_some(Ahead {
            point,
            take_up: true,
        }))
    }

    /// The coming steps' host work that does not depend on the pending check: every world's
    /// bodies kept as the steps begin, the next rewind point queued into the backend's second
    /// slot (`true` where it has one), the first step's host preparation.
    pub(super) fn work_ahead(&mut self) -> Result<bool> {
        self.keep_bodies()?;
        let point = self
            .sim
            .backend
            .save_next_point()
            .context("keeping the next rewind point")?;
        self.sim
            .backend
            .prepare_steps()
            .context("preparing the steps")?;
        Ok(point)
    }

    /// [`LockstepRun::advance_steps`] with the last check deferred: the steps queued, the
    /// worlds' clocks and bodies noted as if no world failed, what a rewind needs kept (the
    /// bodies and the point kept already where `ahead` says so).
    pub(super) fn advance_deferred(
        &mut self,
        steps: u64,
        ahead: Option<Ahead>,
    ) -> Result<Vec<usize>> {
        let t0 = std::time::Instant::now();
        let clock = self.clock();
        if ahead.is_none() {
            self.keep_bodies()?;
        }
        let t1 = std::time::Instant::now();
        let on_backend = if let Some(a) = ahead.filter(|a| a.point) {
            if a.take_up {
                self.sim
                    .backend
                    .use_next_point()
                    .context("taking up the next rewind point")?;
            }
            true
        } else {
            self.sim
                .backend
                .save_point()
                .context("keeping the worlds' rewind point")?
        };
        if !on_backend {
            self.sync()?;
        }
        let t2 = std::time::Instant::now();
        // A backend that queues what a check reads has a frame end's check inside the call
        // queued too (made by `settle`, at that frame end's clock), not made now.
        let queue = on_backend && self.sim.backend.queues_checks();
        let mut marks = Vec::new();
        let queued = (|| {
            let target = self.sim.step.saturating_add(steps);
            while self.sim.step < target {
                if queue {
                    let frame_ended = self.sim.advance_no_checks(target - self.sim.step)?;
                    if frame_ended && self.sim.step < target {
                        if self.sim.backend.queue_check()? {
                            marks.push(self.clock());
                        } else {
                            self.sim.check()?;
                        }
                    }
                } else if on_backend {
                    self.sim.advance_unchecked(target - self.sim.step)?;
                } else {
                    self.sim.advance(target - self.sim.step)?;
                }
            }
            Ok(())
        })();
        let t3 = std::time::Instant::now();
        let frozen = match queued {
            Ok(()) if on_backend => {
                // What the check reads, queued behind these steps (read when it is made).
                self.sim
                    .backend
                    .queue_check()
                    .context("queueing the deferred check's read")?;
                // Into the last record's memory where there is one.
                let mut p = self.spare.take().unwrap_or_default();
                (p.clock, p.marks, p.end, p.steps) = (clock, marks, self.clock(), steps);
                p.statuses.clear();
                p.statuses
                    .extend(self.worlds.iter().map(|w| w.status.clone()));
                p.bodies.resize_with(self.worlds.len(), Vec::new);
                for (kept, w) in p.bodies.iter_mut().zip(&self.worlds) {
                    kept.clone_from(&w.bodies);
                }
                p.at.clear();
                p.at.extend(self.worlds.iter().map(|w| w.at));
                p.origin.clear();
                p.origin.extend(self.worlds.iter().map(|w| w.origin));
                p.since.clear();
                self.pending = Some(p);
                Vec::new()
            }
            Ok(()) => Vec::new(),
            Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => {
                self.rewinds(clock, on_backend, e, steps_of(steps))?
            }
            Err(e) => return Err(e.into()),
        };
        self.after_advance(on_backend, &frozen)?;
        DEFERRED_TIMING.record(1, [t0, t1, t2, t3], std::time::Instant::now());
        Ok(frozen)
    }

    /// Make the check an advance left pending ([`LockstepRun::set_deferred_checks`]), if any:
    /// nothing more when it passes; when it finds a blow-up or stall, the worlds' records back
    /// to the end of that advance, its world frozen and every world put back and stepped again
    /// as the advance would have done, then the resets and poses made since made again (the
    /// worlds frozen are returned by the next advance). An error of the backend itself is
    /// returned.
    pub fn settle(&mut self) -> Result<()> {
        self.settle_found().map(drop)
    }

    /// [`LockstepRun::settle`]; `true` when its check found a failure (the worlds rewound and
    /// stepped again, the changes since made again).
    pub(super) fn settle_found(&mut self) -> Result<bool> {
        let Some(p) = self.pending.take() else {
            return Ok(false);
        };
        self.check_record(p, false)
    }

    /// [`LockstepRun::settle`] of the pending advance `p`; with `queued_after`, the steps of
    /// the next call were queued after it (a pipelined call): when the check fails they are
    /// dropped ([`Worlds::drop_queued_steps`]) before the rewind, whose records the caller
    /// drops.
    pub(super) fn check_record(&mut self, p: Box<Pending>, queued_after: bool) -> Result<bool> {
        // Checked at the clock of each frame end inside the advance whose check was queued, then
        // at the clock the advance ended at (a reset of every world since put it back to 0), as
        // the advance would have checked; the first that fails is the advance's failure.
        let now = self.clock();
        let mut failed = None;
        for at in p.marks.iter().copied().chain([p.end]) {
            self.set_clock(at);
            match self.sim.check() {
                Ok(()) => {}
                Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => {
                    failed = Some(e);
                    break;
                }
                Err(e) => return Err(e.into()),
            }
        }
        let Some(e) = failed else {
            self.set_clock(now);
            self.spare = Some(p);
            return Ok(false);
        };
        if queued_after {
            self.sim
                .backend
                .drop_queued_steps()
                .context("dropping the steps queued after a failed check")?;
        }
        let Pending {
            clock,
            marks: _,
            end: _,
            steps,
            statuses,
            bodies,
            at,
            origin,
            since,
        } = *p;
        // The particles the worlds reset since were put to (they keep them), for the replay.
        let mut reset_to: Vec<Option<std::sync::Arc<Particles>>> = vec![None; self.worlds.len()];
        for change in &since {
            if let Since::Reset(list) = change {
                for &w in list {
                    reset_to[w] = Some(self.worlds[w].kept.clone());
                }
            }
        }
        for (w, world) in self.worlds.iter_mut().enumerate() {
            world.status = statuses[w].clone();
            world.bodies.clone_from(&bodies[w]);
            (world.at, world.origin) = (at[w], origin[w]);
        }
        let frozen = self.rewinds(clock, true, e, steps_of(steps))?;
        self.after_advance(true, &frozen)?;
        self.found.extend(frozen);
        for change in since {
            match change {
                Since::Reset(list) => {
                    let starts = list
                        .into_iter()
                        .filter_map(|w| reset_to[w].clone().map(|p| (w, p)))
                        .collect();
                    self.reset_with(starts, false)?;
                }
                Since::Poses(body, poses) => self.set_body_poses(body, poses)?,
            }
        }
        Ok(true)
    }

    /// Put rigid body `body` of each world listed in `poses` at its pose from the next step on
    /// ([`Worlds::set_body_poses`]), remembered while a check is pending (made again if that
    /// check puts the worlds back).
    pub fn set_body_poses(&mut self, body: usize, poses: Vec<(usize, BodyPose)>) -> Result<()> {
        self.sim
            .backend
            .set_body_poses(body, &poses)
            .with_context(|| format!("posing rigid body {body}"))?;
        if let Some(p) = self.pending.as_mut() {
            p.since.push(Since::Poses(body, poses));
        }
        Ok(())
    }

    /// The worlds `listed` were reset: remembered while a check is pending (made again if that
    /// check puts the worlds back).
    pub(super) fn note_reset(&mut self, listed: Vec<usize>) {
        if let Some(p) = self.pending.as_mut() {
            p.since.push(Since::Reset(listed));
        }
    }
}
