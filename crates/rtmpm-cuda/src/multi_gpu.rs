//! Several GPUs, seed 000's "job splitting by particles": particles are assigned to GPUs in
//! spatially coherent slabs ([`crate::partition`]); every GPU runs the single-GPU pipeline on its
//! own particles with its own block list; after P2G the grid blocks present on several GPUs are
//! summed across GPUs ([`crate::reduce_shared`]: NCCL all-reduce, or, between the GPUs of one
//! process with peer access, peer reads inside kernels after an inter-GPU barrier,
//! [`crate::barrier`]), then every GPU runs the grid update and G2P on its own particles.
//!
//! One step on one GPU, all on the device, no host synchronisation (captured in a CUDA graph):
//!
//! ```text
//! compute stream: rebuild (if this GPU's free zone was left) -> occupancy mask
//!                 -> NCCL all-reduce of the masks (+ "someone rebuilt" flag)
//!                 -> shared-block list and boundary gblocks (only when someone rebuilt)
//!                 -> P2G of the boundary gblocks --event--+
//!                 -> P2G of the other gblocks             |   comm stream: pack shared blocks
//!                                                         |   -> NCCL all-reduce (sum)
//!                 <--------------------------------event--+   -> unpack
//!                 -> grid update -> G2P
//! ```
//!
//! The inter-GPU synchronisation of a step is the all-reduce itself (NCCL's own device-side
//! synchronisation); the reduction overlaps the P2G of the interior gblocks.
//!
//! transport=p2p (one process, every pair of GPUs with peer access): the same step with the two
//! NCCL all-reduces replaced by a barrier ([`crate::barrier`], spin kernel or events) and a kernel
//! reading the other GPUs' buffers through peer pointers:
//!
//! ```text
//! compute stream: rebuild -> occupancy mask -> BARRIER 1 -> sum of every GPU's mask (peer reads)
//!                 -> shared-block list -> P2G of the boundary gblocks --event--+
//!                 -> P2G of the other gblocks                    comm stream: pack
//!                                                                -> BARRIER 2
//!                 <--------------------------------------event-- -> sum of every GPU's pack into
//!                 -> grid update -> G2P                              this GPU's grid (peer reads)
//! ```
//!
//! Why no buffer is overwritten while a peer reads it (so no double buffering is needed): GPU i
//! rewrites its pack buffer at step n+1 only after barrier 1 of step n+1, which GPU j reaches only
//! after its step-n sum (stream order: sum -> grid update -> G2P -> rebuild -> mask -> barrier 1);
//! GPU i rewrites its mask at step n+1 only after barrier 2 of step n, which GPU j reaches only
//! after its step-n sum of the masks (stream order: counts -> list -> P2G -> pack -> barrier 2).
//! Two synchronisations per step, like the two all-reduces of NCCL: the masks must be summed
//! before the shared list can be made, and a GPU's blocks change at its own rebuild, which the
//! others cannot foresee.//!
//! Two ways to run: [`MultiGpuBackend`], one process driving N GPUs (one thread per GPU), and
//! [`NcclRankBackend`], one process per GPU (several machines), meeting through a
//! [`crate::rendezvous::Rendezvous`].
//!
//! Sizes: the all-reduce moves a host-chosen number of shared blocks (`cap`, from the partition
//! with headroom, at most every block of the domain); the device checks the real count at every
//! change and stops with a clear error if it exceeds `cap`. At the end of each frame the host
//! grows `cap` when the count passed half of it, and re-partitions the particles (rebalancing)
//! when the shared blocks have grown well beyond those of the last partition (particles drifted).

use crate::backend::{CudaBackend, Part, err, resize_particles, scatter_state};
use crate::barrier::{HostBarrier, SpinBarrier, TIMEOUT, enqueue_spin, wait_events};
use crate::layout::*;
use crate::nccl::{Communicator, DataType, RedOp, UniqueId};
use crate::partition::{Partition, shared_blocks, slabs};
use crate::reduce_shared::{
    MAX_PEER_GPUS, PeerCtx, SharedCtx, dense_dims, enqueue_copy, enqueue_counts_peers,
    enqueue_list, enqueue_mask, enqueue_sum_peers,
};
use crate::{BarrierKind, CudaOptions, Transport};
use cudarc::driver::{CudaEvent, CudaGraph, CudaSlice, CudaStream, DevicePtr};
use rtmpm_core::sim::{Backend, BadParticle, BadReason, SimError};
use rtmpm_core::{Particles, Scene};
use std::sync::{Arc, mpsc};

fn nccl_err(e: String) -> SimError {
    SimError::Backend(e)
}

/// The particles of `idx`, in that order.
pub fn subset(p: &Particles, idx: &[u32]) -> Particles {
    let pick = |i: &u32| *i as usize;
    Particles {
        x: idx.iter().map(|i| p.x[pick(i)]).collect(),
        v: idx.iter().map(|i| p.v[pick(i)]).collect(),
        c: idx.iter().map(|i| p.c[pick(i)]).collect(),
        f: idx.iter().map(|i| p.f[pick(i)]).collect(),
        plastic: idx.iter().map(|i| p.plastic[pick(i)]).collect(),
        mass: idx.iter().map(|i| p.mass[pick(i)]).collect(),
        vol0: idx.iter().map(|i| p.vol0[pick(i)]).collect(),
        material: idx.iter().map(|i| p.material[pick(i)]).collect(),
    }
}

/// Shared-block capacity for a partition: twice the shared blocks with a margin, at most every
/// block of the domain (which can never overflow).
fn shared_capacity(
    scene: &Scene,
    p: &Particles,
    part: &Partition,
    o: &CudaOptions,
) -> (usize, usize) {
    let d = dense_count(scene);
    let s = shared_blocks(scene, &p.x, part);
    let cap = o.shared_capacity.unwrap_or(2 * s + 1024).clamp(1, d);
    (cap, s)
}

fn dense_count(scene: &Scene) -> usize {
    dense_dims(scene.n_cells())
        .iter()
        .map(|&x| x as usize)
        .product()
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

/// What a GPU shows the others for transport=p2p (pointers valid on every GPU through peer
/// access, handles as integers so that they cross threads).
#[derive(Clone, Copy, Debug)]
pub struct PeerExport {
    device: usize,
    ctx: usize,
    mask: u64,
    buf: u64,
    count: u64,
    events: [usize; 2],
}

/// transport=p2p: this GPU's barrier resources and its view of the other GPUs.
struct P2pRank {
    kind: BarrierKind,
    /// Spin: this GPU's barrier calls so far.
    calls: CudaSlice<u64>,
    /// Spin: the arrival counter (GPU 0's is the one every GPU uses).
    count: CudaSlice<u64>,
    /// Events: recorded at barrier 1 (masks) and barrier 2 (packed blocks).
    events: [CudaEvent; 2],
    /// Set by [`GpuRank::connect`].
    pc: PeerCtx,
    spin: SpinBarrier,
    peer_events: [Vec<usize>; 2],
    host: Option<Arc<HostBarrier>>,
}

/// One GPU of a multi-GPU run: the single-GPU backend on its particles, its communicator, the
/// shared-block reduction buffers and the second stream the reduction runs on.
pub struct GpuRank {
    pub(crate) b: CudaBackend,
    /// Always `Some` (taken by [`GpuRank::into_comm`] only).
    comm: Option<Communicator>,
    comm_stream: Arc<CudaStream>,
    sc: SharedCtx,
    _mask: CudaSlice<u8>,
    _counts: CudaSlice<u8>,
    _chunk: CudaSlice<u32>,
    shared_bufs: (CudaSlice<u32>, CudaSlice<u8>),
    p2g_done: CudaEvent,
    reduced: CudaEvent,
    graph: Option<(CudaGraph, f32)>,
    /// Steps run without capture so far: NCCL connects lazily at a communicator's first
    /// collectives, which must not be captured (capture was invalidated on 2 H200s otherwise).
    eager_steps: u32,
    /// Events around the reduction on the comm stream (timing mode: no graph).
    timing: Option<(CudaEvent, CudaEvent)>,
    ctl_all: Option<CudaSlice<u32>>,
    state_all: Option<CudaSlice<f32>>,
    real: DataType,
    /// transport=p2p (`None`: NCCL).
    p2p: Option<P2pRank>,
}

/// What several GPUs support, checked before any GPU work: the warp P2G, MLS-MPM and single
/// precision (clear errors otherwise).
pub fn check_supported(scene: &Scene, options: &CudaOptions) -> Result<(), SimError> {
    if options.p2g != crate::P2gMode::Warp {
        return Err(SimError::Backend(
            "several GPUs need the warp P2G (p2g=warp)".into(),
        ));
    }
    if scene.solver.transfer != rtmpm_core::transfer::Transfer::Mls {
        return Err(SimError::Backend(format!(
            "several GPUs run MLS-MPM only: the scene's [solver] transfer is \"{}\" (its \
             per-node force and FLIP velocity are not summed across GPUs yet); run it on one \
             GPU (--gpus 1) or on the CPU",
            scene.solver.transfer.name()
        )));
    }
    if options.f64 || scene.precision == rtmpm_core::scene::Precision::F64 {
        return Err(SimError::Backend(
            "several GPUs run in single precision only (the particle exchange at \
             rebalancing moves f32 state); run f64 scenes on one GPU (--gpus 1)"
                .into(),
        ));
    }
    Ok(())
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
        let real = if options.f64 {
            DataType::F64
        } else {
            DataType::F32
        };
        // G2P2G is single-GPU: the shared-block reduction needs P2G as a step of its own.
        let options = CudaOptions {
            g2p2g: false,
            ..options
        };
        let b = CudaBackend::new_part(scene, particles, part, options)?;
        let ctx = b.stream.context().clone();
        ctx.bind_to_thread().map_err(err("bind context"))?;
        let comm = match comm {
            CommSource::Existing(c) => Some(c),
            CommSource::New { id, rank, ranks } => {
                Some(Communicator::init(&id, rank, ranks).map_err(nccl_err)?)
            }
            CommSource::PeerToPeer => None,
        };
        let comm_stream = ctx.new_stream().map_err(err("comm stream"))?;
        let s = &b.stream;
        let dims = dense_dims(scene.n_cells());
        let d = dims.iter().map(|&x| x as usize).product::<usize>();
        let mask = s.alloc_zeros::<u8>(d + 1).map_err(err("alloc mask"))?;
        let counts = s.alloc_zeros::<u8>(d + 1).map_err(err("alloc counts"))?;
        let chunk = s
            .alloc_zeros::<u32>(d.div_ceil(1024).max(1))
            .map_err(err("alloc chunks"))?;
        let sc = SharedCtx {
            mask: mask.device_ptr(s).0,
            counts: counts.device_ptr(s).0,
            chunk: chunk.device_ptr(s).0,
            dims,
            d: d as u32,
            ..Default::default()
        };
        let ev = || ctx.new_event(None).map_err(err("event"));
        let (p2g_done, reduced) = (ev()?, ev()?);
        let p2p = match comm {
            Some(_) => None,
            None => Some(P2pRank {
                kind: b.options.barrier.unwrap_or(BarrierKind::Spin),
                calls: s.alloc_zeros::<u64>(1).map_err(err("alloc barrier"))?,
                count: s.alloc_zeros::<u64>(1).map_err(err("alloc barrier"))?,
                events: [ev()?, ev()?],
                pc: PeerCtx::default(),
                spin: SpinBarrier::default(),
                peer_events: [Vec::new(), Vec::new()],
                host: None,
            }),
        };
        let placeholder = (
            s.alloc_zeros::<u32>(1).map_err(err("alloc"))?,
            s.alloc_zeros::<u8>(1).map_err(err("alloc"))?,
        );
        let mut r = GpuRank {
            b,
            comm,
            comm_stream,
            sc,
            _mask: mask,
            _counts: counts,
            _chunk: chunk,
            shared_bufs: placeholder,
            p2g_done,
            reduced,
            graph: None,
            eager_steps: 0,
            timing: None,
            ctl_all: None,
            state_all: None,
            real,
            p2p,
        };
        r.set_shared_capacity(shared_cap)?;
        Ok(r)
    }

    /// Give the communicator back (to build a new rank object on the same GPU).
    pub fn into_comm(mut self) -> Option<Communicator> {
        self.release_graph();
        self.comm.take()
    }

    /// Wait for the streams and destroy the captured graph. NCCL (2.26+) waits in
    /// `ncclCommDestroy` until every graph holding the communicator's work is destroyed, so the
    /// graph must go first (otherwise destroying the communicator never returns).
    fn release_graph(&mut self) {
        let _ = self.comm_stream.synchronize();
        let _ = self.b.stream.synchronize();
        self.graph = None;
    }

    fn comm(&self) -> Result<&Communicator, SimError> {
        self.comm
            .as_ref()
            .ok_or_else(|| SimError::Backend("GPU rank without a communicator".into()))
    }

    /// Shared blocks the reduction holds.
    pub fn shared_capacity(&self) -> usize {
        self.sc.cap as usize
    }

    /// (Re)allocate the reduction for `cap` shared blocks (drops the captured graph).
    pub fn set_shared_capacity(&mut self, cap: usize) -> Result<(), SimError> {
        let s = self.b.stream.clone();
        s.synchronize().map_err(err("sync"))?;
        let cap = cap.max(1);
        let rb = if self.real == DataType::F64 { 8 } else { 4 };
        let local = s
            .alloc_zeros::<u32>(cap)
            .map_err(err("alloc shared list"))?;
        let buf = s
            .alloc_zeros::<u8>(cap * 256 * rb)
            .map_err(err("alloc shared buffer"))?;
        self.sc.shared_local = local.device_ptr(&s).0;
        self.sc.buf = buf.device_ptr(&s).0;
        self.sc.cap = cap as u32;
        self.shared_bufs = (local, buf);
        self.graph = None;
        // Redo the shared list at the next step with the new capacity.
        self.b.set_ctl_word(CTL_NEED_REBUILD, 1)?;
        Ok(())
    }

    /// Time the reduction with events (and run without the graph) from now on.
    pub fn enable_timing(&mut self) -> Result<(), SimError> {
        let ctx = self.b.stream.context().clone();
        let ev = || {
            ctx.new_event(Some(cudarc::driver::sys::CUevent_flags::CU_EVENT_DEFAULT))
                .map_err(err("event"))
        };
        self.timing = Some((ev()?, ev()?));
        Ok(())
    }

    /// transport=p2p: what the other GPUs need of this one (synchronises, so that the buffers
    /// exist before anyone reads them).
    pub fn peer_export(&self) -> Result<PeerExport, SimError> {
        let p = self
            .p2p
            .as_ref()
            .ok_or_else(|| SimError::Backend("not a transport=p2p rank".into()))?;
        let s = &self.b.stream;
        s.synchronize().map_err(err("sync"))?;
        Ok(PeerExport {
            device: self.b.stream.context().ordinal(),
            ctx: s.context().cu_ctx() as usize,
            mask: self.sc.mask,
            buf: self.sc.buf,
            count: p.count.device_ptr(s).0,
            events: [
                p.events[0].cu_event() as usize,
                p.events[1].cu_event() as usize,
            ],
        })
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
        let n = all.len();
        if n > MAX_PEER_GPUS {
            return Err(SimError::Backend(format!(
                "transport=p2p handles at most {MAX_PEER_GPUS} GPUs; use transport=nccl"
            )));
        }
        for (j, e) in all.iter().enumerate() {
            if j != me {
                crate::peer::enable(e.ctx)
                    .map_err(|m| SimError::Backend(format!("GPU {me} -> GPU {j}: {m}")))?;
            }
        }
        // The peers read this GPU's pool allocations (mask, pack buffer, barrier counter).
        let peers: Vec<usize> = all
            .iter()
            .filter(|e| e.device != self.b.stream.context().ordinal())
            .map(|e| e.device)
            .collect();
        crate::peer::grant_pool_access(self.b.stream.context().ordinal(), &peers)
            .map_err(SimError::Backend)?;
        let p = self
            .p2p
            .as_mut()
            .ok_or_else(|| SimError::Backend("not a transport=p2p rank".into()))?;
        let mut pc = PeerCtx {
            n: n as u32,
            me: me as u32,
            ..Default::default()
        };
        for (j, e) in all.iter().enumerate() {
            pc.mask[j] = e.mask;
            pc.buf[j] = e.buf;
        }
        p.pc = pc;
        p.spin = SpinBarrier {
            count: all[0].count,
            calls: p.calls.device_ptr(&s).0,
            timeout_ns: TIMEOUT.as_nanos() as u64,
            n: n as u32,
            pad: 0,
        };
        for k in 0..2 {
            p.peer_events[k] = all
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != me)
                .map(|(_, e)| e.events[k])
                .collect();
        }
        p.host = Some(host);
        Ok(())
    }

    /// transport=p2p: enqueue inter-GPU barrier `k` (0: masks, 1: packed blocks) on `st`.
    fn barrier(&self, p: &P2pRank, k: usize, st: &CudaStream) -> Result<(), SimError> {
        match p.kind {
            BarrierKind::Spin => {
                enqueue_spin(&self.b.kernels, st, &self.b.ctx, &p.spin).map_err(err("barrier"))
            }
            BarrierKind::Events => {
                p.events[k].record(st).map_err(err("event"))?;
                let host = p
                    .host
                    .as_ref()
                    .ok_or_else(|| SimError::Backend("GPU rank not connected".into()))?;
                host.wait(TIMEOUT).map_err(SimError::Backend)?;
                wait_events(st, &p.peer_events[k]).map_err(err("wait peer events"))
            }
        }
    }

    /// Milliseconds of the last step's reduction (pack, all-reduce, unpack; synchronises).
    pub fn last_reduce_ms(&self) -> Result<f64, SimError> {
        match &self.timing {
            Some((a, b)) => Ok(a.elapsed_ms(b).map_err(err("elapsed"))? as f64),
            None => Ok(0.0),
        }
    }

    fn enqueue(&self) -> Result<(), SimError> {
        let (k, s, c, sc) = (&self.b.kernels, &self.b.stream, &self.b.ctx, &self.sc);
        let t = &self.comm_stream;
        let mode = self.b.options.p2g;
        crate::rebuild::enqueue(k, s, c).map_err(err("rebuild"))?;
        enqueue_mask(k, s, c, sc).map_err(err("mask"))?;
        if let Some(p) = &self.p2p {
            self.barrier(p, 0, s)?;
            enqueue_counts_peers(k, s, c, sc, &p.pc).map_err(err("mask sum"))?;
        } else {
            // SAFETY: mask and counts hold d + 1 bytes on this GPU and live as long as self.
            unsafe {
                self.comm()?.all_reduce(
                    sc.mask,
                    sc.counts,
                    sc.d as usize + 1,
                    DataType::U8,
                    RedOp::Sum,
                    s.cu_stream(),
                )
            }
            .map_err(nccl_err)?;
        }
        enqueue_list(k, s, c, sc).map_err(err("shared list"))?;
        // Overlap off (ablation): all of P2G, then the reduction.
        let overlap = self.b.options.overlap;
        crate::p2g::enqueue_scatter(k, s, c, mode, if overlap { 1 } else { 0 })
            .map_err(err("p2g boundary"))?;
        self.p2g_done.record(s).map_err(err("event"))?;
        t.wait(&self.p2g_done).map_err(err("wait"))?;
        if let Some((a, _)) = &self.timing {
            a.record(t).map_err(err("event"))?;
        }
        enqueue_copy(k, t, c, sc, true).map_err(err("pack"))?;
        if let Some(p) = &self.p2p {
            self.barrier(p, 1, t)?;
            enqueue_sum_peers(k, t, c, sc, &p.pc).map_err(err("peer sum"))?;
        } else {
            // SAFETY: buf holds cap * 256 reals on this GPU and lives as long as self.
            unsafe {
                self.comm()?.all_reduce(
                    sc.buf,
                    sc.buf,
                    sc.cap as usize * 256,
                    self.real,
                    RedOp::Sum,
                    t.cu_stream(),
                )
            }
            .map_err(nccl_err)?;
            enqueue_copy(k, t, c, sc, false).map_err(err("unpack"))?;
        }
        if let Some((_, b)) = &self.timing {
            b.record(t).map_err(err("event"))?;
        }
        self.reduced.record(t).map_err(err("event"))?;
        if overlap {
            crate::p2g::enqueue_scatter(k, s, c, mode, 2).map_err(err("p2g interior"))?;
        }
        s.wait(&self.reduced).map_err(err("wait"))?;
        crate::grid_update::enqueue(k, s, c).map_err(err("grid update"))?;
        // No G2P2G on several GPUs (GpuRank::new), so no fluid variant either.
        crate::g2p::enqueue(k, s, c, false).map_err(err("g2p"))?;
        Ok(())
    }

    /// Enqueue one step (replaying the captured graph while dt stays the same).
    pub fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.b
            .stream
            .context()
            .bind_to_thread()
            .map_err(err("bind"))?;
        self.b.upload_params(dt, t)?;
        // Events barrier: no graph (the waits must bind to the peers' records of this step).
        let events = matches!(&self.p2p, Some(p) if p.kind == BarrierKind::Events);
        if !self.b.options.graph || events || self.timing.is_some() || self.eager_steps < 2 {
            self.eager_steps += 1;
            return self.enqueue();
        }
        if let Some((g, gdt)) = &self.graph
            && *gdt == dt
        {
            return g.launch().map_err(err("graph launch"));
        }
        use cudarc::driver::sys::{CUgraphInstantiate_flags, CUstreamCaptureMode};
        self.graph = None;
        let s = self.b.stream.clone();
        s.begin_capture(CUstreamCaptureMode::CU_STREAM_CAPTURE_MODE_THREAD_LOCAL)
            .map_err(err("begin capture"))?;
        let r = self.enqueue();
        let g = s
            .end_capture(CUgraphInstantiate_flags(0))
            .map_err(err("end capture"))?;
        r?;
        let g = g.ok_or_else(|| SimError::Backend("CUDA: empty graph".into()))?;
        g.launch().map_err(err("graph launch"))?;
        self.graph = Some((g, dt));
        Ok(())
    }

    /// This GPU's control words (synchronises).
    pub fn ctl(&mut self) -> Result<Vec<u32>, SimError> {
        self.b.ctl_words()
    }

    /// Every rank's control words, through an NCCL all-gather (collective; synchronises).
    pub fn gather_ctl(&mut self) -> Result<Vec<Vec<u32>>, SimError> {
        let ranks = self.comm()?.ranks;
        let s = self.b.stream.clone();
        if self.ctl_all.is_none() {
            self.ctl_all = Some(
                s.alloc_zeros::<u32>(ranks * CTL_WORDS)
                    .map_err(err("alloc"))?,
            );
        }
        let all = self
            .ctl_all
            .as_ref()
            .map(|a| a.device_ptr(&s).0)
            .unwrap_or(0);
        // SAFETY: ctl holds CTL_WORDS words, all ranks * CTL_WORDS.
        unsafe {
            self.comm()?
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
        let per = NFIELDS * self.b.ctx.cap as usize;
        let ranks = self.comm()?.ranks;
        let s = self.b.stream.clone();
        if self.state_all.is_none() {
            self.state_all = Some(s.alloc_zeros::<f32>(ranks * per).map_err(err("alloc"))?);
        }
        let all = self
            .state_all
            .as_ref()
            .map(|a| a.device_ptr(&s).0)
            .unwrap_or(0);
        // SAFETY: state holds NFIELDS * cap floats, all ranks times that.
        unsafe {
            self.comm()?
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

/// Combine the control words of every GPU: (max speed, first bad particle by original index).
/// Errors (capacity) of any GPU are reported.
fn combine(b: &CudaBackend, ctls: &[Vec<u32>]) -> Result<(f32, Option<BadParticle>), SimError> {
    let mut speed = 0f32;
    let mut bad: Option<BadParticle> = None;
    for c in ctls {
        b.error_check(c)?;
        speed = speed.max(f32::from_bits(c[CTL_MAX_SPEED]));
        let i = c[CTL_BAD_INDEX];
        if i != u32::MAX && bad.is_none_or(|b| (i as usize) < b.index) {
            bad = Some(BadParticle {
                index: i as usize,
                reason: if c[CTL_BAD_REASON] == 1 {
                    BadReason::NonFinite
                } else {
                    BadReason::TooFast
                },
            });
        }
    }
    Ok((speed, bad))
}

/// What to do at the end of a frame, from the shared-block count (the same on every GPU).
#[derive(Clone, Copy, Debug, PartialEq)]
struct FramePlan {
    grow_to: Option<usize>,
    rebalance: bool,
}

fn plan(
    shared: usize,
    cap: usize,
    d: usize,
    at_partition: usize,
    ranks: usize,
    o: &CudaOptions,
) -> FramePlan {
    let grow_to = (o.shared_capacity.is_none() && shared * 2 > cap && cap < d)
        .then(|| (2 * shared + 1024).min(d));
    let rebalance = ranks > 1 && o.rebalance && shared > 2 * at_partition + 256;
    FramePlan { grow_to, rebalance }
}

// ---------------------------------------------------------------------------------------------
// One process, N GPUs: one worker thread per GPU.

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
        let found = crate::device_count();
        if gpus < 1 || gpus > found {
            return Err(SimError::Backend(format!(
                "--gpus {gpus}: {found} CUDA device(s) found{}",
                if found == 0 {
                    format!(
                        " ({})",
                        crate::probe()
                            .err()
                            .map(|e| e.to_string())
                            .unwrap_or_default()
                    )
                } else {
                    String::new()
                }
            )));
        }
        let info = crate::probe().map_err(|e| SimError::Backend(e.to_string()))?;
        let (transport, why) = choose_transport(gpus, &options)?;
        let mut options = options;
        options.transport = Some(transport);
        if transport == Transport::P2p {
            options.barrier = Some(choose_barrier(gpus, &options)?);
        }
        let (id, what) = match transport {
            Transport::Nccl => {
                let nccl = crate::nccl::library().map_err(|e| {
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
            rank(r)?.timing = None;
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

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let states = self.all(|_, r| {
            let r = rank(r)?;
            Ok((r.b.read_state()?, r.b.len(), r.b.ctx.cap as usize))
        })?;
        *out = Particles::default();
        resize_particles(out, self.n);
        for (host, n, cap) in &states {
            scatter_state(host, *n, *cap, out)?;
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
    let missing = crate::peer::first_pair_without_access(gpus)
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
    let missing = crate::peer::first_pair_without_atomics(gpus)
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

// ---------------------------------------------------------------------------------------------
// One process per GPU (several machines).

/// This process's GPU in a run of several processes (one per GPU, any number of machines).
/// Every process runs the same driver loop; max speed, bad particles and particle read-back are
/// NCCL collectives, so every process calls them at the same points (they do: the same scene and
/// the same time steps everywhere).
pub struct NcclRankBackend {
    rank: Option<GpuRank>,
    scene: Scene,
    options: CudaOptions,
    me: usize,
    ranks: usize,
    device: usize,
    counts: Vec<usize>,
    n: usize,
    name: String,
    shared_cap: usize,
    shared_at_partition: usize,
    d: usize,
    /// Rebalances done so far.
    pub rebalances: u32,
}

impl NcclRankBackend {
    /// Join the run as rank `me` of `ranks` on CUDA device `device`; `particles` are all the
    /// particles of the scene (every process samples the same ones).
    pub fn new(
        scene: &Scene,
        particles: &Particles,
        me: usize,
        ranks: usize,
        device: usize,
        rendezvous: &crate::rendezvous::Rendezvous,
        options: CudaOptions,
    ) -> Result<NcclRankBackend, SimError> {
        check_supported(scene, &options)?;
        if me >= ranks {
            return Err(SimError::Backend(format!(
                "--nccl-rank {me} must be below --nccl-ranks {ranks}"
            )));
        }
        if options.transport == Some(Transport::P2p) || options.barrier.is_some() {
            return Err(SimError::Backend(
                "transport=p2p and barrier= need the GPUs in one process (--gpus N); runs of \
                 several processes use NCCL"
                    .into(),
            ));
        }
        let nccl = crate::nccl::library()
            .map_err(|e| SimError::Backend(format!("multi-process runs need NCCL: {e}")))?;
        let info = crate::probe_device(device)
            .map_err(|e| SimError::Backend(format!("rank {me}: CUDA device {device}: {e}")))?;
        let id = if me == 0 {
            Some(nccl.unique_id().map_err(nccl_err)?.to_bytes())
        } else {
            None
        };
        let id = rendezvous.exchange(me, ranks, id).map_err(nccl_err)?;
        let mut b = NcclRankBackend {
            rank: None,
            scene: scene.clone(),
            options,
            me,
            ranks,
            device,
            counts: Vec::new(),
            n: particles.len(),
            name: format!(
                "cuda rank {me}/{ranks} on device {device} ({}, NCCL {})",
                info.name, nccl.version
            ),
            shared_cap: 0,
            shared_at_partition: 0,
            d: dense_count(scene),
            rebalances: 0,
        };
        b.load(
            particles,
            CommSource::New {
                id: UniqueId::from_bytes(&id),
                rank: me,
                ranks,
            },
        )?;
        Ok(b)
    }

    /// Partition every particle (the same on every rank) and build this rank's share; every rank
    /// gets the capacity of the largest share, so that the state arrays can be all-gathered.
    fn load(&mut self, particles: &Particles, comm: CommSource) -> Result<(), SimError> {
        let part = slabs(&particles.x, self.ranks);
        let (cap, s) = shared_capacity(&self.scene, particles, &part, &self.options);
        self.shared_cap = cap.max(self.shared_cap.min(self.d));
        self.shared_at_partition = s;
        self.counts = part.parts.iter().map(Vec::len).collect();
        let ids = &part.parts[self.me];
        let p = Part {
            device: self.device,
            ids: Some(ids.clone()),
            capacity: part.max_len(),
        };
        self.rank = Some(GpuRank::new(
            &self.scene,
            &subset(particles, ids),
            &p,
            self.options.clone(),
            self.shared_cap,
            comm,
        )?);
        Ok(())
    }

    fn r(&mut self) -> Result<&mut GpuRank, SimError> {
        rank(&mut self.rank)
    }

    /// This process's rank.
    pub fn rank(&self) -> usize {
        self.me
    }
}

impl Backend for NcclRankBackend {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn num_particles(&self) -> usize {
        self.n
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.r()?.step(dt, t)
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let r = self.r()?;
        let c = r.gather_ctl()?;
        Ok(combine(&r.b, &c)?.0)
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let r = self.r()?;
        let c = r.gather_ctl()?;
        let (_, bad) = combine(&r.b, &c)?;
        let me = r.comm()?.rank;
        if c[me][CTL_BAD_INDEX] != u32::MAX {
            r.b.check()?;
        }
        Ok(bad)
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let counts = self.counts.clone();
        let n = self.n;
        let r = self.r()?;
        let cap = r.b.ctx.cap as usize;
        let all = r.gather_state()?;
        *out = Particles::default();
        resize_particles(out, n);
        let per = NFIELDS * cap;
        for (k, &count) in counts.iter().enumerate() {
            scatter_state(&all[k * per..(k + 1) * per], count, cap, out)?;
        }
        Ok(())
    }

    fn end_of_frame(&mut self) -> Result<(), SimError> {
        let c = self.r()?.ctl()?;
        let shared = c[CTL_SHARED] as usize;
        let p = plan(
            shared,
            self.shared_cap,
            self.d,
            self.shared_at_partition,
            self.ranks,
            &self.options,
        );
        if p.rebalance {
            let speed = f32::from_bits(c[CTL_MAX_SPEED]);
            let speed = self.max_speed()?.max(speed);
            let mut all = Particles::default();
            self.read_particles(&mut all)?;
            let old = self.rank.take();
            let comm = old
                .and_then(GpuRank::into_comm)
                .ok_or_else(|| SimError::Backend("no communicator".into()))?;
            self.load(&all, CommSource::Existing(comm))?;
            self.r()?.b.set_ctl_word(CTL_MAX_SPEED, speed.to_bits())?;
            self.rebalances += 1;
        } else if let Some(cap) = p.grow_to {
            self.shared_cap = cap;
            self.r()?.set_shared_capacity(cap)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsupported_scenes_are_clear_errors_before_any_gpu_work() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml");
        let scene = Scene::from_file(&path).expect("dam_break scene");
        let o = CudaOptions::default();
        assert!(check_supported(&scene, &o).is_ok());
        let msg = |r: Result<(), SimError>| r.err().map(|e| e.to_string()).unwrap_or_default();
        let shared = CudaOptions {
            p2g: crate::P2gMode::Shared,
            ..o.clone()
        };
        assert!(msg(check_supported(&scene, &shared)).contains("p2g=warp"));
        let f64 = CudaOptions {
            f64: true,
            ..o.clone()
        };
        assert!(msg(check_supported(&scene, &f64)).contains("single precision"));
        let mut gimp = scene.clone();
        gimp.solver.transfer = rtmpm_core::transfer::Transfer::Gimp;
        assert!(msg(check_supported(&gimp, &o)).contains("\"gimp\""));
        let mut double = scene;
        double.precision = rtmpm_core::scene::Precision::F64;
        assert!(msg(check_supported(&double, &o)).contains("--gpus 1"));
    }

    #[test]
    fn frame_plan_grows_the_reduction_and_rebalances_after_drift() {
        let o = CudaOptions::default();
        let p = plan(100, 1000, 5000, 100, 2, &o);
        assert_eq!(
            p,
            FramePlan {
                grow_to: None,
                rebalance: false
            }
        );
        let p = plan(600, 1000, 5000, 500, 2, &o);
        assert_eq!(p.grow_to, Some(2224));
        assert!(!p.rebalance);
        // Never beyond every block of the domain.
        assert_eq!(plan(600, 1000, 1500, 500, 2, &o).grow_to, Some(1500));
        assert_eq!(plan(1400, 1500, 1500, 500, 2, &o).grow_to, None);
        assert!(plan(1300, 3000, 5000, 500, 2, &o).rebalance);
        assert!(!plan(1300, 3000, 5000, 500, 1, &o).rebalance);
        let fixed = CudaOptions {
            shared_capacity: Some(1000),
            rebalance: false,
            ..o
        };
        assert_eq!(
            plan(900, 1000, 5000, 100, 2, &fixed),
            FramePlan {
                grow_to: None,
                rebalance: false
            }
        );
    }

    #[test]
    fn subset_picks_particles_in_order() {
        let mut p = Particles::default();
        for i in 0..5 {
            p.push(
                rtmpm_core::math::Vec3::splat(i as f32),
                rtmpm_core::math::Vec3::ZERO,
                i as f32,
                1.0,
                i,
                0.0,
            );
        }
        let s = subset(&p, &[4, 1]);
        assert_eq!(s.mass, vec![4.0, 1.0]);
        assert_eq!(s.material, vec![4, 1]);
    }
}
