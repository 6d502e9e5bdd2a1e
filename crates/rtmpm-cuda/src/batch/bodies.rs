//! Rigid bodies in a GPU batch ([`super::CudaBatch`]): one rapier world per world on the host
//! ([`RigidWorld`], as each world of a CPU batch has its own), every world's bodies in one table
//! on the device (row `w * per + b`: body `b` of world `w`), which the grid update couples to
//! that world's nodes only (`kernels/grid_update.cu`: `couple_world_bodies`), and the reaction of
//! every body of every world summed per row, read back as below.
//!
//! Per step: every world's body states go to the table (one copy of the host's rows, none when the
//! table holds them already: bodies at rest), the step runs, and the bodies advance.
//!
//! Two tables, taken in turn. A moving tool changes the rows every step; its upload on the
//! batch's stream ran between two steps' kernels, serial with them (4 us a step of 256 rows on
//! an H200, 40 us a call of 10 steps). So each step reads one of two tables (its sums too go to
//! that table's own sums buffer), the next step the other, and a step's copy of the rows (and the
//! clear of its sums buffer) is queued on a stream of its own: it waits for the step that last
//! read that table (an event recorded after it, and after any read of its sums) and the step
//! waits for it (an event after the copy); so the copy for step k + 1 runs while step k's kernels
//! do. The context of the step points at its table (the step's graph is captured once per table,
//! `step::graph`). Each table remembers the version of the rows it holds
//! ([`HostBodies::version`]): none copied when they are the same (tools standing still: no copy
//! to either after the first two steps). Why not one table and the copy ordered after the grid
//! update that reads it: that needs an event inside the step's graph; two tables keep the graph
//! as it is. `body_upload=serial` (`CudaOptions::batch_body_turns`) or
//! `RTMPM_BATCH_UPLOAD=old`: one table, the copy and the clear on the batch's stream
//! before the step, an upload skipped by comparing the rows' bytes with the last upload's, as
//! before (the A/B in one binary).
//!
//! With a
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
use crate::step::graph::GRAPH_TABLES;
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

/// Upload buffers allocated with the batch (two tables in turn), at most
/// [`RESERVED_UPLOAD_BYTES`] of them: a loop whose tools move uploads at every step, and with a
/// call's steps queued ahead of the last call's check (Python's overlap) the host ran 20 or so
/// uploads ahead of the device, so the ring grew in the loop (session 16 call 2: 0.90-0.95 page-
/// locked allocations a call of 10 steps over 20 calls of a fresh batch of 256 worlds).
const RESERVED_UPLOADS: usize = 32;
/// Bytes of page-locked memory [`RESERVED_UPLOADS`] may take (1.3 MB for 256 worlds of a body).
const RESERVED_UPLOAD_BYTES: usize = 4 << 20;

/// `RTMPM_BATCH_UPLOAD=old`: one body table, uploaded on the batch's stream before each step
/// that changed it (as before the two tables of this module's doc); for comparing the two in one
/// binary (bench/python_batch_gpu.py). Read once.
pub fn old_upload() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_UPLOAD").is_ok_and(|v| v.trim() == "old"))
}

/// One of the tables the steps read in turn: the records, the sums the step that reads it writes,
/// what it holds and the event after its last reader.
struct Table {
    /// `worlds x per` [`GpuBody`] records (`Ctx::bodies` of the steps that read it).
    records: CudaSlice<u8>,
    /// `BODY_EXCHANGE_SLOTS` x `worlds x per` rows x 6 f64 sums (`Ctx::body_exchange`).
    exchange: CudaSlice<f64>,
    /// The version of the host's rows it holds ([`HostBodies::version`]; `None` before the first
    /// upload).
    version: Option<u64>,
    /// `exchange` holds the sums of the step that last read it, to be cleared before the next
    /// (`at_read`: they stay for a read of the loads).
    held: bool,
    /// Recorded on the batch's stream after the last work that reads the table or its sums (the
    /// step, a copy of its sums): a copy into them waits for it.
    free: CudaEvent,
}

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
    /// The tables the steps read in turn (one with `RTMPM_BATCH_UPLOAD=old`).
    tables: Vec<Table>,
    /// The table the last step read (its sums are the last step's).
    last: usize,
    /// The stream the uploads and clears of the tables go on (`None` with
    /// `RTMPM_BATCH_UPLOAD=old`: the batch's).
    copies: Option<Arc<CudaStream>>,
    /// Recorded on `copies` after a table's upload: the step that reads it waits for it.
    copied: CudaEvent,
    /// `RTMPM_BATCH_UPLOAD=old`: the bytes the table holds (the last upload's; empty before the
    /// first): an upload of the same bytes is skipped (bodies at rest, tools standing still).
    uploaded: Vec<u8>,
    /// The page-locked memory the uploads of `table` go through (a copy from pageable memory
    /// may wait for the steps queued ahead of it; with several buffers the host may be that
    /// many changed uploads ahead of the device).
    staging: crate::staging::StagingRing,
    /// The host's waits, counted ([`crate::waits`]; the backend's).
    waits: Arc<HostWaits>,
    /// The host's copy of the sums (filled when a load is read, with `at_read`).
    host: Mutex<HostSums>,
    /// The sums stay on the device until a load is read (no dynamic body, and
    /// `CudaOptions::batch_sums_at_read`).
    at_read: bool,
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
    /// `turns`: `CudaOptions::batch_body_turns` (unless `RTMPM_BATCH_UPLOAD=old`); `waits`: the
    /// backend's count of the host's waits.
    pub fn new(
        worlds: &[Scene],
        stream: &Arc<CudaStream>,
        mesh_offsets: Vec<u32>,
        (sums_at_read, poses, turns): (bool, BodyPoses, bool),
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
        let len = BODY_EXCHANGE_SLOTS * rows * 6;
        let old = !turns || old_upload();
        let tables = (0..if old { 1 } else { GRAPH_TABLES })
            .map(|_| new_table(stream, rows, len))
            .collect::<Result<Vec<_>, _>>()?;
        let copies = if old {
            None
        } else {
            Some(
                stream
                    .context()
                    .new_stream()
                    .map_err(err("a stream for uploads"))?,
            )
        };
        let copied = stream.record_event(None).map_err(err("record an event"))?;
        let mut staging = crate::staging::StagingRing::new(UPLOAD_BUFFERS, OLD_UPLOAD_BUFFERS);
        if !old {
            let bytes = (rows * std::mem::size_of::<GpuBody>()).max(1);
            let count = (RESERVED_UPLOAD_BYTES / bytes).clamp(1, RESERVED_UPLOADS);
            staging.reserve(stream, count, bytes, &waits)?;
        }
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
            last: tables.len() - 1,
            tables,
            copies,
            copied,
            uploaded: Vec::new(),
            staging,
            waits,
            host: Mutex::new(HostSums {
                sums: host,
                done,
                copied: true,
            }),
            at_read: sums_at_read && !dynamic,
            stream: stream.clone(),
            dynamic,
            last_dt: None,
        }))
    }

    /// Device addresses for [`crate::contract::Ctx`] of a step that reads table `k`: (the
    /// table, its sums, bodies of a world).
    pub fn ctx_fields(&self, stream: &Arc<CudaStream>, k: usize) -> (u64, u64, u32) {
        let t = &self.tables[k];
        let (a, _) = t.records.device_ptr(stream);
        let (b, _) = t.exchange.device_ptr(stream);
        (a, b, self.per as u32)
    }

    /// Before a step: the table it reads (the other of the last step's; the one with
    /// `RTMPM_BATCH_UPLOAD=old`) given every world's body states unless it holds them already,
    /// and its sums cleared where they were kept on the device; returns that table's index. The
    /// copy and the clear go on the uploads' stream after the last reader of the table, and
    /// `stream` waits for them (the module's doc).
    pub fn upload(&mut self, stream: &Arc<CudaStream>) -> Result<usize, SimError> {
        let k = (self.last + 1) % self.tables.len();
        self.last = k;
        let rigid = self.rigid.get_mut().unwrap_or_else(|p| p.into_inner());
        let version = rigid.version();
        let copy = if self.copies.is_none() {
            let bytes: &[u8] = bytemuck::cast_slice::<GpuBody, u8>(rigid.records());
            bytes != self.uploaded.as_slice()
        } else {
            self.tables[k].version != Some(version)
        };
        if !copy && !self.tables[k].held {
            return Ok(k);
        }
        let Some(side) = self.copies.clone() else {
            self.fill_table(k, stream, copy, version)?;
            return Ok(k);
        };
        side.wait(&self.tables[k].free)
            .map_err(err("order an upload after its table's reader"))?;
        let filled = self.fill_table(k, &side, copy, version);
        // The step waits for whatever was queued, also after an error (nothing on `side` may
        // outlive what the batch's stream orders: its buffers are freed on that stream).
        self.copied
            .record(&side)
            .map_err(err("record an upload's event"))?;
        stream
            .wait(&self.copied)
            .map_err(err("order a step after its table's upload"))?;
        filled.map(|()| k)
    }

    /// Queue on `side` the clear of table `k`'s sums where they are held and, with `copy`, the
    /// copy of the host's records (of `version`) into it (through the staging ring).
    fn fill_table(
        &mut self,
        k: usize,
        side: &Arc<CudaStream>,
        copy: bool,
        version: u64,
    ) -> Result<(), SimError> {
        let t = &mut self.tables[k];
        if t.held {
            side.memset_zeros(&mut t.exchange)
                .map_err(err("clear the worlds' rigid-body impulses"))?;
            t.held = false;
        }
        if !copy {
            return Ok(());
        }
        let rigid = self.rigid.get_mut().unwrap_or_else(|p| p.into_inner());
        let bytes: &[u8] = bytemuck::cast_slice::<GpuBody, u8>(rigid.records());
        if super::staging::pageable_puts() {
            self.waits.wait(WaitReason::Pageable, || ());
            side.memcpy_htod(bytes, &mut t.records.slice_mut(..bytes.len()))
                .map_err(err("upload the worlds' rigid bodies"))?;
        } else {
            self.staging
                .copy_to_device(side, bytes, &mut t.records, &self.waits)?;
        }
        t.version = Some(version);
        if self.copies.is_none() {
            self.uploaded.clear();
            self.uploaded.extend_from_slice(bytes);
        }
        Ok(())
    }

    /// After a step of `dt` was queued: its sums are copied to the host and cleared (kept on the
    /// device until read or the next step, with `at_read`), and every world's bodies advance by
    /// `dt` (with a dynamic body, by their world's sums, waited for).
    pub fn after_step(&mut self, stream: &Arc<CudaStream>, dt: f32) -> Result<(), SimError> {
        self.last_dt = Some(dt);
        let t = &mut self.tables[self.last];
        if self.at_read {
            t.held = true;
            lock(&self.host).copied = false;
        } else {
            let host = self.host.get_mut().unwrap_or_else(|p| p.into_inner());
            stream
                .memcpy_dtoh(&t.exchange, &mut host.sums)
                .map_err(err("read the worlds' rigid-body impulses"))?;
            host.done = stream.record_event(None).map_err(err("record an event"))?;
            stream
                .memset_zeros(&mut t.exchange)
                .map_err(err("clear the worlds' rigid-body impulses"))?;
        }
        if self.copies.is_some() {
            t.free.record(stream).map_err(err("record an event"))?;
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
            let t = &self.tables[self.last];
            self.stream
                .memcpy_dtoh(&t.exchange, &mut h.sums)
                .map_err(err("read the worlds' rigid-body impulses"))?;
            h.done = self
                .stream
                .record_event(None)
                .map_err(err("record an event"))?;
            // The next clear of these sums waits for this copy too.
            t.free
                .record(&self.stream)
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

/// A table of `rows` records and its `len` sums, zeroed on `stream`, its event recorded after.
fn new_table(stream: &Arc<CudaStream>, rows: usize, len: usize) -> Result<Table, SimError> {
    let records = stream
        .alloc_zeros::<u8>(rows * std::mem::size_of::<GpuBody>())
        .map_err(err("alloc the worlds' rigid bodies"))?;
    let exchange = stream
        .alloc_zeros::<f64>(len)
        .map_err(err("alloc the worlds' rigid-body impulses"))?;
    let free = stream.record_event(None).map_err(err("record an event"))?;
    Ok(Table {
        records,
        exchange,
        version: None,
        held: false,
        free,
    })
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
