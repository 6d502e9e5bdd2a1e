//! P2G, the particle-to-grid transfer, by one of four strategies ([`P2gPlan`]), with the buffers
//! each owns:
//! * [`scatter`] (the default): warps of 32 particles, in-warp sort, warp-level segmented
//!   reduction and direct global atomics (Fei, Huang & Gao, "Real-Time Simulation of MPM on
//!   Modern GPUs", GTC 2022), or a shared-memory tile per gblock (ablation);
//! * the gathers of Chiang et al., "GPU Acceleration of the Generalized Interpolation Material
//!   Point Method" (SAAHPC 2009): [`reverse_map`] (replicated node-to-particle maps) and
//!   [`sort`] (one sort per step of the particle-node contributions).
//!
//! Every strategy takes the per-particle quantities from one device function
//! (`kernels/p2g/particle.cuh`).

pub mod reverse_map;
pub mod scatter;
pub mod sort;

use crate::contract::Ctx;
use crate::kernels::{Kernel, Kernels};
use crate::options::{CkP2g, P2gMode};
use crate::setup::capacity::Capacity;
use cudarc::driver::{CudaStream, DriverError, PushKernelArg};
use reverse_map::{ReverseMap, ReverseMapSize};
use rtmpm_physics::math::IVec3;
use rtmpm_sim::SimError;
use sort::SortMap;
use std::sync::Arc;

/// The P2G strategy of a backend, with the device buffers of the gather strategies. The
/// scatters name CK-MPM's P2G kernel too (the gathers take MLS-MPM contributions only).
pub enum P2gPlan {
    /// Scatter with warp-level reduction and global atomics.
    Warp(CkP2g),
    /// Scatter into a shared-memory tile per gblock (ablation).
    Shared(CkP2g),
    /// Gather through replicated node-to-particle reverse maps.
    ReverseMap(ReverseMap),
    /// Gather through a per-step sort of the particle-node contributions.
    Sort(SortMap),
}

impl P2gPlan {
    /// The plan of `options.p2g`, its buffers allocated (`bases`: the particles' stencil bases;
    /// `initial_pblocks`: the pblocks of the initial mapping).
    pub(crate) fn new(
        options: &crate::options::CudaOptions,
        bases: &[IVec3],
        initial_pblocks: usize,
        cap: &Capacity,
        stream: &Arc<CudaStream>,
        ctx: &Ctx,
        real_bytes: usize,
    ) -> Result<P2gPlan, SimError> {
        Ok(match options.p2g {
            P2gMode::Warp => P2gPlan::Warp(options.ck_p2g),
            P2gMode::Shared => P2gPlan::Shared(options.ck_p2g),
            P2gMode::ReverseMap => {
                let mut size = ReverseMapSize::for_particles(
                    bases,
                    options.rmap_replicas,
                    initial_pblocks,
                    cap.pblocks,
                );
                if let Some(s) = options.rmap_slots {
                    size.slots = s.max(1);
                }
                if let Some(p) = options.rmap_pblocks {
                    size.pblocks = p.clamp(1, cap.pblocks);
                }
                P2gPlan::ReverseMap(ReverseMap::new(stream, ctx, real_bytes, size)?)
            }
            P2gMode::Sort => P2gPlan::Sort(SortMap::new(stream, ctx, real_bytes)?),
        })
    }

    /// The mode this plan implements.
    pub fn mode(&self) -> P2gMode {
        match self {
            P2gPlan::Warp(_) => P2gMode::Warp,
            P2gPlan::Shared(_) => P2gMode::Shared,
            P2gPlan::ReverseMap(_) => P2gMode::ReverseMap,
            P2gPlan::Sort(_) => P2gMode::Sort,
        }
    }

    /// Names of the phases that [`P2gPlan::enqueue_phase`] enqueues (timed separately by the
    /// benchmark).
    pub fn phases(&self) -> &'static [&'static str] {
        match self {
            P2gPlan::Warp(_) => &["scatter"],
            P2gPlan::Shared(_) => &["scatter_shared"],
            P2gPlan::ReverseMap(_) => ReverseMap::PHASES,
            P2gPlan::Sort(_) => SortMap::PHASES,
        }
    }

    /// Enqueue phase `i` of [`P2gPlan::phases`].
    pub(crate) fn enqueue_phase(
        &self,
        i: usize,
        k: &Kernels,
        s: &CudaStream,
        c: &Ctx,
    ) -> Result<(), DriverError> {
        match self {
            P2gPlan::Warp(ck) | P2gPlan::Shared(ck) => {
                scatter::enqueue(k, s, c, self.mode(), *ck, 0)
            }
            P2gPlan::ReverseMap(r) => r.enqueue_phase(i, k, s, c),
            P2gPlan::Sort(m) => m.enqueue_phase(i, k, s, c),
        }
    }

    /// Several GPUs (the scatter only): P2G of part 1 (the gblocks next to a block shared with
    /// another GPU) or part 2 (the others).
    pub(crate) fn enqueue_part(
        &self,
        k: &Kernels,
        s: &CudaStream,
        c: &Ctx,
        part: u32,
    ) -> Result<(), DriverError> {
        scatter::enqueue(k, s, c, self.mode(), self.ck_p2g(), part)
    }

    /// CK-MPM's P2G kernel of a scatter plan (direct for the gathers, which refuse CK-MPM).
    pub fn ck_p2g(&self) -> CkP2g {
        match self {
            P2gPlan::Warp(ck) | P2gPlan::Shared(ck) => *ck,
            P2gPlan::ReverseMap(_) | P2gPlan::Sort(_) => CkP2g::Direct,
        }
    }

    /// Device buffers this strategy adds to the pipeline: (what, bytes).
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        match self {
            P2gPlan::Warp(_) | P2gPlan::Shared(_) => Vec::new(),
            P2gPlan::ReverseMap(r) => r.memory.clone(),
            P2gPlan::Sort(m) => m.memory.clone(),
        }
    }
}

/// Enqueue the MUSL re-map: clear `grid_aux`, then scatter the updated particle momenta into it.
pub(crate) fn enqueue_musl(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    // SAFETY: the kernels bounds-check against the device counters.
    unsafe {
        s.launch_builder(&k[Kernel::GridClearAux])
            .arg(c)
            .launch(k.wave(c.pblock_cap as usize * 256, 256))?;
        s.launch_builder(&k[Kernel::P2gMusl])
            .arg(c)
            .launch(k.wave(c.warp_cap as usize * 32, 128))?;
    }
    Ok(())
}
