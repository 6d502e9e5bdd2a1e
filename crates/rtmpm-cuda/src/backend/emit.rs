//! Particles that appear during a run (`[[emitter]]`, `rtmpm_scene::emitter`): the state arrays
//! are sized for the initial particles plus every emitter's total when the backend is built
//! (`CudaBackend::new_part`), so emitting never reallocates. The host packs the new particles,
//! copies them into the slots after the last particle, raises `n` and asks for a rebuild (and,
//! with G2P2G, for this step's P2G: the fused scatter of the last step did not see them). The
//! captured step graphs launch for the old `n`, so they are dropped and captured again.
//!
//! Cost: one small host-to-device copy per field and a stream synchronisation per step that
//! emits (the packed bytes are freed on return), plus the re-capture of the step graph.

use crate::backend::CudaBackend;
use crate::contract::{CTL_NEED_REBUILD, CTL_P2G_PENDING};
use crate::error::err;
use crate::options::P2gMode;
use rtmpm_scene::Scene;
use rtmpm_sim::{Particles, SimError};

/// Particles every emitter of `scene` emits over the run.
pub fn emitted_total(scene: &Scene) -> usize {
    scene
        .emitters
        .iter()
        .map(|e| e.total() as usize)
        .fold(0, usize::saturating_add)
}

/// What the CUDA backend cannot do with emitters, as a clear error before any GPU work.
pub(crate) fn check(scene: &Scene, p2g: P2gMode) -> Result<(), SimError> {
    if !scene.emitters.is_empty() && matches!(p2g, P2gMode::ReverseMap | P2gMode::Sort) {
        return Err(SimError::Backend(format!(
            "CUDA backend: p2g={} sizes its maps for the initial particles and cannot take the \
             scene's [[emitter]] particles; use p2g=warp (the default) or p2g=shared",
            p2g.name()
        )));
    }
    Ok(())
}

impl CudaBackend {
    /// Append `p` after the last particle (original indices `n..n + len`).
    pub(crate) fn append_particles(&mut self, p: &Particles) -> Result<(), SimError> {
        let (n, k, cap) = (self.n, p.len(), self.ctx.cap as usize);
        if k == 0 {
            return Ok(());
        }
        if n + k > cap {
            return Err(SimError::Backend(format!(
                "CUDA backend: {} particles after emitting exceed the capacity of {cap} planned \
                 from the scene's emitters (particles were added another way?)",
                n + k
            )));
        }
        let fluid = crate::state::fluid_materials(&self.scene);
        let ids: Vec<u32> = (n as u32..(n + k) as u32).collect();
        let f64 = self.options.f64;
        let words = self.layout.words();
        let packed = crate::state::pack(p, &fluid, self.layout, f64, k, Some(&ids))
            .map_err(SimError::Backend)?;
        let wb = crate::state::word_bytes(f64);
        for (f, row) in packed.chunks_exact(k * wb).enumerate().take(words) {
            let at = (f * cap + n) * wb;
            let mut dst = self.buffers.state.slice_mut(at..at + k * wb);
            self.stream
                .memcpy_htod(row, &mut dst)
                .map_err(err("upload emitted particles"))?;
        }
        self.n = n + k;
        self.ctx.n = (n + k) as u32;
        self.clear_graphs();
        self.set_ctl_word(CTL_NEED_REBUILD, 1)?;
        if self.g2p2g() {
            self.set_ctl_word(CTL_P2G_PENDING, 1)?;
        }
        self.stream.synchronize().map_err(err("synchronize"))
    }
}
