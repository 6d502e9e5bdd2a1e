//! Several GPUs of one process ([`MultiGpuBackend`]): one worker thread per GPU, each owning its
//! CUDA context, streams, graph and (transport=nccl) NCCL communicator.

use super::barrier::HostBarrier;
use super::nccl::UniqueId;
use super::partition::split;
use super::plan::{check_supported, dense_count, plan, shared_capacity, subset};
use super::rank::{CommSource, GpuRank};
use super::reduce_shared::MAX_PEER_GPUS;
use super::rigid::SharedBodies;
use crate::backend::Part;
use crate::backend::readback::{resize_particles, scatter_state};
use crate::contract::{CTL_MAX_SPEED, CTL_SHARED};
use crate::options::{BarrierKind, CudaOptions, ExchangeMode, Transport};
use crate::step::rigid::{HeldBodies, loads_of, poses_of, set_poses_of, states_of};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::{Backend, BadParticle, SimError};
use std::sync::{Arc, mpsc};

fn nccl_err(e: String) -> SimError {
    SimError::Backend(e)
}

type Job = Box<dyn FnOnce(&mut Option<GpuRank>) + Send>;

struct Worker {
    tx: Option<mpsc::Sender<Job>>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// N GPUs of one process, one thread per GPU (each owns its CUDA context, streams, graph and,
/// with transport=nccl, NCCL communicator).
pub struct MultiGpuBackend {
    workers: Vec<Worker>,
    scene: Scene,
    options: CudaOptions,
    transport: Transport,
    /// The CUDA device of each rank.
    devices: Vec<usize>,
    /// Events barrier: where the worker threads meet.
    host: Arc<HostBarrier>,
    n: usize,
    name: String,
    shared_cap: usize,
    shared_at_partition: usize,
    d: usize,
    /// Rebalances done so far.
    pub rebalances: u32,
    /// The user's tool (given again to the ranks rebuilt by a rebalance).
    tool: Option<rtmpm_geometry::Tool>,
    /// Rigid bodies (`[[rigid_body]]`): their one world ([`super::rigid`]).
    bodies: Option<SharedBodies>,
}

impl MultiGpuBackend {
    /// Split the particles over GPUs 0..gpus and start one worker per GPU.
    pub fn new(
        scene: &Scene,
        particles: &Particles,
        gpus: usize,
        options: CudaOptions,
    ) -> Result<MultiGpuBackend, SimError> {
        check_supported(scene, &options)?;
        let devices = rank_devices(gpus, &options)?;
        // The bodies' world before any GPU work (its refusals are clear errors).
        let bodies = SharedBodies::new(scene, &options)?;
        let info = crate::probe::probe().map_err(|e| SimError::Backend(e.to_string()))?;
        let (transport, why) = choose_transport(&devices, &options)?;
        let mut options = options;
        options.transport = Some(transport);
        if transport == Transport::P2p {
            options.barrier = Some(choose_barrier(&devices, &options)?);
        }
        check_exchange(&options)?;
        resolve_exchange_defaults(&mut options);
        let on = match &options.devices {
            Some(_) => format!(
                " on devices {}",
                devices
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(":")
            ),
            None => String::new(),
        };
        let (id, what) = match transport {
            Transport::Nccl => {
                let nccl = super::nccl::library().map_err(|e| {
                    SimError::Backend(format!("several GPUs with transport=nccl need NCCL: {e}"))
                })?;
                let id = nccl.unique_id().map_err(nccl_err)?;
                (
                    Some(id),
                    format!("transport nccl: NCCL {} ({why})", nccl.version),
                )
            }
            Transport::P2p => {
                let b = match options.barrier {
                    Some(BarrierKind::Events) => "events barrier, no CUDA graph",
                    _ => "spin barrier",
                };
                (None, format!("transport p2p, {b} ({why})"))
            }
        };
        let mut m = MultiGpuBackend {
            workers: Vec::new(),
            scene: scene.clone(),
            options: options.clone(),
            transport,
            devices,
            host: Arc::new(HostBarrier::new(gpus)),
            n: particles.len(),
            name: format!("cuda x{gpus}{on} ({}, {what})", info.name),
            shared_cap: 0,
            shared_at_partition: 0,
            d: dense_count(scene),
            rebalances: 0,
            tool: None,
            bodies,
        };
        for _ in 0..gpus {
            let (tx, rx) = mpsc::channel::<Job>();
            let handle = std::thread::spawn(move || {
                let mut rank: Option<GpuRank> = None;
                while let Ok(job) = rx.recv() {
                    job(&mut rank);
                }
            });
            m.workers.push(Worker {
                tx: Some(tx),
                handle: Some(handle),
            });
        }
        m.load(particles, id)?;
        Ok(m)
    }

    /// The transport of the shared-block reduction.
    pub fn transport(&self) -> Transport {
        self.transport
    }

    /// What the reduction of a step consists of (for reports).
    pub fn reduction_steps(&self) -> &'static str {
        match (
            self.transport,
            self.options.barrier,
            self.options.exchange.unwrap_or_default(),
        ) {
            (Transport::Nccl, _, _) => "pack + NCCL all-reduce + unpack",
            (Transport::P2p, Some(BarrierKind::Events), _) => {
                "pack + events barrier + sum of peer reads"
            }
            (Transport::P2p, _, ExchangeMode::ListPushUpdate) => {
                "shared list and push in one kernel after P2G + grid update that waits on own \
                 counter and sums the inbox (timed together with the list and the grid update)"
            }
            (Transport::P2p, _, ExchangeMode::PushUpdate) => {
                "push to the holders' inboxes + grid update that waits on own counter and sums \
                 the inbox (timed together with the grid update); list fused"
            }
            (Transport::P2p, _, ExchangeMode::Push) => {
                "push to the holders' inboxes + wait on own counter + sum of the inbox; list fused"
            }
            (Transport::P2p, _, ExchangeMode::Fused) => {
                "pack + spin barrier + sum of peer reads; list fused"
            }
            (Transport::P2p, _, ExchangeMode::Kernels) => "pack + spin barrier + sum of peer reads",
        }
    }

    /// transport=p2p: give every GPU the others' buffers and barrier (after any reallocation).
    fn connect(&self) -> Result<(), SimError> {
        if self.transport != Transport::P2p {
            return Ok(());
        }
        let gpus = self.workers.len();
        let all = Arc::new(self.all(move |_, r| rank(r)?.peer_export(gpus))?);
        let host = self.host.clone();
        self.all(move |i, r| rank(r)?.connect(i, &all, host.clone()))?;
        Ok(())
    }

    /// Run `f` on every worker (concurrently) and collect the results in rank order.
    fn all<R: Send + 'static>(
        &self,
        f: impl Fn(usize, &mut Option<GpuRank>) -> Result<R, SimError> + Send + Sync + 'static,
    ) -> Result<Vec<R>, SimError> {
        let f = Arc::new(f);
        let mut rxs = Vec::new();
        for (i, w) in self.workers.iter().enumerate() {
            let (tx, rx) = mpsc::channel();
            let f = f.clone();
            let job: Job = Box::new(move |r| {
                let _ = tx.send(f(i, r));
            });
            w.tx.as_ref()
                .and_then(|t| t.send(job).ok())
                .ok_or_else(|| SimError::Backend(format!("GPU worker {i} is gone")))?;
            rxs.push(rx);
        }
        let mut out = Vec::new();
        for (i, rx) in rxs.into_iter().enumerate() {
            out.push(
                rx.recv().map_err(|_| {
                    SimError::Backend(format!("GPU worker {i} stopped (panicked)"))
                })??,
            );
        }
        Ok(out)
    }

    /// Partition `particles` and (re)build every GPU's rank (new communicator when `id` is given).
    fn load(&mut self, particles: &Particles, id: Option<UniqueId>) -> Result<(), SimError> {
        let ranks = self.workers.len();
        let part = split(&particles.x, ranks, self.options.partition);
        let (cap, s) = shared_capacity(&self.scene, particles, &part, &self.options);
        self.shared_cap = cap.max(self.shared_cap.min(self.d));
        self.shared_at_partition = s;
        let subsets: Arc<Vec<(Particles, Vec<u32>)>> = Arc::new(
            part.parts
                .iter()
                .map(|ids| (subset(particles, ids), ids.clone()))
                .collect(),
        );
        let (scene, options, cap) = (self.scene.clone(), self.options.clone(), self.shared_cap);
        let p2p = self.transport == Transport::P2p;
        let devices = self.devices.clone();
        self.all(move |i, slot| {
            let (p, ids) = &subsets[i];
            let part = Part {
                device: devices[i],
                ids: Some(ids.clone()),
                capacity: 0,
            };
            let comm = match (slot.take(), id) {
                _ if p2p => CommSource::PeerToPeer,
                (_, Some(id)) => CommSource::New { id, rank: i, ranks },
                (Some(old), None) => match old.into_comm() {
                    Some(c) => CommSource::Existing(c),
                    None => return Err(SimError::Backend("no communicator".into())),
                },
                (None, None) => return Err(SimError::Backend("no communicator".into())),
            };
            *slot = Some(GpuRank::new(&scene, p, &part, options.clone(), cap, comm)?);
            Ok(())
        })?;
        if let Some(t) = self.tool {
            self.all(move |_, r| rank(r)?.b.set_tool(Some(t)))?;
        }
        self.connect()
    }

    /// Re-partition the particles now (gather, split, rebuild every GPU's rank; synchronises).
    pub fn rebalance_now(&mut self) -> Result<(), SimError> {
        // The bodies take the sums held by the ranks about to be rebuilt.
        self.flush_rigid()?;
        let speed = self
            .ctls()?
            .iter()
            .map(|c| c[CTL_MAX_SPEED])
            .max()
            .unwrap_or(0);
        let mut all = Particles::default();
        self.read_particles(&mut all)?;
        self.load(&all, None)?;
        self.all(move |_, r| rank(r)?.b.set_ctl_word(CTL_MAX_SPEED, speed))?;
        self.rebalances += 1;
        Ok(())
    }

    /// Enqueue one step on every GPU, with the bodies' states of now; the bodies then take the
    /// sums of this step (without overlap) or of the one before ([`super::rigid`]).
    fn step_ranks(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let states = self.bodies.as_ref().map(|b| Arc::new(b.states().to_vec()));
        let copies = self.all(move |_, r| {
            let r = rank(r)?;
            if let Some(s) = &states {
                r.set_body_states(s);
            }
            r.step(dt, t)?;
            Ok(r.body_copy())
        })?;
        let due = match (self.bodies.as_mut(), copies.first().copied().flatten()) {
            (Some(b), Some(k)) => b.queued(k, dt),
            _ => None,
        };
        match due {
            Some((k, dt)) => self.advance_bodies(k, dt),
            None => Ok(()),
        }
    }

    /// Give the bodies every GPU's sums of host copy `k` and advance them by `dt`.
    fn advance_bodies(&mut self, k: usize, dt: f32) -> Result<(), SimError> {
        let per_rank = self.all(move |_, r| rank(r)?.body_sums(k))?;
        if let Some(b) = self.bodies.as_mut() {
            b.advance(&per_rank, dt);
        }
        Ok(())
    }

    fn ctls(&self) -> Result<Vec<Vec<u32>>, SimError> {
        self.all(|_, r| rank(r)?.ctl())
    }

    /// Shared blocks now (synchronises).
    pub fn shared_blocks(&self) -> Result<usize, SimError> {
        Ok(self.ctls()?[0][CTL_SHARED] as usize)
    }

    /// Particles per GPU.
    pub fn counts(&self) -> Result<Vec<usize>, SimError> {
        self.all(|_, r| Ok(rank(r)?.b.len()))
    }

    /// Time `steps` steps of size `dt` from time `t0` with events (no graph): returns the
    /// milliseconds per step of the whole step (host wall clock, synchronised every step) and of
    /// the shared-block reduction (the slowest GPU's pack + all-reduce + unpack).
    pub fn time_reduction(&mut self, dt: f32, t0: f32, steps: u32) -> Result<(f64, f64), SimError> {
        self.all(|_, r| rank(r)?.enable_timing())?;
        let mut reduce = 0.0;
        let start = std::time::Instant::now();
        for i in 0..steps {
            let t = t0 + i as f32 * dt;
            self.step_ranks(dt, t)?;
            let ms = self.all(|_, r| rank(r)?.last_reduce_ms())?;
            reduce += ms.into_iter().fold(0.0, f64::max);
        }
        let wall = start.elapsed().as_secs_f64() * 1e3;
        self.all(|_, r| {
            rank(r)?.disable_timing();
            Ok(())
        })?;
        Ok((wall / steps.max(1) as f64, reduce / steps.max(1) as f64))
    }
}

impl Drop for MultiGpuBackend {
    fn drop(&mut self) {
        // Let every worker leave its loop (and destroy its communicator) before joining any.
        for w in &mut self.workers {
            w.tx = None;
        }
    }
}

fn rank(r: &mut Option<GpuRank>) -> Result<&mut GpuRank, SimError> {
    r.as_mut()
        .ok_or_else(|| SimError::Backend("GPU worker without a rank".into()))
}

impl Backend for MultiGpuBackend {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn num_particles(&self) -> usize {
        self.n
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.step_ranks(dt, t)
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let speed = self.all(|_, r| rank(r)?.b.max_speed())?;
        Ok(speed.into_iter().fold(0.0, f32::max))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let bad = self.all(|_, r| rank(r)?.b.check())?;
        Ok(bad.into_iter().flatten().min_by_key(|b| b.index))
    }

    /// Gravity on every GPU (and the rigid bodies').
    fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) -> Result<(), SimError> {
        self.all(move |_, r| rank(r)?.b.set_gravity(gravity))?;
        if let Some(b) = self.bodies.as_mut() {
            b.set_gravity(gravity);
        }
        self.scene.gravity = gravity;
        Ok(())
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        states_of(self.bodies.as_ref())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        poses_of(self.bodies.as_ref())
    }

    /// Every body's load over the last step the bodies took, summed over the GPUs (kinematic
    /// and fixed bodies too; with `rigid_overlap`, the last step's after
    /// [`Backend::flush_rigid`]), as on one GPU.
    fn rigid_loads(&self) -> Option<Vec<rtmpm_rigid::BodyLoad>> {
        loads_of(self.bodies.as_ref())
    }

    fn flush_rigid(&mut self) -> Result<(), SimError> {
        match self.bodies.as_mut().and_then(|b| b.take_pending()) {
            Some((k, dt)) => self.advance_bodies(k, dt),
            None => Ok(()),
        }
    }

    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        set_poses_of(self.bodies.as_mut(), poses)
    }

    /// The tool on every GPU (each applies it to the grid nodes of its particles).
    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        self.all(move |_, r| rank(r)?.b.set_tool(tool))?;
        self.tool = tool;
        Ok(())
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let states = self.all(|_, r| {
            let r = rank(r)?;
            let layout = r.b.state_layout();
            Ok((r.b.read_state()?, r.b.len(), r.b.ctx.cap as usize, layout))
        })?;
        *out = Particles::default();
        resize_particles(out, self.n);
        for (host, n, cap, layout) in &states {
            scatter_state(host, *n, *cap, *layout, out)?;
        }
        Ok(())
    }

    /// The bodies take the impulses of the frame's last step (as on one GPU), then the
    /// reduction grows or the particles are re-partitioned where the plan says so.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.flush_rigid()?;
        let c = self.ctls()?;
        let shared = c[0][CTL_SHARED] as usize;
        let p = plan(
            shared,
            self.shared_cap,
            self.d,
            self.shared_at_partition,
            self.workers.len(),
            &self.options,
        );
        if p.rebalance {
            self.rebalance_now()?;
        } else if let Some(cap) = p.grow_to {
            self.shared_cap = cap;
            self.all(move |_, r| rank(r)?.set_shared_capacity(cap))?;
            self.connect()?;
        }
        Ok(())
    }
}

/// The CUDA device of each of `gpus` ranks: `devices=` of the options, else 0..gpus; every one
/// present.
fn rank_devices(gpus: usize, o: &CudaOptions) -> Result<Vec<usize>, SimError> {
    let found = crate::probe::device_count();
    let why = || {
        if found == 0 {
            format!(
                " ({})",
                crate::probe::probe()
                    .err()
                    .map(|e| e.to_string())
                    .unwrap_or_default()
            )
        } else {
            String::new()
        }
    };
    let devices = match &o.devices {
        None => {
            if gpus < 1 || gpus > found {
                return Err(SimError::Backend(format!(
                    "--gpus {gpus}: {found} CUDA device(s) found{}",
                    why()
                )));
            }
            (0..gpus).collect()
        }
        Some(d) => {
            if d.len() != gpus {
                return Err(SimError::Backend(format!(
                    "devices= names {} device(s) for {gpus} GPU ranks (--gpus {gpus}): name \
                     one device per rank",
                    d.len()
                )));
            }
            if let Some(bad) = d.iter().find(|&&x| x >= found) {
                return Err(SimError::Backend(format!(
                    "devices=: CUDA device {bad} asked, {found} CUDA device(s) found{}",
                    why()
                )));
            }
            d.clone()
        }
    };
    Ok(devices)
}

/// Two ranks on one device (`devices=`), as (first rank, second rank, device).
fn shared_device(devices: &[usize]) -> Option<(usize, usize, usize)> {
    (0..devices.len())
        .flat_map(|i| (i + 1..devices.len()).map(move |j| (i, j)))
        .find(|&(i, j)| devices[i] == devices[j])
        .map(|(i, j)| (i, j, devices[i]))
}

/// The transport of a run of GPU ranks on `devices` in one process, and why: the one asked
/// for, else p2p when every pair of GPUs has peer access (and there are at most
/// [`MAX_PEER_GPUS`]), else NCCL. Ranks sharing a device run p2p only.
fn choose_transport(devices: &[usize], o: &CudaOptions) -> Result<(Transport, String), SimError> {
    let gpus = devices.len();
    if o.transport == Some(Transport::Nccl) && o.barrier.is_some() {
        return Err(SimError::Backend(
            "barrier= applies to transport=p2p only (NCCL synchronises the GPUs itself)".into(),
        ));
    }
    // NCCL refuses two ranks on one device.
    let shared = shared_device(devices);
    if let (Some(Transport::Nccl), Some((i, j, d))) = (o.transport, shared) {
        return Err(SimError::Backend(format!(
            "transport=nccl: ranks {i} and {j} are both on CUDA device {d} (devices=), and NCCL \
             refuses two ranks on one device; use transport=p2p (with barrier=events) or one \
             device per rank"
        )));
    }
    let p2p = o.transport == Some(Transport::P2p) || (o.transport.is_none() && shared.is_some());
    if p2p && gpus > MAX_PEER_GPUS {
        return Err(SimError::Backend(format!(
            "transport=p2p handles at most {MAX_PEER_GPUS} GPUs; use transport=nccl (one device \
             per rank)"
        )));
    }
    let missing = super::peer::first_pair_without_access_among(devices)
        .map_err(|e| SimError::Backend(format!("peer access query: {e}")))?;
    let chosen = match (o.transport, missing) {
        (Some(Transport::P2p), Some((i, j))) => {
            return Err(SimError::Backend(format!(
                "transport=p2p: GPU {i} has no peer access to GPU {j}'s memory; use \
                 transport=nccl (or leave transport= out)"
            )));
        }
        (None, Some((i, j))) if shared.is_some() => {
            return Err(SimError::Backend(format!(
                "devices=: ranks that share a device run transport=p2p, but GPU {i} has no \
                 peer access to GPU {j}'s memory; name one device per rank"
            )));
        }
        (Some(t), _) => (t, "asked for".to_string()),
        (None, _) if shared.is_some() => (
            Transport::P2p,
            "default: ranks share a device (devices=)".to_string(),
        ),
        (None, Some((i, j))) => (
            Transport::Nccl,
            format!("default: GPU {i} has no peer access to GPU {j}"),
        ),
        (None, None) if gpus > MAX_PEER_GPUS => (
            Transport::Nccl,
            format!("default: p2p handles at most {MAX_PEER_GPUS} GPUs"),
        ),
        (None, None) => (
            Transport::P2p,
            "default: peer access between every pair of GPUs".to_string(),
        ),
    };
    if chosen.0 == Transport::Nccl && o.barrier.is_some() {
        return Err(SimError::Backend(
            "barrier= applies to transport=p2p only (NCCL synchronises the GPUs itself)".into(),
        ));
    }
    Ok(chosen)
}

/// `exchange=fused|push|push_update` need transport=p2p with the spin barrier (their kernels
/// take the inter-GPU barrier inside them), and `push_update` runs without the overlap (its
/// grid update kernel overlaps the wait itself); a clear error otherwise. `o`: the options with
/// the transport and barrier chosen.
fn check_exchange(o: &CudaOptions) -> Result<(), SimError> {
    let Some(mode) = o.exchange.filter(|&m| m != ExchangeMode::Kernels) else {
        return Ok(());
    };
    let name = super::exchange::mode_name(mode);
    if mode.sums_in_update() && o.overlap == Some(true) {
        return Err(SimError::Backend(format!(
            "exchange={name} sums the inbox inside the grid update, which updates the unshared \
             pblocks while it waits: it has no overlap on a second stream; leave overlap= out \
             (or off), or use exchange=push with overlap=on"
        )));
    }
    match (o.transport, o.barrier) {
        (Some(Transport::P2p), Some(BarrierKind::Spin)) => Ok(()),
        (Some(Transport::P2p), _) => Err(SimError::Backend(format!(
            "exchange={name} takes the spin barrier inside its kernels, and this run has the \
             events barrier (barrier=events, ranks sharing a device, or GPUs without native \
             atomics between them); use exchange=kernels"
        ))),
        _ => Err(SimError::Backend(format!(
            "exchange={name} needs transport=p2p (peer access between every pair of GPUs); with \
             NCCL use exchange=kernels"
        ))),
    }
}

/// The defaults of `exchange=` and `overlap=` for the transport and barrier chosen (`o`: the
/// options with both set): with transport=p2p and the spin barrier `exchange=push` without the
/// overlap (measured faster on 2 H200s, weak and strong: docs/multi-gpu.md, "The defaults of
/// two GPUs"); otherwise `exchange=kernels` with the overlap, as before. What was asked for is
/// kept.
fn resolve_exchange_defaults(o: &mut CudaOptions) {
    let spin = o.transport == Some(Transport::P2p) && o.barrier == Some(BarrierKind::Spin);
    o.exchange = Some(o.exchange.unwrap_or(if spin {
        ExchangeMode::Push
    } else {
        ExchangeMode::Kernels
    }));
    o.overlap = Some(o.overlap.unwrap_or(!spin));
}

/// The barrier of transport=p2p: the one asked for, else spin (it needs native atomics between
/// every pair of GPUs; without them the default is events). Ranks sharing a device: events only
/// (the one-thread spin kernels of two ranks on one device may not run at the same time, and
/// the one that runs would then wait for the other forever).
fn choose_barrier(devices: &[usize], o: &CudaOptions) -> Result<BarrierKind, SimError> {
    if let Some((i, j, d)) = shared_device(devices) {
        return match o.barrier {
            Some(BarrierKind::Spin) => Err(SimError::Backend(format!(
                "barrier=spin: ranks {i} and {j} are both on CUDA device {d} (devices=), where \
                 their spin kernels could wait on each other forever; use barrier=events (the \
                 default there)"
            ))),
            _ => Ok(BarrierKind::Events),
        };
    }
    let missing = super::peer::first_pair_without_atomics(devices)
        .map_err(|e| SimError::Backend(format!("peer atomics query: {e}")))?;
    match (o.barrier, missing) {
        (Some(BarrierKind::Spin), Some((i, j))) => Err(SimError::Backend(format!(
            "barrier=spin: GPU {i} has no native atomics on GPU {j}'s memory; use barrier=events"
        ))),
        (Some(b), _) => Ok(b),
        (None, Some(_)) => Ok(BarrierKind::Events),
        (None, None) => Ok(BarrierKind::Spin),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn o(text: &str) -> CudaOptions {
        text.parse().expect("options")
    }

    fn msg<T: std::fmt::Debug>(r: Result<T, SimError>) -> String {
        r.err().map(|e| e.to_string()).unwrap_or_default()
    }

    #[test]
    fn ranks_sharing_a_device_are_found() {
        assert_eq!(shared_device(&[0, 1]), None);
        assert_eq!(shared_device(&[0, 0]), Some((0, 1, 0)));
        assert_eq!(shared_device(&[1, 0, 2, 0]), Some((1, 3, 0)));
    }

    /// Ranks on one device (`devices=`): NCCL and the spin barrier are clear errors, the events
    /// barrier is the default; these decisions need no GPU.
    #[test]
    fn ranks_sharing_a_device_run_p2p_with_the_events_barrier_only() {
        let e = msg(choose_transport(&[0, 0], &o("transport=nccl,devices=0:0")));
        assert!(
            e.contains("NCCL refuses two ranks on one device") && e.contains("transport=p2p"),
            "{e}"
        );
        // barrier= with NCCL is named first (the option pair is wrong on any devices).
        let e = msg(choose_transport(
            &[0, 0],
            &o("transport=nccl,barrier=events"),
        ));
        assert!(e.contains("barrier= applies to transport=p2p only"), "{e}");
        let e = msg(choose_barrier(&[0, 0], &o("barrier=spin")));
        assert!(
            e.contains("ranks 0 and 1 are both on CUDA device 0") && e.contains("barrier=events"),
            "{e}"
        );
        assert_eq!(
            choose_barrier(&[0, 0], &o("")).ok(),
            Some(BarrierKind::Events)
        );
        assert_eq!(
            choose_barrier(&[1, 1], &o("barrier=events")).ok(),
            Some(BarrierKind::Events)
        );
        let many = [0; MAX_PEER_GPUS + 1];
        let e = msg(choose_transport(&many, &o("")));
        assert!(e.contains(&format!("at most {MAX_PEER_GPUS} GPUs")), "{e}");
    }

    /// `exchange=fused|push` run with transport=p2p and the spin barrier only; the others are
    /// clear errors that say what to use (decided without a GPU).
    #[test]
    fn the_fused_exchanges_need_p2p_with_the_spin_barrier() {
        let with = |text: &str, t: Transport, b: Option<BarrierKind>| {
            let mut o = o(text);
            o.transport = Some(t);
            o.barrier = b;
            check_exchange(&o)
        };
        for mode in ["fused", "push", "push_update", "list_push_update"] {
            let x = format!("exchange={mode}");
            assert!(with(&x, Transport::P2p, Some(BarrierKind::Spin)).is_ok());
            let e = msg(with(&x, Transport::P2p, Some(BarrierKind::Events)));
            assert!(
                e.contains(&format!("exchange={mode} takes the spin barrier"))
                    && e.contains("use exchange=kernels"),
                "{e}"
            );
            let e = msg(with(&x, Transport::Nccl, None));
            assert!(
                e.contains("needs transport=p2p") && e.contains("use exchange=kernels"),
                "{e}"
            );
        }
        for t in [Transport::P2p, Transport::Nccl] {
            assert!(with("", t, Some(BarrierKind::Events)).is_ok());
        }
        // push_update has no overlap on a second stream: overlap=on is refused, off allowed.
        let spin = Some(BarrierKind::Spin);
        for mode in ["push_update", "list_push_update"] {
            let e = msg(with(
                &format!("exchange={mode},overlap=on"),
                Transport::P2p,
                spin,
            ));
            assert!(
                e.contains(&format!("exchange={mode} sums")) && e.contains("leave overlap= out"),
                "{e}"
            );
            let off = format!("exchange={mode},overlap=off");
            assert!(with(&off, Transport::P2p, spin).is_ok());
        }
        assert!(with("exchange=push,overlap=on", Transport::P2p, spin).is_ok());
        // Without the overlap asked for, it resolves to off.
        let mut r = o("exchange=push_update");
        r.transport = Some(Transport::P2p);
        r.barrier = spin;
        resolve_exchange_defaults(&mut r);
        assert_eq!(
            (r.exchange, r.overlap),
            (Some(ExchangeMode::PushUpdate), Some(false))
        );
    }

    #[test]
    fn devices_name_one_present_device_per_rank() {
        let e = msg(rank_devices(2, &o("devices=0:0:0")));
        assert!(e.contains("names 3 device(s) for 2 GPU ranks"), "{e}");
        let found = crate::probe::device_count();
        let e = msg(rank_devices(2, &o(&format!("devices=0:{found}"))));
        assert!(
            e.contains(&format!(
                "CUDA device {found} asked, {found} CUDA device(s) found"
            )),
            "{e}"
        );
        if found == 0 {
            let e = msg(rank_devices(2, &o("")));
            assert!(e.contains("--gpus 2: 0 CUDA device(s) found"), "{e}");
        } else {
            assert_eq!(rank_devices(1, &o("devices=0")).ok(), Some(vec![0]));
        }
    }
}
