//! The exchange of shared grid blocks, the one thing several GPUs add to the step: the hook that
//! [`crate::step`] calls between P2G and the grid update ([`Exchanger`] implements
//! [`Exchange`]). On each GPU:
//!
//! ```text
//! compute stream: rebuild -> occupancy mask -> [sum of the masks]  (after_rebuild)
//!                 -> shared-block list and boundary gblocks (only when a GPU rebuilt)
//!                 -> P2G of the boundary gblocks --event--+                           (start)
//!                 -> P2G of the other gblocks             |   comm stream: pack shared blocks
//!                 -> grid update, unshared pblocks        |   -> sum across GPUs -> unpack
//!                 <--------------------------------event--+                          (finish)
//!                 -> grid update, shared pblocks -> G2P (or G2P2G)
//! ```
//!
//! With G2P2G the P2G of a step was done by the previous step's fused kernel (one launch after a
//! rebuild), so only the grid update overlaps the sum. `overlap=off`: P2G, sum, grid update.
//! `exchange=push_update` uses no second stream: the push on the compute stream, then one grid
//! update kernel that updates the unshared pblocks, waits for the peers' pushes and sums and
//! updates the shared ones ([`Exchange::grid_update`]); `list_push_update` makes the shared list
//! after P2G, in one cooperative kernel with the push (nothing after the rebuild).
//!
//! The sums are NCCL all-reduces (transport=nccl), or (transport=p2p, one process) a barrier
//! ([`super::barrier`]) and a kernel reading the other GPUs' buffers through peer pointers.
//!
//! Why no buffer is overwritten while a peer reads it (so no double buffering is needed): GPU i
//! rewrites its pack buffer at step n+1 only after barrier 1 of step n+1, which GPU j reaches only
//! after its step-n sum (stream order: sum -> grid update -> G2P -> rebuild -> mask -> barrier 1);
//! GPU i rewrites its mask at step n+1 only after barrier 2 of step n, which GPU j reaches only
//! after its step-n sum of the masks (stream order: counts -> list -> P2G -> pack -> barrier 2).
//! Two synchronisations per step, like the two all-reduces of NCCL: the masks must be summed
//! before the shared list can be made, and a GPU's blocks change at its own rebuild, which the
//! others cannot foresee.

use super::barrier::{HostBarrier, SpinBarrier, TIMEOUT, enqueue_spin, wait_events};
use super::nccl::{Communicator, DataType, RedOp};
use super::reduce_shared::{
    MAX_PEER_GPUS, PeerCtx, PushCtx, SharedCtx, dense_dims, enqueue_copy, enqueue_counts_peers,
    enqueue_grid_update_gather, enqueue_list, enqueue_list_fused, enqueue_list_push, enqueue_mask,
    enqueue_push, enqueue_push_gather, enqueue_sum_peers, inbox_bytes, list_fused_blocks,
    list_push_blocks,
};
use crate::contract::Ctx;
use crate::error::err;
use crate::kernels::Kernels;
use crate::options::{BarrierKind, ExchangeMode};
use crate::step::{Exchange, Hooks};
use cudarc::driver::{CudaEvent, CudaSlice, CudaStream, DevicePtr};
use rtmpm_sim::SimError;
use std::sync::Arc;

fn nccl_err(e: String) -> SimError {
    SimError::Backend(e)
}

/// What a GPU shows the others for transport=p2p (pointers valid on every GPU through peer
/// access, handles as integers so that they cross threads).
#[derive(Clone, Copy, Debug)]
pub struct PeerExport {
    pub(crate) device: usize,
    pub(crate) ctx: usize,
    mask: u64,
    buf: u64,
    count: u64,
    events: [usize; 2],
    /// `exchange=push|push_update`: the arrival counter and the inbox (0 otherwise).
    arrivals: u64,
    inbox: u64,
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
    /// Set by [`Exchanger::connect`].
    pc: PeerCtx,
    spin: SpinBarrier,
    peer_events: [Vec<usize>; 2],
    host: Option<Arc<HostBarrier>>,
    /// `exchange=push`: this GPU's arrival counter, exchange count and done word (u64 each).
    push_words: CudaSlice<u64>,
    /// `exchange=push`: the inbox (2 x GPUs x capacity x 256 reals), made at the export.
    inbox: Option<CudaSlice<u8>>,
    /// `exchange=push`: set by [`Exchanger::connect`].
    qc: PushCtx,
}

/// One GPU's part of the exchange: the reduction buffers, the second stream it runs on, its
/// communicator (NCCL) or its barrier and view of the peers (p2p).
pub struct Exchanger {
    /// `None` with transport=p2p (and after [`Exchanger::take_comm`]).
    comm: Option<Communicator>,
    comm_stream: Arc<CudaStream>,
    pub(crate) sc: SharedCtx,
    _mask: CudaSlice<u8>,
    _counts: CudaSlice<u8>,
    _chunk: CudaSlice<u32>,
    shared_bufs: Option<(CudaSlice<u32>, CudaSlice<u8>)>,
    p2g_done: CudaEvent,
    reduced: CudaEvent,
    /// Events around the reduction on the comm stream (timing mode: no graph).
    pub(crate) timing: Option<(CudaEvent, CudaEvent)>,
    real: DataType,
    overlap: bool,
    /// The kernels of the list and sum (`exchange=`; not `Kernels` only with p2p + spin).
    mode: ExchangeMode,
    /// `exchange=push|push_update`: u8 per shared block, the GPUs that hold it.
    holders: Option<CudaSlice<u8>>,
    /// `exchange=fused|push|push_update`: the grid of the fused list (`list_push_update`: of the
    /// list and push), found at the first (uncaptured) step.
    list_blocks: std::sync::OnceLock<u32>,
    /// transport=p2p (`None`: NCCL).
    p2p: Option<P2pRank>,
}

impl Exchanger {
    /// The exchange of a GPU whose compute stream is `s`, for a domain of `n_cells` cells;
    /// `comm`: its NCCL communicator (`None`: transport=p2p with barrier `barrier`); `mode`:
    /// the kernels of the list and the sum (other than `Kernels` only with p2p and the spin
    /// barrier: refused otherwise).
    pub(crate) fn new(
        s: &Arc<CudaStream>,
        n_cells: [u32; 3],
        comm: Option<Communicator>,
        barrier: BarrierKind,
        f64: bool,
        overlap: bool,
        mode: ExchangeMode,
    ) -> Result<Exchanger, SimError> {
        if mode != ExchangeMode::Kernels && (comm.is_some() || barrier != BarrierKind::Spin) {
            return Err(SimError::Backend(format!(
                "exchange={}: needs transport=p2p with the spin barrier (the GPUs of one \
                 process with peer access and native atomics between them); use exchange=kernels",
                mode_name(mode)
            )));
        }
        let ctx = s.context().clone();
        let comm_stream = ctx.new_stream().map_err(err("comm stream"))?;
        let dims = dense_dims(n_cells);
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
        let p2p = match comm {
            Some(_) => None,
            None => Some(P2pRank {
                kind: barrier,
                calls: s.alloc_zeros::<u64>(1).map_err(err("alloc barrier"))?,
                count: s.alloc_zeros::<u64>(1).map_err(err("alloc barrier"))?,
                events: [ev()?, ev()?],
                pc: PeerCtx::default(),
                spin: SpinBarrier::default(),
                peer_events: [Vec::new(), Vec::new()],
                host: None,
                push_words: s
                    .alloc_zeros::<u64>(3)
                    .map_err(err("alloc push counters"))?,
                inbox: None,
                qc: PushCtx::default(),
            }),
        };
        Ok(Exchanger {
            comm,
            comm_stream,
            sc,
            _mask: mask,
            _counts: counts,
            _chunk: chunk,
            shared_bufs: None,
            p2g_done: ev()?,
            reduced: ev()?,
            timing: None,
            real: if f64 { DataType::F64 } else { DataType::F32 },
            overlap,
            mode,
            holders: None,
            list_blocks: std::sync::OnceLock::new(),
            p2p,
        })
    }

    pub(crate) fn comm(&self) -> Result<&Communicator, SimError> {
        self.comm
            .as_ref()
            .ok_or_else(|| SimError::Backend("GPU rank without a communicator".into()))
    }

    /// Give the communicator away (to build a new rank object on the same GPU).
    pub(crate) fn take_comm(&mut self) -> Option<Communicator> {
        self.comm.take()
    }

    /// True for the events barrier of transport=p2p (its waits bind to the peers' records of
    /// the same step, so it runs without CUDA graphs).
    pub(crate) fn uses_event_barrier(&self) -> bool {
        matches!(&self.p2p, Some(p) if p.kind == BarrierKind::Events)
    }

    /// Wait for the comm stream (before graphs or buffers go).
    pub(crate) fn synchronize(&self) {
        let _ = self.comm_stream.synchronize();
    }

    /// (Re)allocate the reduction for `cap` shared blocks on stream `s`.
    pub(crate) fn set_capacity(&mut self, s: &Arc<CudaStream>, cap: usize) -> Result<(), SimError> {
        let cap = cap.max(1);
        let rb = if self.real == DataType::F64 { 8 } else { 4 };
        let local = s
            .alloc_zeros::<u32>(cap)
            .map_err(err("alloc shared list"))?;
        let buf = s
            .alloc_zeros::<u8>(cap * 256 * rb)
            .map_err(err("alloc shared buffer"))?;
        self.sc.shared_local = local.device_ptr(s).0;
        self.sc.buf = buf.device_ptr(s).0;
        self.sc.cap = cap as u32;
        self.shared_bufs = Some((local, buf));
        if self.mode.pushes() {
            let h = s
                .alloc_zeros::<u8>(cap)
                .map_err(err("alloc shared holders"))?;
            self.sc.holders = h.device_ptr(s).0;
            self.holders = Some(h);
        }
        // The inbox follows the capacity: made again at the next export.
        if let Some(p) = self.p2p.as_mut() {
            p.inbox = None;
        }
        Ok(())
    }

    /// transport=p2p: what the other GPUs need of this one, in a run of `gpus` GPUs
    /// (`exchange=push|push_update`: its inbox is made here, for `gpus` GPUs and the capacity).
    pub(crate) fn peer_export(
        &mut self,
        s: &Arc<CudaStream>,
        gpus: usize,
    ) -> Result<PeerExport, SimError> {
        let (push, cap, f64) = (
            self.mode.pushes(),
            self.sc.cap as usize,
            self.real == DataType::F64,
        );
        let p = self
            .p2p
            .as_mut()
            .ok_or_else(|| SimError::Backend("not a transport=p2p rank".into()))?;
        let want = inbox_bytes(gpus, cap, f64);
        if push && p.inbox.as_ref().is_none_or(|b| b.len() != want) {
            p.inbox = None;
            p.inbox = Some(s.alloc_zeros::<u8>(want).map_err(err("alloc push inbox"))?);
            s.synchronize().map_err(err("sync"))?;
        }
        let inbox = p.inbox.as_ref().map_or(0, |b| b.device_ptr(s).0);
        Ok(PeerExport {
            arrivals: p.push_words.device_ptr(s).0,
            inbox,
            device: s.context().ordinal(),
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

    /// transport=p2p: take the other GPUs' buffers and barrier (rank `me` of `all`).
    pub(crate) fn connect(
        &mut self,
        s: &CudaStream,
        me: usize,
        all: &[PeerExport],
        host: Arc<HostBarrier>,
    ) -> Result<(), SimError> {
        let n = all.len();
        if n > MAX_PEER_GPUS {
            return Err(SimError::Backend(format!(
                "transport=p2p handles at most {MAX_PEER_GPUS} GPUs; use transport=nccl"
            )));
        }
        let p = self
            .p2p
            .as_mut()
            .ok_or_else(|| SimError::Backend("not a transport=p2p rank".into()))?;
        let mut pc = PeerCtx {
            n: n as u32,
            me: me as u32,
            ..Default::default()
        };
        let words = p.push_words.device_ptr(s).0;
        let mut qc = PushCtx {
            calls: words + 8,
            done: words + 16,
            timeout_ns: TIMEOUT.as_nanos() as u64,
            n: n as u32,
            me: me as u32,
            ..Default::default()
        };
        for (j, e) in all.iter().enumerate() {
            pc.mask[j] = e.mask;
            pc.buf[j] = e.buf;
            qc.inbox[j] = e.inbox;
            qc.arrivals[j] = e.arrivals;
        }
        p.pc = pc;
        p.qc = qc;
        p.spin = SpinBarrier {
            count: all[0].count,
            calls: p.calls.device_ptr(s).0,
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

    /// transport=p2p: enqueue inter-GPU barrier `i` (0: masks, 1: packed blocks) on `st`.
    fn barrier(
        &self,
        p: &P2pRank,
        i: usize,
        k: &Kernels,
        st: &CudaStream,
        c: &Ctx,
    ) -> Result<(), SimError> {
        match p.kind {
            BarrierKind::Spin => enqueue_spin(k, st, c, &p.spin).map_err(err("barrier")),
            BarrierKind::Events => {
                p.events[i].record(st).map_err(err("event"))?;
                let host = p
                    .host
                    .as_ref()
                    .ok_or_else(|| SimError::Backend("GPU rank not connected".into()))?;
                host.wait(TIMEOUT).map_err(SimError::Backend)?;
                wait_events(st, &p.peer_events[i]).map_err(err("wait peer events"))
            }
        }
    }

    /// The grid of the mode's cooperative list kernel (`occupancy`: [`list_fused_blocks`] or
    /// [`list_push_blocks`]), found once.
    fn fused_grid(
        &self,
        k: &Kernels,
        occupancy: fn(&Kernels) -> Result<u32, cudarc::driver::DriverError>,
    ) -> Result<u32, SimError> {
        match self.list_blocks.get() {
            Some(&b) => Ok(b),
            None => {
                let b = occupancy(k).map_err(err("occupancy of the fused shared list"))?;
                Ok(*self.list_blocks.get_or_init(|| b))
            }
        }
    }

    /// Milliseconds of the last step's reduction (pack, sum, unpack; synchronises).
    pub(crate) fn last_reduce_ms(&self) -> Result<f64, SimError> {
        match &self.timing {
            Some((a, b)) => Ok(a.elapsed_ms(b).map_err(err("elapsed"))? as f64),
            None => Ok(0.0),
        }
    }
}

impl Exchange for Exchanger {
    fn after_rebuild(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), SimError> {
        let sc = &self.sc;
        if self.p2p.is_some() && self.mode == ExchangeMode::ListPushUpdate {
            return Ok(()); // the list is made with the push, after P2G (start)
        }
        if let (Some(p), false) = (&self.p2p, self.mode == ExchangeMode::Kernels) {
            // One cooperative launch: mask, barrier, sum of the masks, list, boundary.
            let blocks = self.fused_grid(k, list_fused_blocks)?;
            return enqueue_list_fused(k, s, c, sc, &p.pc, &p.spin, blocks)
                .map_err(err("shared list"));
        }
        enqueue_mask(k, s, c, sc).map_err(err("mask"))?;
        if let Some(p) = &self.p2p {
            self.barrier(p, 0, k, s, c)?;
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
        enqueue_list(k, s, c, sc).map_err(err("shared list"))
    }

    fn overlap(&self) -> bool {
        // push_update: the grid update is its own kernel's (refused with overlap=on).
        self.overlap && !self.mode.sums_in_update()
    }

    fn start(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), SimError> {
        let (sc, t) = (&self.sc, &self.comm_stream);
        if let (Some(p), true) = (&self.p2p, self.mode.sums_in_update()) {
            // On the compute stream: the grid update that follows waits and sums inside it.
            if let Some((a, _)) = &self.timing {
                a.record(s).map_err(err("event"))?;
            }
            if self.mode == ExchangeMode::ListPushUpdate {
                let blocks = self.fused_grid(k, list_push_blocks)?;
                return enqueue_list_push(k, s, c, sc, &p.pc, &p.spin, &p.qc, blocks)
                    .map_err(err("shared list and push"));
            }
            let f64 = self.real == DataType::F64;
            return enqueue_push(k, s, c, sc, &p.qc, f64).map_err(err("push"));
        }
        self.p2g_done.record(s).map_err(err("event"))?;
        t.wait(&self.p2g_done).map_err(err("wait"))?;
        if let Some((a, _)) = &self.timing {
            a.record(t).map_err(err("event"))?;
        }
        if let (Some(p), ExchangeMode::Push) = (&self.p2p, self.mode) {
            let f64 = self.real == DataType::F64;
            enqueue_push_gather(k, t, c, sc, &p.qc, f64).map_err(err("push"))?;
        } else if let Some(p) = &self.p2p {
            enqueue_copy(k, t, c, sc, true).map_err(err("pack"))?;
            self.barrier(p, 1, k, t, c)?;
            enqueue_sum_peers(k, t, c, sc, &p.pc).map_err(err("peer sum"))?;
        } else {
            enqueue_copy(k, t, c, sc, true).map_err(err("pack"))?;
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
        self.reduced.record(t).map_err(err("event"))
    }

    fn finish(&self, _k: &Kernels, s: &CudaStream, _c: &Ctx) -> Result<(), SimError> {
        if self.mode.sums_in_update() && self.p2p.is_some() {
            return Ok(()); // nothing on a second stream
        }
        s.wait(&self.reduced).map_err(err("wait"))
    }

    fn grid_update(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<bool, SimError> {
        let Some(p) = self.p2p.as_ref().filter(|_| self.mode.sums_in_update()) else {
            return Ok(false);
        };
        enqueue_grid_update_gather(k, s, c, &self.sc, &p.qc)
            .map_err(err("grid update with the sum of the inbox"))?;
        // Timing: the push and this grid update together (the sum is inside the update).
        if let Some((_, b)) = &self.timing {
            b.record(s).map_err(err("event"))?;
        }
        Ok(true)
    }
}

/// The option value of `mode` (`exchange=`).
pub(crate) fn mode_name(mode: ExchangeMode) -> &'static str {
    match mode {
        ExchangeMode::Kernels => "kernels",
        ExchangeMode::Fused => "fused",
        ExchangeMode::Push => "push",
        ExchangeMode::PushUpdate => "push_update",
        ExchangeMode::ListPushUpdate => "list_push_update",
    }
}

/// The hooks of a GPU of several: its exchange.
pub(crate) struct ExchangeHooks<'a>(pub &'a Exchanger);

impl Hooks for ExchangeHooks<'_> {
    fn exchange(&self) -> Option<&dyn Exchange> {
        Some(self.0)
    }
}
