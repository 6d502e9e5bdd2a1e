//! Several GPUs of one process ([`MultiGpuBackend`]): one worker thread per GPU, each owning its
//! CUDA context, streams, graph and (transport=nccl) NCCL communicator.

use super::barrier::HostBarrier;
use super::nccl::UniqueId;
use super::partition::slabs;
use super::plan::{check_supported, dense_count, plan, shared_capacity, subset};
use super::rank::{CommSource, GpuRank};
use super::reduce_shared::MAX_PEER_GPUS;
use crate::backend::Part;
use crate::backend::readback::{resize_particles, scatter_state};
use crate::contract::{CTL_MAX_SPEED, CTL_SHARED};
use crate::options::{BarrierKind, CudaOptions, Transport};
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
        let found = crate::probe::device_count();
        if gpus < 1 || gpus > found {
            return Err(SimError::Backend(format!(
                "--gpus {gpus}: {found} CUDA device(s) found{}",
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
            )));
        }
        let info = crate::probe::probe().map_err(|e| SimError::Backend(e.to_string()))?;
        let (transport, why) = choose_transport(gpus, &options)?;
        let mut options = options;
        options.transport = Some(transport);
        if transport == Transport::P2p {
            options.barrier = Some(choose_barrier(gpus, &options)?);
        }
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
            host: Arc::new(HostBarrier::new(gpus)),
            n: particles.len(),
            name: format!("cuda x{gpus} ({}, {what})", info.name),
            shared_cap: 0,
            shared_at_partition: 0,
            d: dense_count(scene),
            rebalances: 0,
            tool: None,
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
        match (self.transport, self.options.barrier) {
            (Transport::Nccl, _) => "pack + NCCL all-reduce + unpack",
            (Transport::P2p, Some(BarrierKind::Events)) => {
                "pack + events barrier + sum of peer reads"
            }
            (Transport::P2p, _) => "pack + spin barrier + sum of peer reads",
        }
    }

    /// transport=p2p: give every GPU the others' buffers and barrier (after any reallocation).
    fn connect(&self) -> Result<(), SimError> {
        if self.transport != Transport::P2p {
            return Ok(());
        }
        let all = Arc::new(self.all(|_, r| rank(r)?.peer_export())?);
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
        let part = slabs(&particles.x, ranks);
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
        self.all(move |i, slot| {
            let (p, ids) = &subsets[i];
            let part = Part {
                device: i,
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
            self.all(move |_, r| rank(r)?.step(dt, t))?;
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
        self.all(move |_, r| rank(r)?.step(dt, t))?;
        Ok(())
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let speed = self.all(|_, r| rank(r)?.b.max_speed())?;
        Ok(speed.into_iter().fold(0.0, f32::max))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let bad = self.all(|_, r| rank(r)?.b.check())?;
        Ok(bad.into_iter().flatten().min_by_key(|b| b.index))
    }

    /// Gravity on every GPU.
    fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) -> Result<(), SimError> {
        self.all(move |_, r| rank(r)?.b.set_gravity(gravity))?;
        self.scene.gravity = gravity;
        Ok(())
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

    fn end_of_frame(&mut self) -> Result<(), SimError> {
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

/// The transport of a run of `gpus` GPUs in one process, and why: the one asked for, else p2p
/// when every pair of GPUs has peer access (and there are at most [`MAX_PEER_GPUS`]), else NCCL.
fn choose_transport(gpus: usize, o: &CudaOptions) -> Result<(Transport, String), SimError> {
    let missing = super::peer::first_pair_without_access(gpus)
        .map_err(|e| SimError::Backend(format!("peer access query: {e}")))?;
    let chosen = match (o.transport, missing) {
        (Some(Transport::P2p), Some((i, j))) => {
            return Err(SimError::Backend(format!(
                "transport=p2p: GPU {i} has no peer access to GPU {j}'s memory; use \
                 transport=nccl (or leave transport= out)"
            )));
        }
        (Some(Transport::P2p), None) if gpus > MAX_PEER_GPUS => {
            return Err(SimError::Backend(format!(
                "transport=p2p handles at most {MAX_PEER_GPUS} GPUs; use transport=nccl"
            )));
        }
        (Some(t), _) => (t, "asked for".to_string()),
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

/// The barrier of transport=p2p: the one asked for, else spin (it needs native atomics between
/// every pair of GPUs; without them the default is events).
fn choose_barrier(gpus: usize, o: &CudaOptions) -> Result<BarrierKind, SimError> {
    let missing = super::peer::first_pair_without_atomics(gpus)
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
