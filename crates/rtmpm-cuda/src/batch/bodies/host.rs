//! The host side of a GPU batch's rigid bodies ([`HostBodies`]): every world's rapier world and,
//! beside them in rows `w * per + b` (body `b` of world `w`), each body's pose as its world holds
//! it and its record for the device table, rewritten whenever a world changes (each step's
//! advance, on every core or, for worlds without a dynamic body, on the calling thread
//! ([`HostBodies::fan`]); a pose given to it).
//!
//! Why the rows: between two calls of a script the step advanced every world on every core, so a
//! script posing a tool in every world from its one thread found each world's rapier bodies in
//! other cores' caches or in memory: reading and setting 256 worlds' tool took 0.15-0.22 ms with
//! the caches flushed between calls, 0.03 ms warm (the `pose_path_timing` test below, on a
//! 2-core machine). Now the pose a script reads is its row (0.01-0.02 ms a call there), and the
//! pose it gives a body is kept, in the order given (`CudaOptions::batch_poses`), until something
//! needs the world's own state: the next step's upload, a read of that body's pose, the worlds'
//! states, a new pose for every body of that world (a reset, a rewind). Then every kept pose is
//! given to its world, on every core from [`PARALLEL_FLUSH`] worlds, with the same setter calls
//! in the same order as when each is given at once (`body_poses=eager`, kept for comparison), so
//! the worlds' state is the same bit for bit. A row of a body with no kept pose is its world's:
//! giving another body of that world its pose puts this one again at the pose it has (rapier's
//! setters change nothing for an unchanged value), which leaves its pose and velocities as they
//! are.

use crate::contract::GpuBody;
use crate::options::BodyPoses;
use rayon::prelude::*;
use rtmpm_rigid::{BodyPose, BodyState, Exchange, RigidWorld};
use rtmpm_sim::SimError;

/// Worlds posed at once from which [`HostBodies::set_body_poses`] poses them on every core when
/// poses are given at once (`body_poses=eager`).
const PARALLEL_POSES: usize = 4096;

/// Worlds with kept poses from which [`HostBodies::flush`] gives them on every core (each world
/// costs about a microsecond when its memory is cold, waking the pool some microseconds).
const PARALLEL_FLUSH: usize = 16;

/// A kept pose: world, body, pose.
type Kept = (usize, usize, BodyPose);

/// `RTMPM_POSE_TIMING=1`: the host's time in the kept poses' putting in ([`HostBodies::flush`])
/// and in the steps' advance of the worlds, printed to stderr every 100 of each (means); off by
/// default (one check of a flag a call).
static PUT_IN: rtmpm_sim::timing::PartTimes<1> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_POSE_TIMING",
    "kept poses put in",
    "worlds",
    ["put in"],
);

/// `RTMPM_POSE_TIMING=1`: the steps' advance of the worlds (see [`PUT_IN`]; its worlds are
/// those stepped, the others at rest).
static ADVANCE: rtmpm_sim::timing::PartTimes<1> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_POSE_TIMING",
    "worlds advanced",
    "worlds",
    ["advance"],
);

/// Every world's rapier world, its bodies' poses and device records in rows, and the poses given
/// but not yet put into the worlds.
pub(crate) struct HostBodies {
    /// One rapier world per world, in order.
    worlds: Vec<RigidWorld>,
    /// Bodies of one world.
    per: usize,
    /// Where each body's distance grid starts in the mesh table.
    mesh_offsets: Vec<u32>,
    /// Each body's pose as its world holds it (row `w * per + b`), for the rows not `pending`.
    poses: Vec<BodyPose>,
    /// Each body's device record of its world's state (row `w * per + b`), once no pose is kept.
    records: Vec<GpuBody>,
    /// Poses given and not yet put into their worlds, in the order given.
    kept: Vec<Kept>,
    /// Rows with a pose in `kept`.
    pending: Vec<bool>,
    /// Poses are kept until needed and then put in on every core, or on one thread, or put in
    /// at once (`CudaOptions::batch_poses`).
    mode: BodyPoses,
    /// Each body's row as its world's last advance left it (row `w * per + b`).
    advanced: Vec<BodyPose>,
    /// Each world's last advance changed none of its rows and left it at rest: no dynamic body,
    /// every velocity zero (see [`HostBodies::advance`]).
    rest: Vec<bool>,
    /// Worlds the last advance stepped (the others were at rest and unchanged since).
    stepped: usize,
    /// Every world was at rest after the last advance (and its rows as it left them).
    all_rest: bool,
    /// No world has a dynamic body: each advances by its own integration, without rapier's
    /// step ([`RigidWorld::kinematic_only`]; see [`HostBodies::fan`]).
    cheap: bool,
    /// A world's rapier world or rows may have changed since the last advance (a pose put in).
    touched: bool,
    /// Bumped whenever a row's record may have changed (a pose put in, a world stepped): the
    /// device's copies of the records hold the rows of the version they were uploaded at
    /// ([`HostBodies::version`]).
    version: u64,
    /// No sums, one per body: what a world advances by without any (no allocation a step).
    none: Vec<Exchange>,
}

/// `RTMPM_BATCH_REST=old`: every world's rapier world is stepped at every step, also a world
/// at rest that a step leaves as it is (as before the skip of [`HostBodies::advance`]); for
/// comparing the two in one binary. Read once.
pub fn old_rest() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_REST").is_ok_and(|v| v.trim() == "old"))
}

/// The rows `a` and `b` hold the same poses bit for bit.
fn same_bits(a: &[BodyPose], b: &[BodyPose]) -> bool {
    let words = |p: &BodyPose| {
        let all = p
            .position
            .to_array()
            .into_iter()
            .chain(p.rotation.to_array());
        let all = all.chain(p.velocity.to_array());
        all.chain(p.angular_velocity.to_array()).map(f32::to_bits)
    };
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| words(p).eq(words(q)))
}

/// Worlds of kinematic and fixed bodies only up to which [`HostBodies::advance`] advances them
/// on the calling thread (`moving_advance_timing`: 256 such worlds 25 us a step on one thread of
/// the 2-core machine, 38-40 us on both cores).
const SERIAL_ADVANCE: usize = 512;

/// Worlds of kinematic and fixed bodies only a task of [`HostBodies::advance`] takes at least
/// on every core (past [`SERIAL_ADVANCE`]): some microseconds of work a task, as a wake-up costs.
const CHEAP_MIN_LEN: usize = 64;

/// `RTMPM_BATCH_FAN`: how [`HostBodies::advance`] spreads the worlds over the cores whatever
/// they hold (for the A/B on a machine of many cores): `serial` on the calling thread, `cores`
/// on every core one or more worlds a task (as before the choice of [`HostBodies::fan`]), a
/// number `n` on every core `n` or more worlds a task; unset or anything else: the choice of
/// [`HostBodies::fan`]. Read once.
fn fan_switch() -> Option<Fan> {
    static FAN: std::sync::OnceLock<Option<Fan>> = std::sync::OnceLock::new();
    *FAN.get_or_init(|| {
        let v = std::env::var("RTMPM_BATCH_FAN").ok()?;
        match v.trim() {
            "serial" => Some(Fan::Serial),
            "cores" => Some(Fan::Cores(1)),
            n => n.parse().ok().filter(|&n| n > 0).map(Fan::Cores),
        }
    })
}

/// One world's rapier world and rows as [`HostBodies::advance`] hands them to a core: the world,
/// its poses, its records, its rows after its last advance, its flag of rest.
type WorldRows<'a> = (
    (
        ((&'a mut RigidWorld, &'a mut [BodyPose]), &'a mut [GpuBody]),
        &'a mut [BodyPose],
    ),
    &'a mut bool,
);

/// How [`HostBodies::advance`] spreads the worlds over the cores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fan {
    /// Every world on the calling thread (no worker woken).
    Serial,
    /// On every core, at least this many worlds a task.
    Cores(usize),
}

/// `world`, whose rows are `poses`, is at rest: no dynamic body (gravity and the material move
/// those), every body's velocity and angular velocity zero (a kinematic body moves by them).
fn at_rest(world: &RigidWorld, poses: &[BodyPose]) -> bool {
    world.states().iter().all(|s| !s.dynamic)
        && poses
            .iter()
            .all(|p| p.velocity == glam::Vec3::ZERO && p.angular_velocity == glam::Vec3::ZERO)
}

/// A step of `world` (rows `poses`, `records`; `advanced`: its rows after its last advance;
/// `rest`: that advance left it at rest, unchanged) by `dt` with the sums `ex`; `false`: skipped,
/// the world at rest and its rows as that advance left them (`skip`), where the step would
/// change nothing (below).
fn advance_world(
    (world, poses, records): (&mut RigidWorld, &mut [BodyPose], &mut [GpuBody]),
    (advanced, rest): (&mut [BodyPose], &mut bool),
    (ex, dt, skip): (&[Exchange], f32, bool),
) -> bool {
    if skip && *rest && same_bits(poses, advanced) {
        return false;
    }
    advanced.copy_from_slice(poses);
    world.advance(ex, dt);
    write_motion(world, poses, records);
    *rest = at_rest(world, poses) && same_bits(poses, advanced);
    advanced.copy_from_slice(poses);
    true
}

/// World `world`'s rows from its state now: `poses` and `records` are its bodies'.
fn write_rows(world: &RigidWorld, mesh: &[u32], poses: &mut [BodyPose], records: &mut [GpuBody]) {
    let rows = poses.iter_mut().zip(records.iter_mut());
    for (i, ((p, r), s)) in rows.zip(world.states()).enumerate() {
        if let Some(pose) = world.pose(i) {
            *p = pose;
        }
        *r = crate::step::rigid::encode(s, mesh.get(i).copied().unwrap_or(0));
    }
}

/// [`write_rows`] of a world whose records [`write_rows`] wrote before: only the fields that move
/// (`step::rigid::encode_motion`; a body's shape, rule and kind never change), the same records
/// bit for bit with less work at every step's advance and put-in of a pose.
fn write_motion(world: &RigidWorld, poses: &mut [BodyPose], records: &mut [GpuBody]) {
    let rows = poses.iter_mut().zip(records.iter_mut());
    for (i, ((p, r), s)) in rows.zip(world.states()).enumerate() {
        if let Some(pose) = world.pose(i) {
            *p = pose;
        }
        crate::step::rigid::encode_motion(s, r);
    }
}

/// Put the kept poses `run` (one world's, in the order given) into `world`, then its rows.
fn put_kept(world: &mut RigidWorld, run: &[Kept], poses: &mut [BodyPose], records: &mut [GpuBody]) {
    for (_, body, pose) in run {
        // `set_body_poses` checked the body: `set_pose` refuses only a body past the last.
        let _ = world.set_pose(*body, pose);
    }
    write_motion(world, poses, records);
}

impl HostBodies {
    /// The bodies of `worlds` (every world has as many), `mesh_offsets` where each body's distance
    /// grid starts in the mesh table; `mode`: `CudaOptions::batch_poses`.
    pub fn new(worlds: Vec<RigidWorld>, mesh_offsets: Vec<u32>, mode: BodyPoses) -> HostBodies {
        let per = worlds.first().map_or(0, |w| w.states().len());
        let cheap = worlds.iter().all(RigidWorld::kinematic_only);
        let (rows, worlds_count) = (worlds.len() * per, worlds.len());
        let poses: Vec<BodyPose> = worlds.iter().flat_map(|w| w.poses()).collect();
        let records = vec![GpuBody::default(); rows];
        let mut h = HostBodies {
            worlds,
            per,
            mesh_offsets,
            poses,
            records,
            kept: Vec::new(),
            pending: vec![false; rows],
            mode,
            advanced: Vec::new(),
            rest: vec![false; worlds_count],
            stepped: 0,
            all_rest: false,
            cheap,
            touched: true,
            version: 0,
            none: vec![Exchange::default(); per],
        };
        for w in 0..h.worlds.len() {
            h.rewrite(w);
        }
        h.advanced = h.poses.clone();
        h
    }

    /// World `w`'s rows rewritten from its state.
    fn rewrite(&mut self, w: usize) {
        let rows = w * self.per..(w + 1) * self.per;
        write_rows(
            &self.worlds[w],
            &self.mesh_offsets,
            &mut self.poses[rows.clone()],
            &mut self.records[rows],
        );
    }

    /// Every kept pose put into its world (each world's in the order given; on every core from
    /// [`PARALLEL_FLUSH`] worlds, unless the advance runs on the calling thread,
    /// [`HostBodies::fan`]), and the posed worlds' rows rewritten.
    pub fn flush(&mut self) {
        if self.kept.is_empty() {
            return;
        }
        self.touched = true;
        self.version += 1;
        let t0 = std::time::Instant::now();
        let mut kept = std::mem::take(&mut self.kept);
        kept.sort_by_key(|k| k.0); // stable: each world's in the order given
        let per = self.per.max(1);
        for &(w, b, _) in &kept {
            self.pending[w * per + b] = false;
        }
        let runs = kept.chunk_by(|a, b| a.0 == b.0);
        // On the calling thread where the advance of these worlds is (`HostBodies::fan`): on the
        // 32-core host every core's putting in of 256 kinematic tools took 154-167 us a call
        // (session 15 call 3, RTMPM_POSE_TIMING), the rayon fan-out costing more than the work.
        let serial = self.mode == BodyPoses::DeferredSerial || self.fan() == Fan::Serial;
        if serial || runs.clone().count() < PARALLEL_FLUSH {
            for run in runs {
                let w = run[0].0;
                let rows = w * per..(w + 1) * per;
                put_kept(
                    &mut self.worlds[w],
                    run,
                    &mut self.poses[rows.clone()],
                    &mut self.records[rows],
                );
            }
        } else {
            // Each world's run of kept poses by its index (`usize::MAX`: none).
            let mut first = vec![usize::MAX; self.worlds.len()];
            for (j, k) in kept.iter().enumerate().rev() {
                first[k.0] = j;
            }
            let kept = &kept;
            self.worlds
                .par_iter_mut()
                .zip(self.poses.par_chunks_mut(per))
                .zip(self.records.par_chunks_mut(per))
                .zip(first.par_iter())
                .filter(|(_, f)| **f != usize::MAX)
                .for_each(|(((world, poses), records), &f)| {
                    let w = kept[f].0;
                    let n = kept[f..].iter().take_while(|k| k.0 == w).count();
                    put_kept(world, &kept[f..f + n], poses, records);
                });
        }
        if PUT_IN.on() {
            let worlds = kept.chunk_by(|a, b| a.0 == b.0).count();
            PUT_IN.record(worlds, [t0], std::time::Instant::now());
        }
        kept.clear();
        self.kept = kept; // its memory kept for the next poses
    }

    /// World `w`'s kept poses put into it (the others kept), and its rows rewritten.
    fn flush_world(&mut self, w: usize) {
        if !self.kept.iter().any(|k| k.0 == w) {
            return;
        }
        self.touched = true;
        self.version += 1;
        let run: Vec<Kept> = self.kept.iter().filter(|k| k.0 == w).copied().collect();
        self.kept.retain(|k| k.0 != w);
        let per = self.per;
        for &(_, b, _) in &run {
            self.pending[w * per + b] = false;
        }
        let rows = w * per..(w + 1) * per;
        put_kept(
            &mut self.worlds[w],
            &run,
            &mut self.poses[rows.clone()],
            &mut self.records[rows],
        );
    }

    /// Every body's record for the device table (the kept poses put into their worlds first).
    pub fn records(&mut self) -> &[GpuBody] {
        self.flush();
        &self.records
    }

    /// The version of the records (the kept poses put into their worlds first): the same number
    /// means the same records, bit for bit (a new one may hold the same records: a world stepped
    /// or posed to where it was).
    pub fn version(&mut self) -> u64 {
        self.flush();
        self.version
    }

    /// Advance every world by `dt` (each by its bodies' sums `each[w]`, or none), on every core
    /// or on the calling thread ([`HostBodies::fan`]), and rewrite its rows; a world at rest is
    /// not stepped. At rest: its last advance left its rows (poses and velocities) as they were,
    /// bit for bit, with no dynamic body and every velocity zero, and its rows are still those
    /// (no pose given since, or the same): a step of it is then a function of those rows alone
    /// (a kinematic body moves by its velocities times dt, zero for any dt; a fixed body does
    /// not move; no dynamic body for gravity or the material to move), so it would leave them as
    /// they are again, and the rapier world is not stepped (a kinematic tool standing still in
    /// 256 worlds: no step of any of them; a world whose rotation a step renormalises, under
    /// `RTMPM_KINEMATIC=rapier`, is stepped until it stops changing; the worlds' own integration
    /// leaves a body without velocities as it is). Tested bit for bit against stepping every
    /// world (`worlds_at_rest_are_skipped_and_step_on_as_before`). `RTMPM_BATCH_REST=old`: every
    /// world stepped, as before.
    pub fn advance(&mut self, each: Option<&[Vec<Exchange>]>, dt: f32) {
        self.advance_skipping(each, dt, !old_rest());
    }

    /// [`HostBodies::advance`], the worlds at rest skipped when `skip`.
    fn advance_skipping(&mut self, each: Option<&[Vec<Exchange>]>, dt: f32, skip: bool) {
        let fan = self.fan();
        self.advance_fanned(each, dt, skip, fan);
    }

    /// How [`HostBodies::advance`] spreads the worlds over the cores: `RTMPM_BATCH_FAN` where
    /// set ([`fan_switch`]); otherwise worlds that rapier steps (a dynamic body: 1-3 us a world)
    /// one or more a task on every core, as before; worlds of kinematic and fixed bodies only
    /// (their own integration, [`RigidWorld::advance`]: about 0.1 us a world with its rows) on
    /// the calling thread up to [`SERIAL_ADVANCE`] worlds (waking the pool costs more than
    /// they do), [`CHEAP_MIN_LEN`] or more a task past that.
    fn fan(&self) -> Fan {
        match fan_switch() {
            Some(fan) => fan,
            None if !self.cheap => Fan::Cores(1),
            None if self.worlds.len() <= SERIAL_ADVANCE => Fan::Serial,
            None => Fan::Cores(CHEAP_MIN_LEN),
        }
    }

    /// [`HostBodies::advance_skipping`], the worlds spread over the cores as `fan` says.
    fn advance_fanned(&mut self, each: Option<&[Vec<Exchange>]>, dt: f32, skip: bool, fan: Fan) {
        self.flush();
        let t0 = std::time::Instant::now();
        let none = &self.none[..];
        let per = self.per.max(1);
        // Every world at rest and unchanged: nothing to step, no worker woken (nothing put in
        // since the last advance left every world at rest: not even a look at the rows).
        let resting = |w: usize| {
            let rows = w * per..(w + 1) * per;
            self.rest[w] && same_bits(&self.poses[rows.clone()], &self.advanced[rows])
        };
        if skip && ((self.all_rest && !self.touched) || (0..self.worlds.len()).all(resting)) {
            (self.stepped, self.all_rest, self.touched) = (0, true, false);
            if ADVANCE.on() {
                ADVANCE.record(0, [t0], std::time::Instant::now());
            }
            return;
        }
        // Each world is independent: the same results in any order.
        let step = |(w, ((((world, poses), records), advanced), rest)): (usize, WorldRows)| {
            let ex = each.and_then(|e| e.get(w)).map_or(none, |e| &e[..]);
            advance_world((world, poses, records), (advanced, rest), (ex, dt, skip))
        };
        self.stepped = match fan {
            Fan::Serial => self
                .worlds
                .iter_mut()
                .zip(self.poses.chunks_mut(per))
                .zip(self.records.chunks_mut(per))
                .zip(self.advanced.chunks_mut(per))
                .zip(self.rest.iter_mut())
                .enumerate()
                .map(step)
                .filter(|&stepped| stepped)
                .count(),
            Fan::Cores(min_len) => self
                .worlds
                .par_iter_mut()
                .zip(self.poses.par_chunks_mut(per))
                .zip(self.records.par_chunks_mut(per))
                .zip(self.advanced.par_chunks_mut(per))
                .zip(self.rest.par_iter_mut())
                .enumerate()
                .with_min_len(min_len)
                .map(step)
                .filter(|&stepped| stepped)
                .count(),
        };
        // Every world's rows are now as this advance left them.
        (self.all_rest, self.touched) = (self.rest.iter().all(|&r| r), false);
        if self.stepped > 0 {
            self.version += 1;
        }
        if ADVANCE.on() {
            ADVANCE.record(self.stepped, [t0], std::time::Instant::now());
        }
    }

    /// Worlds the last [`HostBodies::advance`] stepped (the others at rest).
    #[cfg(all(test, feature = "rigid"))]
    pub fn stepped(&self) -> usize {
        self.stepped
    }

    /// Every world's body states, world by world (the kept poses put into their worlds first).
    pub fn states(&mut self) -> Vec<BodyState> {
        self.flush();
        self.worlds
            .iter()
            .flat_map(|w| w.states().iter().cloned())
            .collect()
    }

    /// Body `body` of world `w` as its world holds it (its kept pose put in first, with every
    /// other: a pose read is its world's); `None`: no such world or body.
    pub fn pose(&mut self, w: usize, body: usize) -> Option<BodyPose> {
        if w >= self.worlds.len() || body >= self.per {
            return None;
        }
        let row = w * self.per + body;
        if self.pending[row] {
            self.flush();
        }
        Some(self.poses[row])
    }

    /// World `w`'s bodies' poses into `out` (emptied first; empty for no such world).
    pub fn poses_into(&mut self, w: usize, out: &mut Vec<BodyPose>) {
        out.clear();
        if w >= self.worlds.len() {
            return;
        }
        let rows = w * self.per..(w + 1) * self.per;
        if self.pending[rows.clone()].contains(&true) {
            self.flush();
        }
        out.extend_from_slice(&self.poses[rows]);
    }

    /// Body `body` of each world of `worlds` into `out` (emptied first; `None` for no such world
    /// or body): [`HostBodies::pose`] of each, from the rows (the kept poses put into their
    /// worlds first where one of these rows has one, as a read of it does).
    pub fn body_poses(&mut self, body: usize, worlds: &[usize], out: &mut Vec<Option<BodyPose>>) {
        out.clear();
        let (count, per) = (self.worlds.len(), self.per);
        let row = |w: usize| (w < count && body < per).then(|| w * per + body);
        if worlds
            .iter()
            .any(|&w| row(w).is_some_and(|r| self.pending[r]))
        {
            self.flush();
        }
        out.extend(worlds.iter().map(|&w| row(w).map(|r| self.poses[r])));
    }

    /// Every world's bodies' poses handed to `each(w, poses)`, world after world, from the rows
    /// (the kept poses put into their worlds first, as a read of one world's does).
    pub fn each_poses(&mut self, each: &mut dyn FnMut(usize, &[BodyPose])) {
        if self.pending.contains(&true) {
            self.flush();
        }
        for (w, rows) in self.poses.chunks(self.per.max(1)).enumerate() {
            each(w, rows);
        }
    }

    /// Put world `w`'s bodies at `poses` (one per body), after the poses kept for it.
    pub fn set_poses(&mut self, w: usize, poses: &[BodyPose]) -> Result<(), SimError> {
        let count = self.worlds.len();
        if w >= count {
            return Err(SimError::Backend(format!(
                "CUDA batch: no world {w} (the batch has {count})"
            )));
        }
        self.flush_world(w);
        self.touched = true;
        self.version += 1;
        let r = self.worlds[w]
            .set_poses(poses)
            .map_err(|e| SimError::Backend(format!("CUDA batch: world {w}: {e}")));
        self.rewrite(w);
        r
    }

    /// Put body `body` of each world `w` of `poses` at its pose, the worlds' other bodies where
    /// they are: the worlds and the body checked first (nothing changes on an error), then each
    /// world's last pose of the list kept (or, `body_poses=eager`, put into the world at once: on
    /// every core from [`PARALLEL_POSES`] worlds).
    pub fn set_body_poses(
        &mut self,
        body: usize,
        poses: &[(usize, BodyPose)],
    ) -> Result<(), SimError> {
        let count = self.worlds.len();
        if body >= self.per && !poses.is_empty() {
            return Err(SimError::Backend(format!(
                "CUDA batch: rigid body {body}: a world has {}",
                self.per
            )));
        }
        let mut last = vec![None; count];
        for (j, (w, _)) in poses.iter().enumerate() {
            let slot = last.get_mut(*w).ok_or_else(|| {
                SimError::Backend(format!("CUDA batch: no world {w} (the batch has {count})"))
            })?;
            *slot = Some(j);
        }
        if self.mode != BodyPoses::Eager {
            for (w, at) in last.iter().enumerate() {
                if let Some(j) = at {
                    self.kept.push((w, body, poses[*j].1));
                    self.pending[w * self.per + body] = true;
                }
            }
            return Ok(());
        }
        self.touched = true;
        self.version += 1;
        let per = self.per;
        if poses.len() < PARALLEL_POSES {
            let rows = self.poses.chunks_mut(per).zip(self.records.chunks_mut(per));
            for ((world, (p, r)), at) in self.worlds.iter_mut().zip(rows).zip(&last) {
                if let Some(j) = at {
                    put_kept(world, &[(0, body, poses[*j].1)], p, r);
                }
            }
        } else {
            self.worlds
                .par_iter_mut()
                .zip(self.poses.par_chunks_mut(per))
                .zip(self.records.par_chunks_mut(per))
                .zip(last.par_iter())
                .with_min_len(256)
                .for_each(|(((world, p), r), at)| {
                    if let Some(j) = at {
                        put_kept(world, &[(0, body, poses[*j].1)], p, r);
                    }
                });
        }
        Ok(())
    }
}

#[cfg(all(test, feature = "rigid"))]
mod tests;
