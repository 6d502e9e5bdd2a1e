//! One GPU of a multi-GPU run ([`GpuRank`]): the single-GPU backend on its particles, stepped by
//! the one step sequence with the exchange of shared blocks as its hook.

use super::barrier::HostBarrier;
use super::exchange::{ExchangeHooks, Exchanger, PeerExport};
use super::nccl::{Communicator, DataType, RedOp, UniqueId};
use super::plan::check_supported;
use crate::backend::{CudaBackend, Part};
use crate::contract::{CTL_NEED_REBUILD, CTL_WORDS};
use crate::error::err;
use crate::options::{BarrierKind, CudaOptions};
use crate::step::rigid::CHECK_WORDS;
use cudarc::driver::{CudaSlice, DevicePtr};
use rtmpm_physics::Particles;
use rtmpm_rigid::{BodyState, Exchange};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;
use std::sync::Arc;

fn nccl_err(e: String) -> SimError {
    SimError::Backend(e)
}

/// How a [`GpuRank`] gets its communicator.
pub enum CommSource {
    /// Join a new communicator: `ncclCommInitRank` (blocks until every rank joined).
    New {
        /// The id rank 0 made.
        id: UniqueId,
        /// This rank.
        rank: usize,
        /// Number of ranks.
        ranks: usize,
    },
    /// Keep the communicator of a previous rank object (rebalancing).
    Existing(Communicator),
    /// No communicator: transport=p2p (peer reads and barriers, [`GpuRank::connect`]).
    PeerToPeer,
}

/// One GPU of a multi-GPU run.
pub struct GpuRank {
    pub(crate) b: CudaBackend,
    pub(crate) x: Exchanger,
    /// Steps run without capture so far: NCCL connects lazily at a communicator's first
    /// collectives, which must not be captured (capture was invalidated on 2 H200s otherwise).
    eager_steps: u32,
    ctl_all: Option<CudaSlice<u32>>,
    state_all: Option<CudaSlice<f32>>,
    /// Rigid bodies: their states for the coming steps (the same on every GPU,
    /// [`GpuRank::set_body_states`]).
    body_states: Vec<BodyState>,
    /// Rigid bodies: the host copy that the last step's impulse sums go to.
    body_copy: Option<usize>,
    /// Rigid bodies in a run of several processes: the check of this process's world
    /// ([`GpuRank::set_body_check`]); the impulse sums are then summed across the processes.
    body_check: Option<[f64; CHECK_WORDS]>,
}

impl GpuRank {
    /// Upload one GPU's particles (`part.ids`: their original indices) and join the communicator.
    pub fn new(
        scene: &Scene,
        particles: &Particles,
        part: &Part,
        options: CudaOptions,
        shared_cap: usize,
        comm: CommSource,
    ) -> Result<GpuRank, SimError> {
        check_supported(scene, &options)?;
        // With G2P2G (the default) the exchange sums what the previous step's fused kernel (or
        // this step's P2G, after a rebuild) scattered into this step's grid: it is the step's hook
        // between P2G and the grid update either way (crate::step).
        let b = CudaBackend::new_part(scene, particles, part, options)?;
        b.stream
            .context()
            .bind_to_thread()
            .map_err(err("bind context"))?;
        let comm = match comm {
            CommSource::Existing(c) => Some(c),
            CommSource::New { id, rank, ranks } => {
                Some(Communicator::init(&id, rank, ranks).map_err(nccl_err)?)
            }
            CommSource::PeerToPeer => None,
        };
        let x = Exchanger::new(
            &b.stream,
            scene.n_cells(),
            comm,
            b.options.barrier.unwrap_or(BarrierKind::Spin),
            b.options.f64,
            // Resolved by the backend that made this rank (NCCL's defaults where it did not).
            b.options.overlap.unwrap_or(true),
            b.options.exchange.unwrap_or_default(),
        )?;
        let mut r = GpuRank {
            b,
            x,
            eager_steps: 0,
            ctl_all: None,
            state_all: None,
            body_states: Vec::new(),
            body_copy: None,
            body_check: None,
        };
        r.set_shared_capacity(shared_cap)?;
        Ok(r)
    }

    /// Give the communicator back (to build a new rank object on the same GPU).
    pub fn into_comm(mut self) -> Option<Communicator> {
        self.release_graph();
        self.x.take_comm()
    }

    /// Wait for the streams and destroy the captured graph. NCCL (2.26+) waits in
    /// `ncclCommDestroy` until every graph holding the communicator's work is destroyed, so the
    /// graph must go first (otherwise destroying the communicator never returns).
    fn release_graph(&mut self) {
        self.x.synchronize();
        let _ = self.b.stream.synchronize();
        self.b.clear_graphs();
    }

    /// Shared blocks the reduction holds.
    pub fn shared_capacity(&self) -> usize {
        self.x.sc.cap as usize
    }

    /// (Re)allocate the reduction for `cap` shared blocks (drops the captured graph).
    pub fn set_shared_capacity(&mut self, cap: usize) -> Result<(), SimError> {
        let s = self.b.stream.clone();
        s.synchronize().map_err(err("sync"))?;
        self.x.set_capacity(&s, cap)?;
        self.b.clear_graphs();
        // Redo the shared list at the next step with the new capacity.
        self.b.set_ctl_word(CTL_NEED_REBUILD, 1)
    }

    /// Time the reduction with events (and run without the graph) from now on.
    pub fn enable_timing(&mut self) -> Result<(), SimError> {
        let ctx = self.b.stream.context().clone();
        let ev = || {
            ctx.new_event(Some(cudarc::driver::sys::CUevent_flags::CU_EVENT_DEFAULT))
                .map_err(err("event"))
        };
        self.x.timing = Some((ev()?, ev()?));
        Ok(())
    }

    /// Stop timing the reduction.
    pub fn disable_timing(&mut self) {
        self.x.timing = None;
    }

    /// Milliseconds of the last step's reduction (pack, sum, unpack; synchronises).
    pub fn last_reduce_ms(&self) -> Result<f64, SimError> {
        self.x.last_reduce_ms()
    }

    /// transport=p2p: what the other GPUs need of this one, in a run of `gpus` GPUs
    /// (synchronises, so that the buffers exist before anyone reads them).
    pub fn peer_export(&mut self, gpus: usize) -> Result<PeerExport, SimError> {
        let s = self.b.stream.clone();
        s.synchronize().map_err(err("sync"))?;
        self.x.peer_export(&s, gpus)
    }

    /// transport=p2p: enable peer access to every other GPU and take their buffers and barrier
    /// (again after any GPU reallocated its buffers; drops the captured graph).
    pub fn connect(
        &mut self,
        me: usize,
        all: &[PeerExport],
        host: Arc<HostBarrier>,
    ) -> Result<(), SimError> {
        self.release_graph();
        let s = self.b.stream.clone();
        s.context().bind_to_thread().map_err(err("bind"))?;
        let own = s.context().ordinal();
        for (j, e) in all.iter().enumerate() {
            // Ranks on this GPU (`devices=`) share its context: nothing to enable.
            if j != me && e.device != own {
                super::peer::enable(e.ctx)
                    .map_err(|m| SimError::Backend(format!("GPU {me} -> GPU {j}: {m}")))?;
            }
        }
        // The peers read this GPU's pool allocations (mask, pack buffer, barrier counter).
        let mut peers: Vec<usize> = all
            .iter()
            .filter(|e| e.device != own)
            .map(|e| e.device)
            .collect();
        peers.sort_unstable();
        peers.dedup();
        super::peer::grant_pool_access(own, &peers).map_err(SimError::Backend)?;
        self.x.connect(&s, me, all, host)
    }

    /// Enqueue one step (replaying the captured graph while dt stays the same). With rigid
    /// bodies: the states last given ([`GpuRank::set_body_states`]) go up before it, and its
    /// impulse sums are copied to the host after it ([`GpuRank::body_sums`]); with a check
    /// given ([`GpuRank::set_body_check`]) they are first summed over every rank of the
    /// communicator, check included (an NCCL all-reduce on the stream, after the step's graph).
    pub fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.b
            .stream
            .context()
            .bind_to_thread()
            .map_err(err("bind"))?;
        self.b.upload_params(dt, t)?;
        if let Some(link) = self.b.body_link.as_mut() {
            if self.body_states.len() != self.b.ctx.n_bodies as usize {
                return Err(SimError::Backend(format!(
                    "GPU rank: {} rigid-body states for {} bodies",
                    self.body_states.len(),
                    self.b.ctx.n_bodies
                )));
            }
            link.upload(&self.b.module, &self.b.stream, &self.body_states)?;
        }
        // Events barrier: no graph (the waits must bind to the peers' records of this step).
        let graph =
            !self.x.uses_event_barrier() && self.x.timing.is_none() && self.eager_steps >= 2;
        if !graph {
            self.eager_steps += 1;
        }
        let GpuRank { b, x, .. } = self;
        b.run_step(dt, &mut ExchangeHooks(x), graph)?;
        if let Some(link) = self.b.body_link.as_mut() {
            if let Some(words) = &self.body_check {
                let s = &self.b.stream;
                link.write_check(s, words)?;
                let (_, sums, _) = link.ctx_fields(s);
                // SAFETY: the impulse buffer holds `link.words()` f64 on this rank's GPU and
                // lives as long as the rank; in place, enqueued on the rank's stream after the
                // step (every rank enqueues it at the same point: one per step).
                unsafe {
                    self.x.comm()?.all_reduce(
                        sums,
                        sums,
                        link.words(),
                        DataType::F64,
                        RedOp::Sum,
                        s.cu_stream(),
                    )
                }
                .map_err(nccl_err)?;
            }
            self.body_copy = Some(link.queue_sums(&self.b.stream)?);
        }
        Ok(())
    }

    /// Rigid bodies in a run of several processes (one rank per process): from the next step
    /// on, `words` (the check of this process's rapier world, `crate::multi::rigid`) go after
    /// the step's impulse sums, and sums and check are summed over every rank of the
    /// communicator before they are copied to the host: every rank's copy then holds the
    /// whole run's sums ([`GpuRank::body_copy_words`]). Not for several GPUs of one process,
    /// whose host adds the ranks' sums itself.
    pub fn set_body_check(&mut self, words: [f64; CHECK_WORDS]) {
        self.body_check = Some(words);
    }

    /// Rigid bodies: their states at the time of the coming steps.
    pub fn set_body_states(&mut self, states: &[BodyState]) {
        self.body_states.clear();
        self.body_states.extend_from_slice(states);
    }

    /// Rigid bodies: the host copy that the last step's impulse sums went to (`None` without
    /// bodies, or before the first step).
    pub fn body_copy(&self) -> Option<usize> {
        self.body_copy
    }

    /// Rigid bodies: the impulse sums of this GPU's nodes in host copy `k` (waits for them).
    pub fn body_sums(&self, k: usize) -> Result<Vec<Exchange>, SimError> {
        match &self.b.body_link {
            Some(link) => link.sums(k),
            None => Ok(Vec::new()),
        }
    }

    /// Rigid bodies: host copy `k` whole (waits for it): the impulse sums' slots, then the
    /// check (`crate::step::rigid::BodyLink::copy`); empty without bodies.
    pub fn body_copy_words(&self, k: usize) -> Result<Vec<f64>, SimError> {
        match &self.b.body_link {
            Some(link) => Ok(link.copy(k)?.to_vec()),
            None => Ok(Vec::new()),
        }
    }

    /// This GPU's control words (synchronises).
    pub fn ctl(&mut self) -> Result<Vec<u32>, SimError> {
        self.b.ctl_words()
    }

    /// Every rank's control words, through an NCCL all-gather (collective; synchronises).
    pub fn gather_ctl(&mut self) -> Result<Vec<Vec<u32>>, SimError> {
        let ranks = self.x.comm()?.ranks;
        let s = self.b.stream.clone();
        if self.ctl_all.is_none() {
            self.ctl_all = Some(
                s.alloc_zeros::<u32>(ranks * CTL_WORDS)
                    .map_err(err("alloc"))?,
            );
        }
        let all = self.ctl_all.as_ref().map_or(0, |a| a.device_ptr(&s).0);
        // SAFETY: ctl holds CTL_WORDS words, all ranks * CTL_WORDS.
        unsafe {
            self.x
                .comm()?
                .all_gather(self.b.ctx.ctl, all, CTL_WORDS, DataType::U32, s.cu_stream())
        }
        .map_err(nccl_err)?;
        let host = match &self.ctl_all {
            Some(a) => s.clone_dtoh(a).map_err(err("read control words"))?,
            None => Vec::new(),
        };
        Ok(host.chunks(CTL_WORDS).map(<[u32]>::to_vec).collect())
    }

    /// Every rank's particle state arrays (all ranks must have the same capacity), through an
    /// NCCL all-gather (collective; synchronises).
    pub fn gather_state(&mut self) -> Result<Vec<f32>, SimError> {
        let per = self.b.state_layout().words() * self.b.ctx.cap as usize;
        let ranks = self.x.comm()?.ranks;
        let s = self.b.stream.clone();
        if self.state_all.is_none() {
            self.state_all = Some(s.alloc_zeros::<f32>(ranks * per).map_err(err("alloc"))?);
        }
        let all = self.state_all.as_ref().map_or(0, |a| a.device_ptr(&s).0);
        // SAFETY: state holds words * cap floats, all ranks times that.
        unsafe {
            self.x
                .comm()?
                .all_gather(self.b.ctx.state, all, per, DataType::F32, s.cu_stream())
        }
        .map_err(nccl_err)?;
        match &self.state_all {
            Some(a) => s.clone_dtoh(a).map_err(err("read particles")),
            None => Ok(Vec::new()),
        }
    }
}

impl Drop for GpuRank {
    fn drop(&mut self) {
        // The graph before the communicator (the fields drop after this).
        self.release_graph();
    }
}
