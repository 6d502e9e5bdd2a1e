//! What the host reads of a [`CudaBackend`] (each call synchronises): control words and the
//! errors they report, the grid, the particle state, sizes.

use crate::backend::CudaBackend;
use crate::contract::*;
use crate::error::err;
use crate::step::p2g::{P2gPlan, reverse_map::ReverseMapSize};
use cudarc::driver::CudaSlice;
use rtmpm_physics::math::IVec3;
use rtmpm_sim::SimError;

impl CudaBackend {
    /// Extra device memory of the P2G strategy: (buffer, bytes); empty for the scatter.
    pub fn p2g_memory(&self) -> Vec<(&'static str, usize)> {
        self.p2g.memory()
    }

    /// Bytes of every device allocation of this backend: the pipeline's buffers and the P2G
    /// strategy's extra buffers and, once a picture was drawn, the render stage's (the compiled
    /// module and CUDA's own context memory aside).
    pub fn device_bytes(&self) -> usize {
        self.buffers.bytes()
            + self.p2g.memory().iter().map(|m| m.1).sum::<usize>()
            + self.render.as_ref().map_or(0, |r| r.bytes())
    }

    /// The device bytes of this backend by group: state, sort scratch, grid, sort, hash/lists
    /// (planned by `Capacity::bytes`), then the P2G strategy's extra buffers ("p2g") and the
    /// rest (tables, control words, parameters: "other"); the sum is [`Self::device_bytes`].
    pub fn memory_breakdown(&self) -> Vec<(&'static str, usize)> {
        let planned = self.buffers.planned;
        let mut v = planned.groups().to_vec();
        let p2g: usize = self.p2g.memory().iter().map(|m| m.1).sum();
        v.push(("p2g", p2g));
        let total = self.device_bytes();
        v.push(("other", total.saturating_sub(planned.total() + p2g)));
        v
    }

    /// Bytes of the grid (nodes of every allocated pblock), for comparison with
    /// [`CudaBackend::p2g_memory`].
    pub fn grid_bytes(&self) -> usize {
        self.ctx.pblock_cap as usize * 64 * 4 * self.real_bytes()
    }

    /// The whole particle state as stored (every field at stride [`CudaBackend::capacity`], the
    /// slots past the particles included), in the backend's precision: for tests that compare
    /// states word for word.
    pub fn state_bytes(&mut self) -> Result<Vec<u8>, SimError> {
        self.stream
            .clone_dtoh(&self.buffers.state)
            .map_err(err("read the particle state"))
    }

    /// Particle capacity of the state arrays (the stride of a field; at least the count).
    pub fn capacity(&self) -> usize {
        self.ctx.cap as usize
    }

    /// Bytes of one `real` (4, or 8 in f64).
    pub(crate) fn real_bytes(&self) -> usize {
        if self.options.f64 { 8 } else { 4 }
    }

    /// Sizes of the reverse map (`p2g=reverse_map` only).
    pub fn reverse_map_size(&self) -> Option<ReverseMapSize> {
        match &self.p2g {
            P2gPlan::ReverseMap(r) => Some(r.size),
            _ => None,
        }
    }

    /// The grid the last step wrote (velocities after the grid update).
    fn shown_grid(&self) -> &CudaSlice<u8> {
        match (self.last_grid, &self.buffers.grid_next) {
            (1, Some(g)) => g,
            _ => &self.buffers.grid,
        }
    }

    /// The `i`-th real of a grid read back as bytes, widened to f64.
    fn real_at(&self, bytes: &[u8], i: usize) -> f64 {
        let rb = self.real_bytes();
        let b = &bytes[rb * i..rb * i + rb];
        if rb == 8 {
            f64::from_le_bytes(b.try_into().unwrap_or([0; 8]))
        } else {
            f32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as f64
        }
    }

    /// Every grid node of the pblocks in use with its four values (mass, momentum or velocity),
    /// by grid coordinate. Pblock ids differ between runs, coordinates do not: this compares the
    /// grids of two backends node by node.
    pub fn grid_nodes(&mut self) -> Result<Vec<(IVec3, [f64; 4])>, SimError> {
        self.nodes_of(false)
    }

    /// [`CudaBackend::grid_nodes`] of the grid the coming step reads: with G2P2G the last fused
    /// scatter (masses and momenta) and whatever was redone into it since (a batch's redo of
    /// the worlds put); without, the last step's grid, as `grid_nodes`.
    pub fn coming_grid_nodes(&mut self) -> Result<Vec<(IVec3, [f64; 4])>, SimError> {
        self.nodes_of(self.g2p2g())
    }

    /// The nodes of the grid the last step wrote, or (`coming`) of the other of G2P2G's two.
    fn nodes_of(&mut self, coming: bool) -> Result<Vec<(IVec3, [f64; 4])>, SimError> {
        let (_, p, _) = self.block_counts()?;
        let which = match (coming, self.parity, &self.buffers.grid_next) {
            (true, 1, Some(g)) => g,
            (true, _, _) => &self.buffers.grid,
            (false, _, _) => self.shown_grid(),
        };
        let grid = self.stream.clone_dtoh(which).map_err(err("read grid"))?;
        let coords: Vec<i32> = self
            .stream
            .clone_dtoh(&self.buffers.block_coords)
            .map_err(err("read block coordinates"))?
            .chunks_exact(4)
            .map(|w| i32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        let mut out = Vec::with_capacity(p as usize * 64);
        for id in 0..(p as usize).min(self.ctx.pblock_cap as usize) {
            let bc = IVec3::new(coords[3 * id], coords[3 * id + 1], coords[3 * id + 2]);
            for cell in 0..64usize {
                let node = bc * 4
                    + IVec3::new(
                        (cell >> 4) as i32,
                        ((cell >> 2) & 3) as i32,
                        (cell & 3) as i32,
                    );
                let v = std::array::from_fn(|q| self.real_at(&grid, 4 * (id * 64 + cell) + q));
                out.push((node, v));
            }
        }
        Ok(out)
    }

    /// Sum of node masses and momenta/velocities on the grid, as f64. After a step the grid
    /// holds velocities; see the tests for how P2G alone is checked.
    pub fn grid_sums(&mut self) -> Result<[f64; 4], SimError> {
        let (_, p, _) = self.block_counts()?;
        let bytes = self
            .stream
            .clone_dtoh(self.shown_grid())
            .map_err(err("read grid"))?;
        let mut s = [0f64; 4];
        for i in 0..p as usize * 64 * 4 {
            s[i % 4] += self.real_at(&bytes, i);
        }
        Ok(s)
    }

    /// Every control word, read now (a wait for the stream).
    pub(crate) fn ctl_words(&mut self) -> Result<Vec<u32>, SimError> {
        self.ctl_words_for(crate::waits::WaitReason::Control)
    }

    /// Positions and velocities of every particle in original order, in the backend's
    /// precision widened to f64 (for precision tests).
    pub fn read_x_v_f64(&mut self) -> Result<Vec<[[f64; 3]; 2]>, SimError> {
        let host = self
            .stream
            .clone_dtoh(&self.buffers.state)
            .map_err(err("read particles"))?;
        crate::state::unpack_x_v_f64(
            &host,
            self.n,
            self.ctx.cap as usize,
            self.layout,
            self.options.f64,
        )
        .map_err(SimError::Backend)
    }

    /// The particle state arrays as stored (SoA, stride = capacity). Single precision only (the
    /// multi-GPU runs that use it refuse f64).
    pub fn read_state(&mut self) -> Result<Vec<f32>, SimError> {
        if self.options.f64 {
            return Err(SimError::Backend(
                "CUDA: read_state is single precision only".into(),
            ));
        }
        let bytes = self
            .stream
            .clone_dtoh(&self.buffers.state)
            .map_err(err("read particles"))?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// The particle state arrays as stored, in either precision: the bytes of the layout's
    /// word arrays ([`CudaBackend::state_layout`]) (SoA, `real` words) and their stride (the particle capacity).
    pub fn read_state_bytes(&mut self) -> Result<(Vec<u8>, usize), SimError> {
        let bytes = self
            .stream
            .clone_dtoh(&self.buffers.state)
            .map_err(err("read particles"))?;
        Ok((bytes, self.ctx.cap as usize))
    }

    /// Number of rebuilds of the mapping so far.
    pub fn rebuild_count(&mut self) -> Result<u32, SimError> {
        Ok(self.ctl_words()?[CTL_REBUILDS])
    }

    /// Current (gblock, pblock, warp) counts.
    pub fn block_counts(&mut self) -> Result<(u32, u32, u32), SimError> {
        let c = self.ctl_words()?;
        Ok((c[CTL_GBLOCKS], c[CTL_PBLOCKS], c[CTL_WARPS]))
    }

    /// The errors the device reported in control words `c` (any GPU's), as one message.
    pub(crate) fn error_check(&self, c: &[u32]) -> Result<(), SimError> {
        let e = c[CTL_ERROR];
        if e == 0 {
            return Ok(());
        }
        let mut what = Vec::new();
        if e & ERR_HASH != 0 {
            what.push(format!(
                "block hash table full ({} slots)",
                self.ctx.hash_cap
            ));
        }
        if e & ERR_GBLOCKS != 0 {
            what.push(format!("more than {} gblocks", self.ctx.gblock_cap));
        }
        if e & ERR_PBLOCKS != 0 {
            what.push(format!("more than {} pblocks", self.ctx.pblock_cap));
        }
        if e & ERR_WARPS != 0 {
            what.push(format!("more than {} warps", self.ctx.warp_cap));
        }
        if e & ERR_P2G_MAP != 0 {
            what.push(match self.reverse_map_size() {
                Some(s) => format!(
                    "p2g=reverse_map: a node received more than {} entries in one of its {} maps, \
                     or the material reached more than {} pblocks (raise rmap_slots= or rmap_pblocks=)",
                    s.slots, s.replicas, s.pblocks
                ),
                None => "P2G contribution map overflow".to_string(),
            });
        }
        if e & ERR_SHARED != 0 {
            what.push(format!(
                "more than {} blocks shared between GPUs (raise it with the shared= option)",
                c[CTL_SHARED_CAP]
            ));
        }
        if e & ERR_BARRIER != 0 {
            what.push(
                "the inter-GPU spin barrier timed out: another GPU never arrived (its host \
                 thread stopped; see the other errors)"
                    .to_string(),
            );
        }
        let hint = if e & ERR_MAPPING != 0 {
            " (the material spread over more blocks than allocated; raise the capacity with \
             the gblocks=/pblocks= options)"
        } else {
            ""
        };
        let head = if e & !ERR_BARRIER != 0 {
            "CUDA backend out of capacity"
        } else {
            "CUDA multi-GPU run stopped"
        };
        Err(SimError::Backend(format!(
            "{head}: {}{hint}",
            what.join(", ")
        )))
    }
}

/// Size every column of `out` for `n` particles (zeros); see [`crate::state::resize_particles`].
pub use crate::state::resize_particles;

/// Put the `n` particles of a single-precision state array (SoA with stride `cap` in `layout`, as
/// stored on one GPU) at their original index in `out` (already sized for every particle of the
/// run).
pub fn scatter_state(
    host: &[f32],
    n: usize,
    cap: usize,
    layout: crate::contract::StateLayout,
    out: &mut rtmpm_physics::Particles,
) -> Result<(), SimError> {
    crate::state::scatter_f32(host, n, cap, layout, out).map_err(SimError::Backend)
}
