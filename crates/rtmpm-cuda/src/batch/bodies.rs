//! Rigid bodies in a GPU batch ([`super::CudaBatch`]): one rapier world per world on the host
//! ([`RigidWorld`], as each world of a CPU batch has its own), every world's bodies in one table
//! on the device (row `w * per + b`: body `b` of world `w`), which the grid update couples to
//! that world's nodes only (`kernels/grid_update.cu`: `couple_world_bodies`), and the reaction of
//! every body of every world summed per row, read back as below.
//!
//! Per step: every world's body states go to the table (one copy of the host's rows, none when the
//! table holds them already: bodies at rest), the step runs, and the bodies advance. With a
//! dynamic body in any world the step's sums are copied to page-locked memory and cleared, and
//! the host waits for them and advances each world's rapier world by its own (the order of
//! `rigid_overlap=off` in a single run: the CPU backend's). With kinematic and
//! fixed bodies only, which no sum moves, the worlds advance at once and the sums are needed only
//! for the loads: they stay on the device until a load is read ([`WorldBodies::loads`]: one copy
//! of the last step's, then kept for the other worlds' reads) and are cleared as the next step
//! begins (`CudaOptions::batch_sums_at_read`; `body_sums=step` copies them after every step, as
//! before, for comparison: 393 KB a step for 256 worlds of one body, 32 copies of 6 sums a row).

use crate::contract::{BODY_EXCHANGE_SLOTS, GpuBody};
use crate::error::err;
use crate::options::BodyPoses;
use crate::waits::{HostWaits, WaitReason};
use cudarc::driver::{CudaEvent, CudaSlice, CudaStream, DevicePtr, PinnedHostSlice};
use rtmpm_rigid::{BodyLoad, BodyPose, BodyState, Exchange, RigidKind};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::sync::{Arc, Mutex, MutexGuard};

mod host;

use host::HostBodies;

/// Page-locked buffers the body table's uploads go through at most ([`WorldBodies`]`::staging`):
/// the host may be that many changed uploads (steps of a moving tool) ahead of the device before
/// it waits; 4, used in turn, with `RTMPM_BATCH_WAITS=old`.
const UPLOAD_BUFFERS: usize = 64;
const OLD_UPLOAD_BUFFERS: usize = 4;

/// Every world's rigid bodies: their rapier worlds and the device side of their coupling.
pub(crate) struct WorldBodies {
    /// The host side: every world's rapier world, its bodies' poses and device records, the
    /// poses given and not yet put into the worlds (behind a lock: a read through `&self` may
    /// put them in first).
    rigid: Mutex<HostBodies>,
    /// Worlds.
    count: usize,
    /// Bodies of one world.
    per: usize,
    /// `worlds x per` [`GpuBody`] records (`Ctx::bodies` in a batch).
    table: CudaSlice<u8>,
    /// The bytes `table` holds (the last upload's; empty before the first): an upload of the
    /// same bytes is skipped (bodies at rest, tools standing still).
    uploaded: Vec<u8>,
    /// The page-locked memory the uploads of `table` go through (a copy from pageable memory
    /// may wait for the steps queued ahead of it; with several buffers the host may be that
    /// many changed uploads ahead of the device).
    staging: crate::staging::StagingRing,
    /// The host's waits, counted ([`crate::waits`]; the backend's).
    waits: Arc<HostWaits>,
    /// `BODY_EXCHANGE_SLOTS` x `worlds x per` rows x 6 f64 sums (`Ctx::body_exchange`).
    exchange: CudaSlice<f64>,
    /// The host's copy of the sums (filled when a load is read, with `at_read`).
    host: Mutex<HostSums>,
    /// The sums stay on the device until a load is read (no dynamic body, and
    /// `CudaOptions::batch_sums_at_read`).
    at_read: bool,
    /// `exchange` holds the last step's sums, to be cleared before the next step (`at_read`).
    held: bool,
    /// The batch's stream (the copies of the sums when read).
    stream: Arc<CudaStream>,
    /// Some world has a dynamic body (the host waits for every step's sums).
    dynamic: bool,
    /// The dt of the last step (whose sums are the loads); `None` before the first step.
    last_dt: Option<f32>,
}

/// The page-locked copy of the last step's sums, the event after its copy, and whether it is
/// of the last step (a copy is queued for it).
struct HostSums {
    sums: PinnedHostSlice<f64>,
    done: CudaEvent,
    copied: bool,
}

impl WorldBodies {
    /// The bodies of the worlds `worlds` (`None` when they have none; every world has as many,
    /// `super::unsupported`), their buffers allocated on `stream`; `mesh_offsets`: where each
    /// body's distance grid starts in the mesh table (`encode::Tables::body_mesh`);
    /// `sums_at_read`: `CudaOptions::batch_sums_at_read`; `poses`: `CudaOptions::batch_poses`;
    /// `waits`: the backend's count of the host's waits.
    pub fn new(
        worlds: &[Scene],
        stream: &Arc<CudaStream>,
        mesh_offsets: Vec<u32>,
        (sums_at_read, poses): (bool, BodyPoses),
        waits: Arc<HostWaits>,
    ) -> Result<Option<WorldBodies>, SimError> {
        let per = worlds.first().map_or(0, |s| s.rigid_bodies.len());
        if per == 0 {
            return Ok(None);
        }
        let mut rapier = Vec::with_capacity(worlds.len());
        for (w, s) in worlds.iter().enumerate() {
            let world = crate::step::rigid::world(s)
                .map_err(|e| SimError::Backend(format!("CUDA batch: world {w}: {e}")))?
                .ok_or_else(|| {
                    SimError::Backend(format!("CUDA batch: world {w} has no rigid bodies"))
                })?;
            rapier.push(world);
        }
        let rows = worlds.len() * per;
        let table = stream
            .alloc_zeros::<u8>(rows * std::mem::size_of::<GpuBody>())
            .map_err(err("alloc the worlds' rigid bodies"))?;
        let len = BODY_EXCHANGE_SLOTS * rows * 6;
        let exchange = stream
            .alloc_zeros::<f64>(len)
            .map_err(err("alloc the worlds' rigid-body impulses"))?;
        // SAFETY: the copy is written by a device copy before the host reads it (after `done`).
        let host = unsafe { stream.context().alloc_pinned_with_flags::<f64>(len, 0) }
            .map_err(err("allocate page-locked memory"))?;
        let done = stream.record_event(None).map_err(err("record an event"))?;
        let dynamic = worlds
            .iter()
            .flat_map(|s| &s.rigid_bodies)
            .any(|b| b.kind == RigidKind::Dynamic);
        Ok(Some(WorldBodies {
            count: rapier.len(),
            rigid: Mutex::new(HostBodies::new(rapier, mesh_offsets, poses)),
            per,
            table,
            uploaded: Vec::new(),
            staging: crate::staging::StagingRing::new(UPLOAD_BUFFERS, OLD_UPLOAD_BUFFERS),
            waits,
            exchange,
            host: Mutex::new(HostSums {
                sums: host,
                done,
                copied: true,
            }),
            at_read: sums_at_read && !dynamic,
            held: false,
            stream: stream.clone(),
            dynamic,
            last_dt: None,
        }))
    }

    /// Device addresses for [`crate::contract::Ctx`]: (the table, the sums, bodies of a world).
    pub fn ctx_fields(&self, stream: &Arc<CudaStream>) -> (u64, u64, u32) {
        let (a, _) = self.table.device_ptr(stream);
        let (b, _) = self.exchange.device_ptr(stream);
        (a, b, self.per as u32)
    }

    /// Before a step: every world's body states to the table (unless it holds them already),
    /// and the last step's sums cleared where they were kept on the device.
    pub fn upload(&mut self, stream: &Arc<CudaStream>) -> Result<(), SimError> {
        if self.held {
            stream
                .memset_zeros(&mut self.exchange)
                .map_err(err("clear the worlds' rigid-body impulses"))?;
            self.held = false;
        }
        let rigid = self.rigid.get_mut().unwrap_or_else(|p| p.into_inner());
        let bytes: &[u8] = bytemuck::cast_slice::<GpuBody, u8>(rigid.records());
        if bytes == self.uploaded.as_slice() {
            return Ok(());
        }
        if super::staging::pageable_puts() {
            self.waits.wait(WaitReason::Pageable, || ());
            stream
                .memcpy_htod(bytes, &mut self.table.slice_mut(..bytes.len()))
                .map_err(err("upload the worlds' rigid bodies"))?;
        } else {
            self.staging
                .copy_to_device(stream, bytes, &mut self.table, &self.waits)?;
        }
        self.uploaded.clear();
        self.uploaded.extend_from_slice(bytes);
        Ok(())
    }

    /// After a step of `dt` was queued: its sums are copied to the host and cleared (kept on the
    /// device until read or the next step, with `at_read`), and every world's bodies advance by
    /// `dt` (with a dynamic body, by their world's sums, waited for).
    pub fn after_step(&mut self, stream: &Arc<CudaStream>, dt: f32) -> Result<(), SimError> {
        self.last_dt = Some(dt);
        if self.at_read {
            self.held = true;
            lock(&self.host).copied = false;
        } else {
            let host = self.host.get_mut().unwrap_or_else(|p| p.into_inner());
            stream
                .memcpy_dtoh(&self.exchange, &mut host.sums)
                .map_err(err("read the worlds' rigid-body impulses"))?;
            host.done = stream.record_event(None).map_err(err("record an event"))?;
            stream
                .memset_zeros(&mut self.exchange)
                .map_err(err("clear the worlds' rigid-body impulses"))?;
        }
        // The worlds advance (on every core, or on this thread: `HostBodies::fan`) while the
        // device runs the step just queued.
        if !self.dynamic {
            self.host_mut().advance(None, dt);
            return Ok(());
        }
        let (count, per) = (self.count, self.per);
        let rows = count * per;
        let each: Vec<Vec<Exchange>> = self.with_sums(|sums| {
            (0..count)
                .map(|w| row_sums(sums, rows, w * per, per))
                .collect()
        })?;
        self.host_mut().advance(Some(&each), dt);
        Ok(())
    }

    /// `read` of the last step's sums on the host: copied from the device first where they were
    /// kept there (`at_read`, once a step), waited for.
    fn with_sums<T>(&self, read: impl FnOnce(&[f64]) -> T) -> Result<T, SimError> {
        let mut host = lock(&self.host);
        if !host.copied {
            let h = &mut *host;
            self.stream
                .memcpy_dtoh(&self.exchange, &mut h.sums)
                .map_err(err("read the worlds' rigid-body impulses"))?;
            h.done = self
                .stream
                .record_event(None)
                .map_err(err("record an event"))?;
            h.copied = true;
        }
        self.waits
            .wait(WaitReason::Sums, || host.done.synchronize())
            .map_err(err("wait for the worlds' rigid-body impulses"))?;
        Ok(read(
            host.sums.as_slice().map_err(err("page-locked memory"))?,
        ))
    }

    /// The load the material put on each of world `w`'s bodies over the last step (zeros
    /// before the first): its sums over that step's dt, as the CPU backend's
    /// `Backend::rigid_loads`.
    pub fn loads(&self, w: usize) -> Result<Vec<BodyLoad>, SimError> {
        let Some(dt) = self.last_dt else {
            return Ok(vec![BodyLoad::default(); self.per]);
        };
        let rows = self.count * self.per;
        let sums = self.with_sums(|s| row_sums(s, rows, w * self.per, self.per))?;
        Ok(sums.iter().map(|e| e.load(dt as f64)).collect())
    }

    /// The host side, also after a panic while it was held.
    fn host(&self) -> MutexGuard<'_, HostBodies> {
        self.rigid.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The host side through `&mut self` (no lock taken).
    fn host_mut(&mut self) -> &mut HostBodies {
        self.rigid.get_mut().unwrap_or_else(|p| p.into_inner())
    }

    /// Every world's body states, world by world (what bounds the shared time step).
    pub fn states(&self) -> Vec<BodyState> {
        self.host().states()
    }

    /// World `w`'s bodies' poses and velocities.
    pub fn poses(&self, w: usize) -> Vec<BodyPose> {
        let mut out = Vec::with_capacity(self.per);
        self.poses_into(w, &mut out);
        out
    }

    /// World `w`'s bodies' poses and velocities into `out` (emptied first; empty for no such
    /// world).
    pub fn poses_into(&self, w: usize, out: &mut Vec<BodyPose>) {
        self.host().poses_into(w, out)
    }

    /// Body `body` of each world of `worlds` into `out` (`None`: no such world or body), under
    /// one lock.
    pub fn body_poses(&self, body: usize, worlds: &[usize], out: &mut Vec<Option<BodyPose>>) {
        self.host().body_poses(body, worlds, out)
    }

    /// Every world's bodies' poses handed to `each(w, poses)`, world after world, under one lock.
    pub fn each_poses(&self, each: &mut dyn FnMut(usize, &[BodyPose])) {
        self.host().each_poses(each)
    }

    /// Body `body` of world `w` (`None`: no such world or body).
    pub fn pose(&self, w: usize, body: usize) -> Option<BodyPose> {
        self.host().pose(w, body)
    }

    /// Put body `body` of each world `w` of `poses` at its pose from the next step on, the
    /// worlds' other bodies where they are: the worlds and the body checked first (nothing
    /// changes on an error; a world listed twice ends with its last pose, as one after the other
    /// would), then the poses kept until the next step puts them into the worlds on every core
    /// ([`HostBodies::set_body_poses`]).
    pub fn set_body_poses(
        &mut self,
        body: usize,
        poses: &[(usize, BodyPose)],
    ) -> Result<(), SimError> {
        self.host_mut().set_body_poses(body, poses)
    }

    /// The kept poses put into their worlds now ([`HostBodies::flush`]: what the next upload
    /// or read would do first; the same state).
    pub fn flush_kept(&mut self) {
        self.host_mut().flush();
    }

    /// Put world `w`'s bodies at `poses` (one per body).
    pub fn set_poses(&mut self, w: usize, poses: &[BodyPose]) -> Result<(), SimError> {
        self.host_mut().set_poses(w, poses)
    }

    /// Bodies of one world.
    pub fn per_world(&self) -> usize {
        self.per
    }
}

/// The host's sums, also after a panic while they were held (they are plain numbers).
fn lock(host: &Mutex<HostSums>) -> MutexGuard<'_, HostSums> {
    host.lock().unwrap_or_else(|p| p.into_inner())
}

/// The sums of rows `first .. first + count` of `rows` per copy, over the
/// `BODY_EXCHANGE_SLOTS` copies (slot-major: slot, row, 6 values), added in slot order.
pub fn row_sums(sums: &[f64], rows: usize, first: usize, count: usize) -> Vec<Exchange> {
    let mut out = vec![Exchange::default(); count];
    for slot in 0..BODY_EXCHANGE_SLOTS {
        for (b, e) in out.iter_mut().enumerate() {
            let at = 6 * (slot * rows + first + b);
            let Some(v) = sums.get(at..at + 6) else {
                continue;
            };
            for a in 0..3 {
                e.impulse[a] += v[a];
                e.torque[a] += v[3 + a];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CudaOptions;

    /// A jelly block and `extra` (rigid bodies, emitters, a solver table).
    fn scene(extra: &str) -> Scene {
        let text = format!(
            "[domain]\nmin = [0,0,0]\nmax = [0.4,0.4,0.4]\ndx = 0.02\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"j\"\ntype = \"fixed_corotated\"\ndensity = 1000.0\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.3\n[[body]]\nmaterial = \"j\"\n\
             shape = \"box\"\nmin = [0.1, 0.06, 0.1]\nmax = [0.3, 0.18, 0.3]\n{extra}"
        );
        Scene::from_toml(&text, "test").unwrap_or_else(|e| panic!("{e}"))
    }

    fn tool(y: f32, kind: &str) -> String {
        format!(
            "[[rigid_body]]\nshape = \"box\"\nmin = [0.17, {y}, 0.17]\nmax = [0.23, {}, 0.23]\n\
             density = 1000.0\ntype = \"{kind}\"\n",
            y + 0.06
        )
    }

    /// Worlds with rigid bodies run on the GPU batch (with the rigid-body engine) when each
    /// has as many, whatever their kind and pose; refused, with the reason, when the counts
    /// differ, with emitters, and with MUSL steps.
    #[test]
    fn worlds_with_as_many_rigid_bodies_run_and_the_rest_is_refused_with_the_reason() {
        let o = CudaOptions::default();
        let worlds = [
            scene(&tool(0.2, "kinematic")),
            scene(&tool(0.25, "dynamic")),
            scene(&tool(0.24, "fixed")),
        ];
        let verdict = crate::batch::unsupported(&worlds, &o);
        if cfg!(feature = "rigid") {
            assert_eq!(verdict, None);
        } else {
            let why = verdict.expect("refused without the engine");
            assert!(why.contains("cargo feature `rigid`"), "{why}");
        }
        let uneven = [
            scene(&tool(0.2, "kinematic")),
            scene(&format!(
                "{}{}",
                tool(0.2, "kinematic"),
                tool(0.27, "dynamic")
            )),
        ];
        let why = crate::batch::unsupported(&uneven, &o).expect("refused");
        assert!(
            why.contains("world 1 has 2 rigid bodies and world 0 has 1"),
            "{why}"
        );
        let emitter = "[[emitter]]\nmaterial = \"j\"\nshape = \"box\"\n\
                       min = [0.2, 0.3, 0.2]\nmax = [0.22, 0.32, 0.22]\n\
                       velocity = [0.0, -1.0, 0.0]\nvolume_rate = 1e-5\n";
        let why = crate::batch::unsupported(&[scene(""), scene(emitter)], &o).expect("refused");
        assert!(why.contains("world 1 has emitters"), "{why}");
        if cfg!(feature = "rigid") {
            // The scene file refuses MUSL with rigid bodies; the batch refuses it all the same.
            let mut musl = scene(&tool(0.2, "kinematic"));
            musl.solver.update = rtmpm_physics::transfer::Update::Musl;
            let why = crate::batch::unsupported(&[musl.clone(), musl], &o).expect("refused");
            assert!(why.contains("USL steps"), "{why}");
        }
    }

    /// Rows of one world are summed over the copies, the other worlds' rows left out: world 1
    /// of 3 with 2 bodies each is rows 2 and 3 of 6; the single run's sums
    /// (`step::rigid::exchange_sums`) are the case of one world.
    #[test]
    fn a_worlds_rows_are_summed_over_the_copies_and_no_other_rows() {
        let rows = 6;
        let mut sums = vec![0.0; BODY_EXCHANGE_SLOTS * rows * 6];
        let put = |s: &mut Vec<f64>, slot: usize, row: usize, k: usize, v: f64| {
            s[6 * (slot * rows + row) + k] = v;
        };
        put(&mut sums, 0, 2, 1, 1.5); // world 1 body 0, impulse y
        put(&mut sums, 31, 2, 1, 2.0);
        put(&mut sums, 7, 3, 5, -3.0); // world 1 body 1, torque z
        put(&mut sums, 3, 1, 0, 100.0); // world 0 body 1: not world 1's
        put(&mut sums, 3, 4, 0, 100.0); // world 2 body 0: not world 1's
        let e = row_sums(&sums, rows, 2, 2);
        assert_eq!(e[0].impulse, [0.0, 3.5, 0.0]);
        assert_eq!(e[0].torque, [0.0; 3]);
        assert_eq!(e[1].torque, [0.0, 0.0, -3.0]);
        assert_eq!(e[1].impulse, [0.0; 3]);
        let w0 = row_sums(&sums, rows, 0, 2);
        assert_eq!(w0[1].impulse, [100.0, 0.0, 0.0]);
        // One world: the single run's sums.
        let one = row_sums(&sums[..BODY_EXCHANGE_SLOTS * 6 * 6], 6, 0, 6);
        let single = crate::step::rigid::exchange_sums(&sums, 6);
        assert_eq!(one, single);
    }
}
