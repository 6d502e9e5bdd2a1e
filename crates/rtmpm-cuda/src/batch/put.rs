//! Putting state into a batch: the lockstep driver's rewind point kept on the device
//! ([`CudaBatch::save_point`], [`CudaBatch::restore_point`]) and worlds put back from the host,
//! one or many in one upload ([`CudaBatch::put_world`], [`CudaBatch::put_worlds`]).

use super::CudaBatch;
use super::put_slots::within_x;
use super::staging::pageable_puts;
use crate::contract::PUT_GBLOCKS_PER_WARP;
use crate::contract::{CTL_ERROR, CTL_NEED_REBUILD, CTL_P2G_PENDING};
use crate::error::err;
use crate::kernels::Kernel;
use crate::waits::WaitReason;
use cudarc::driver::{CudaSlice, CudaView, DriverError, PushKernelArg};
use rtmpm_physics::Particles;
use rtmpm_sim::SimError;

impl CudaBatch {
    /// Keep every world's particles as they are now as the rewind point (the lockstep driver's,
    /// as an advance begins): one device-to-device copy of the particle state (every word of
    /// every slot, in its storage order), into memory allocated at the first call (as much as
    /// the state). `false`: the device has no memory for it (the driver then keeps the point on
    /// the host, reading every world after each advance, as without this).
    pub fn save_point(&mut self) -> Result<bool, SimError> {
        if self.no_point {
            return Ok(false);
        }
        let b = &mut self.backend;
        if self.point.is_none() {
            // SAFETY: every byte is written by the copy below before anything reads it.
            let (stream, len) = (&b.stream, b.buffers.state.len());
            match b
                .waits
                .wait(WaitReason::Alloc, || unsafe { stream.alloc::<u8>(len) })
            {
                Ok(p) => self.point = Some(p),
                Err(_) => {
                    self.no_point = true;
                    return Ok(false);
                }
            }
        }
        let Some(point) = self.point.as_mut() else {
            return Ok(false);
        };
        b.stream
            .memcpy_dtod(&b.buffers.state, point)
            .map_err(err("keep the rewind point"))?;
        Ok(true)
    }

    /// Keep the state the worlds will have once everything queued so far has run as the next
    /// rewind point (one device-to-device copy queued behind it, into a second buffer as large
    /// as the point, allocated at the first call), leaving the point [`CudaBatch::restore_point`]
    /// puts back as it is: the lockstep driver's next call keeps its point before the last
    /// call's check, which may still rewind to the last point, is made. `false`: no rewind
    /// point is kept on the device, or no memory for a second (nothing kept; the driver keeps
    /// the point after that check, as before).
    pub fn save_next_point(&mut self) -> Result<bool, SimError> {
        if self.no_point || self.point.is_none() {
            return Ok(false);
        }
        let b = &mut self.backend;
        if self.next_point.is_none() {
            // SAFETY: every byte is written by the copy below before anything reads it.
            let (stream, len) = (&b.stream, b.buffers.state.len());
            match b
                .waits
                .wait(WaitReason::Alloc, || unsafe { stream.alloc::<u8>(len) })
            {
                Ok(p) => self.next_point = Some(p),
                Err(_) => return Ok(false),
            }
        }
        let Some(next) = self.next_point.as_mut() else {
            return Ok(false);
        };
        b.stream
            .memcpy_dtod(&b.buffers.state, next)
            .map_err(err("keep the next rewind point"))?;
        Ok(true)
    }

    /// Make the point the last [`CudaBatch::save_next_point`] kept the rewind point (the two
    /// buffers swapped: no copy); the point before becomes the next one's buffer.
    pub fn use_next_point(&mut self) -> Result<(), SimError> {
        if self.next_point.is_none() || self.no_point {
            return Err(SimError::Backend(
                "CUDA batch: no next rewind point was kept (save_next_point first)".into(),
            ));
        }
        std::mem::swap(&mut self.point, &mut self.next_point);
        Ok(())
    }

    /// The steps queued after a check's copy that found a failure are dropped (the lockstep
    /// driver's pipelined call, rewound): the error word they may have set, stepping from the
    /// blown-up state (a grid's capacity overflowed by particles flying off), is cleared on the
    /// stream behind them, as it was when the check's copy was taken (a set word ends the run at
    /// that check). The rest is put back by [`CudaBatch::restore_point`] (the state; the mapping
    /// rebuilt) or was reset by the check (its bad-particle words).
    pub fn drop_queued_steps(&mut self) -> Result<(), SimError> {
        // A rebuild the error stopped may have left the slot ranges half made
        // (crate::batch::put_slots), and the cleared word no longer says so.
        self.put_slots.doubt();
        self.backend.set_ctl_word(CTL_ERROR, 0)
    }

    /// Put every world's particles back to the last [`CudaBatch::save_point`], word for word
    /// (their storage order too); the next step rebuilds the mapping (always, unlike after
    /// [`CudaBatch::put_world`]: the point is in the storage order of its save, which a rebuild
    /// since may have changed) and redoes its P2G. Rigid bodies are not part of the point
    /// ([`CudaBatch::set_world_poses`]).
    pub fn restore_point(&mut self) -> Result<(), SimError> {
        let Some(point) = self.point.as_ref().filter(|_| !self.no_point) else {
            return Err(SimError::Backend(
                "CUDA batch: no rewind point was kept (save_point first)".into(),
            ));
        };
        let b = &mut self.backend;
        b.stream
            .memcpy_dtod(point, &mut b.buffers.state)
            .map_err(err("put the rewind point back"))?;
        b.set_ctl_word(CTL_NEED_REBUILD, 1)?;
        if b.g2p2g() {
            b.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        // Every world's P2G is redone (and the mapping rebuilt): nothing left to redo alone.
        self.put_since.clear();
        // The state is in the point's order, not the last rebuild's (crate::batch::put_slots).
        self.put_slots.doubt();
        // Everything after is queued behind the copy on the same stream: no wait (but with
        // `RTMPM_BATCH_WAITS=old`, as before).
        if crate::waits::old_waits() {
            b.waits
                .wait(WaitReason::Sync, || b.stream.synchronize())
                .map_err(err("put the rewind point back"))?;
        }
        Ok(())
    }

    /// Keep the rewind point on the device (`true`, the default) or not (`false`: the driver
    /// keeps it on the host, reading every world after each advance, as before the device
    /// point existed; for comparisons of the two).
    pub fn set_device_point(&mut self, on: bool) {
        self.no_point = !on;
        if !on {
            (self.point, self.next_point) = (None, None);
        }
    }

    /// Bytes of the rewind points on the device (0 before the first
    /// [`CudaBatch::save_point`]; twice the state once a next point was kept,
    /// [`CudaBatch::save_next_point`]).
    pub fn point_bytes(&self) -> usize {
        let bytes = |p: &Option<CudaSlice<u8>>| p.as_ref().map_or(0, |p| p.len());
        bytes(&self.point) + bytes(&self.next_point)
    }

    /// Put world `w`'s particles to `particles` (its initial ones for a reset, or any state of
    /// as many particles, in its own material indices), the other worlds untouched: the state
    /// words of its slots are overwritten (`batch_put_gblocks` or `batch_put_world`,
    /// `kernels/batch.cu`, [`super::put_slots`]) and the next
    /// step redoes its P2G (with G2P2G, whose last fused scatter was of the old particles: that
    /// world's alone, [`CudaBatch::redo_puts`]). The
    /// mapping of particles to blocks is rebuilt at the next step only when a particle put
    /// needs it: when its stencil base leaves the free zone of the gblock its slot was sorted
    /// into (G2P's rule, checked by the kernel, `kernels/batch.cu`), as a step rebuilds when a
    /// particle moves out of it; a world put back within about a block of where it is (a reset
    /// of a world that has not gone far) costs the other worlds no rebuild.
    /// [`CudaBatch::put_worlds`] of one world.
    pub fn put_world(&mut self, w: usize, particles: &Particles) -> Result<(), SimError> {
        self.put_many(&[(w, particles)])
    }

    /// Put each world `w` of `worlds` to its particles as [`CudaBatch::put_world`] does, all at
    /// once: every world is checked before any changes (a world listed twice ends with its
    /// last); each run of consecutive worlds is packed as one (their particles are consecutive
    /// in original order), all runs go to the device in one copy (into a buffer kept between
    /// calls, [`CudaBatch::put_bytes`]), one put launch a run and the worlds
    /// listed for the redo of their P2G before the next step (with G2P2G,
    /// [`CudaBatch::redo_puts`]), where a world at a time paid an allocation, a copy, two
    /// control-word writes and a wait. Nothing waits for the device: the images go through kept
    /// page-locked memory, an asynchronous copy even while steps are queued ahead of it
    /// ([`CudaBatch::upload_put`]; `RTMPM_BATCH_PAGEABLE_PUT=1` copies from pageable memory as
    /// before), and whatever reads the worlds next (a step, a read, a gather) is queued behind
    /// the launches on the same stream.
    pub fn put_worlds(&mut self, worlds: &[(usize, Particles)]) -> Result<(), SimError> {
        let refs: Vec<(usize, &Particles)> = worlds.iter().map(|(w, p)| (*w, p)).collect();
        self.put_many(&refs)
    }

    /// Bytes of the device buffer the last [`CudaBatch::put_worlds`] uploaded into (kept for
    /// the next; as large as the largest put so far, 0 before the first).
    pub fn put_bytes(&self) -> usize {
        self.put_buffer.as_ref().map_or(0, |b| b.len())
    }

    /// World `w` exists and `particles` fit it (as many as it has, its own materials).
    pub(super) fn check_put(&self, w: usize, particles: &Particles) -> Result<(), SimError> {
        if w >= self.worlds() {
            return Err(SimError::Backend(format!(
                "CUDA batch: no world {w} (the batch has {})",
                self.worlds()
            )));
        }
        let count = self.offsets[w + 1] - self.offsets[w];
        if particles.len() != count {
            return Err(SimError::Backend(format!(
                "CUDA batch: world {w} has {count} particles, {} given",
                particles.len()
            )));
        }
        if let Some(k) = particles
            .material
            .iter()
            .find(|&&k| k as usize >= self.materials)
        {
            return Err(SimError::Backend(format!(
                "CUDA batch: world {w}: material {k}, a world has {}",
                self.materials
            )));
        }
        Ok(())
    }

    /// The packed images of the runs of consecutive worlds of `given` (world `w`'s particles or
    /// `None`), one after another in the kept host buffer `put_host`: each run as (its first
    /// particle, its particles, where its image starts in the buffer, its image's length), its
    /// materials as the kernels' rows (`w * materials + k`). The run's particles are gathered
    /// in the kept `put_run` and packed straight into the buffer: no allocation, no fresh page.
    fn pack_runs(&mut self, given: &[Option<&Particles>]) -> Result<Vec<PutRun>, SimError> {
        let fluid = crate::state::fluid_materials(&self.backend.scene);
        let (layout, f64) = (self.backend.layout, self.backend.options.f64);
        let mut run = std::mem::take(&mut self.put_run);
        let mut bytes = std::mem::take(&mut self.put_host);
        bytes.clear();
        let mut runs = Vec::new();
        let mut packed = Ok(());
        let mut w = 0;
        while w < given.len() && packed.is_ok() {
            if given[w].is_none() {
                w += 1;
                continue;
            }
            clear_particles(&mut run);
            let first = self.offsets[w];
            while let Some(Some(p)) = given.get(w) {
                let at = run.len();
                run.extend(p);
                for k in &mut run.material[at..] {
                    *k += (w * self.materials) as u32;
                }
                w += 1;
            }
            let at = bytes.len();
            packed = crate::state::pack_into(&run, &fluid, layout, f64, run.len(), &mut bytes);
            runs.push((first as u32, run.len() as u32, at, bytes.len() - at));
        }
        self.put_run = run;
        self.put_host = bytes;
        packed.map_err(SimError::Backend)?;
        Ok(runs)
    }

    /// [`CudaBatch::put_worlds`] of borrowed particles.
    pub(super) fn put_many(&mut self, worlds: &[(usize, &Particles)]) -> Result<(), SimError> {
        for &(w, p) in worlds {
            self.check_put(w, p)?;
        }
        let (lo, hi) = (self.clock.domain_min.x, self.clock.domain_max.x);
        if !worlds.iter().all(|(_, p)| within_x(p, lo, hi)) {
            // Before any launch: the put's own launches test every slot.
            self.put_slots.doubt();
        }
        let mut given: Vec<Option<&Particles>> = vec![None; self.worlds()];
        for &(w, p) in worlds {
            given[w] = Some(p);
        }
        let t0 = std::time::Instant::now();
        let runs = self.pack_runs(&given)?;
        if runs.is_empty() {
            return Ok(());
        }
        let t1 = std::time::Instant::now();
        self.upload_put()?;
        let t2 = std::time::Instant::now();
        let Some(buf) = self.put_buffer.as_ref() else {
            return Ok(());
        };
        for (first, count, at, len) in &runs {
            // The run's image: `count` particles a row.
            self.launch_put(&buf.slice(*at..*at + *len), *first, *count, *count)
                .map_err(err("put worlds"))?;
        }
        // The rebuild flag is the kernel's (only where a particle put leaves its zone); the P2G
        // of the worlds put is redone before the next step (crate::batch::redo).
        self.note_put(worlds.iter().map(|(w, _)| *w))?;
        PUT_TIMING.record(worlds.len(), [t0, t1, t2], std::time::Instant::now());
        Ok(())
    }
}

impl CudaBatch {
    /// The packed images of a put (`put_host`) into the device buffer `put_buffer` (allocated,
    /// or grown, to fit): by default through the kept page-locked buffers `put_staging`, an
    /// asynchronous copy that returns at once even while steps are queued ahead of it (the
    /// images are copied into a buffer whose last copy is done:
    /// [`crate::staging::StagingRing`]); with
    /// `RTMPM_BATCH_PAGEABLE_PUT=1` ([`pageable_puts`]) straight from the pageable `put_host`
    /// as before, which the driver stages itself (and, for a large put, may wait for the
    /// stream to reach the copy).
    fn upload_put(&mut self) -> Result<(), SimError> {
        let (stream, len) = (self.backend.stream.clone(), self.put_host.len());
        if self.put_buffer.as_ref().is_none_or(|buf| buf.len() < len) {
            self.put_buffer = None;
            // SAFETY: the copy below writes every byte the kernels read (`len` bytes).
            let buf = self
                .backend
                .waits
                .wait(WaitReason::Alloc, || unsafe { stream.alloc::<u8>(len) })
                .map_err(err("upload worlds"))?;
            self.put_buffer = Some(buf);
        }
        let Some(buf) = self.put_buffer.as_mut() else {
            return Ok(());
        };
        if pageable_puts() {
            self.backend.waits.wait(WaitReason::Pageable, || ());
            return stream
                .memcpy_htod(&self.put_host, &mut buf.slice_mut(..len))
                .map_err(err("upload worlds"));
        }
        self.put_staging
            .copy_to_device(&stream, &self.put_host, buf, &self.backend.waits)
    }
}

/// The launch of a put (which kernel, over which slots: [`super::put_slots`]).
impl CudaBatch {
    /// Queue the put of particles `first..first + count` (original order, whole worlds) from
    /// `src` (structure of arrays, rows of `stride` particles, from particle `first`):
    /// `batch_put_gblocks` where the slot ranges are trusted ([`super::PutSlots`]), else
    /// `batch_put_world` over every slot.
    pub(super) fn launch_put(
        &self,
        src: &CudaView<'_, u8>,
        first: u32,
        count: u32,
        stride: u32,
    ) -> Result<(), DriverError> {
        let b = &self.backend;
        let (kernel, cfg) = if self.gblock_puts && self.put_slots.trusted() {
            let threads = b.ctx.gblock_cap as usize * 32 / PUT_GBLOCKS_PER_WARP;
            (Kernel::BatchPutGblocks, b.kernels.wave(threads, 256))
        } else {
            (Kernel::BatchPutWorld, b.kernels.wave(b.n, 256))
        };
        // SAFETY: the kernels read `src` at `f * stride + k` for the state's words `f` and
        // `k < count` (the caller's image holds them), write the state's slots below n and the
        // rebuild flag, and bound every other index by the device counters and capacities.
        unsafe {
            b.stream
                .launch_builder(&b.kernels[kernel])
                .arg(&b.ctx)
                .arg(src)
                .arg(&first)
                .arg(&count)
                .arg(&stride)
                .launch(cfg)
        }
        .map(|_| ())
    }

    /// Put with `batch_put_gblocks` where it applies (`true`, the default but with
    /// `RTMPM_BATCH_PUT=old`) or always with `batch_put_world` over every slot (`false`); for
    /// comparisons of the two in one process.
    pub fn set_gblock_puts(&mut self, on: bool) {
        self.gblock_puts = on;
    }

    /// Whether the next put would use `batch_put_gblocks` (on, and the slot ranges trusted).
    pub fn gblock_put_next(&self) -> bool {
        self.gblock_puts && self.put_slots.trusted()
    }
}

/// `RTMPM_RESET_TIMING=1`: where a put's host time goes, printed to stderr every 100 puts (the
/// means of the packing, the upload's host side and the launches); off by default.
static PUT_TIMING: rtmpm_sim::timing::PartTimes<3> = rtmpm_sim::timing::PartTimes::new(
    "RTMPM_RESET_TIMING",
    "put",
    "worlds",
    ["pack", "upload", "launches"],
);

/// A run of consecutive worlds put at once ([`CudaBatch::put_worlds`]): its first particle
/// (original order), its particles, where its packed image starts in the upload and its length
/// (bytes).
type PutRun = (u32, u32, usize, usize);

/// `p` emptied, its vectors' memory kept.
pub(super) fn clear_particles(p: &mut Particles) {
    p.x.clear();
    p.v.clear();
    p.c.clear();
    p.f.clear();
    p.plastic.clear();
    p.mass.clear();
    p.vol0.clear();
    p.material.clear();
}
