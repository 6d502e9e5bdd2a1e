//! The step, written once. Every mode enqueues its steps through [`enqueue_step`]: one GPU
//! ([`crate::backend::CudaBackend`]), several GPUs of one process and one process per GPU
//! ([`crate::multi`]), the benchmark ([`crate::backend::bench`]) and `rtmpm validate`. The modes differ
//! only by their [`Hooks`]: the exchange of the blocks shared with other GPUs between P2G and
//! the grid update, and the timing events of the benchmark. Graph capture and replay of a step
//! are in [`crate::step::graph`].
//!
//! One step (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs", GTC 2022):
//!
//! 1. **rebuild** of the mapping (blocks, hash, neighbour lists, sort), only when a particle left
//!    its free zone; the grid clear ([`crate::step::rebuild`]);
//! 2. **P2G**: mass, momentum and stress to the grid ([`crate::step::p2g`]); with G2P2G only after a
//!    rebuild or a new dt, the previous step's fused kernel having scattered the particles;
//!    *hook*: several GPUs sum the blocks they share (with the separate P2G, the gblocks next
//!    to a shared block first, the exchange while the others run);
//! 3. **grid update**: velocities, gravity, walls, colliders ([`crate::step::grid_update`]); several
//!    GPUs update the pblocks no other GPU shares while the shared ones are summed, then those;
//! 4. MUSL only: the re-map of the updated particle momenta ([`crate::step::g2p`], [`crate::step::p2g`],
//!    [`crate::step::grid_update`]);
//! 5. **G2P**: velocities, affine matrix, F, plasticity, advection; with G2P2G fused with the
//!    next step's P2G ([`crate::step::g2p`]).

pub mod g2p;
pub mod graph;
pub mod grid_update;
pub mod p2g;
pub mod rebuild;
pub mod rigid;

use crate::contract::Ctx;
use crate::error::err;
use crate::kernels::Kernels;
use crate::step::p2g::P2gPlan;
use cudarc::driver::CudaStream;
use rtmpm_physics::transfer::{Transfer, Update};
use rtmpm_sim::SimError;

/// A stage of the step, in order (each may be several kernels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Rebuild of the mapping (when needed) and the grid clear.
    Rebuild,
    /// Phase `i` of the P2G strategy ([`P2gPlan::phases`]).
    P2g(usize),
    /// Grid update.
    GridUpdate,
    /// MUSL: new particle velocities, their momenta mapped to the grid again, its update.
    MuslRemap,
    /// G2P (or G2P2G).
    G2p,
}

/// What a step is made of: the P2G strategy and the scene's transfer.
pub struct StepPlan<'a> {
    /// The P2G strategy.
    pub p2g: &'a P2gPlan,
    /// Every material is a fluid (G2P2G then runs its fluid variant).
    pub all_fluid: bool,
}

impl StepPlan<'_> {
    /// The stages of a step with context `c`, in order.
    pub fn stages(&self, c: &Ctx) -> Vec<Stage> {
        let mut s = vec![Stage::Rebuild];
        s.extend((0..self.p2g.phases().len()).map(Stage::P2g));
        s.push(Stage::GridUpdate);
        if musl(c) {
            s.push(Stage::MuslRemap);
        }
        s.push(Stage::G2p);
        s
    }
}

/// True for the MUSL stress update of the classic transfers (MLS-MPM and CK-MPM are USL only).
fn musl(c: &Ctx) -> bool {
    c.transfer != Transfer::Mls.code()
        && c.transfer != Transfer::CkMpm.code()
        && c.update == crate::contract::update(Update::Musl)
}

/// Several GPUs: the sum of the grid blocks a GPU shares with the others, between P2G and the
/// grid update (`crate::multi::exchange`).
pub trait Exchange {
    /// After the rebuild: which blocks are shared (redone only when a GPU rebuilt).
    fn after_rebuild(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), SimError>;
    /// Overlap the exchange with the work that does not need it: the grid update of the pblocks
    /// no other GPU shares, and (separate P2G) the P2G of the gblocks next to no shared block.
    /// Else P2G, the exchange, then the grid update, in sequence.
    fn overlap(&self) -> bool;
    /// Start the exchange (after the P2G of every block that touches a shared block).
    fn start(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), SimError>;
    /// Make `s` wait for the exchange (before the grid update).
    fn finish(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), SimError>;
    /// Without the overlap, after [`Exchange::finish`]: enqueue the grid update of every pblock
    /// with the end of the exchange inside it and return true (`exchange=push_update`: the
    /// inbox summed in the grid update's kernel), or return false and let the step enqueue the
    /// plain grid update.
    fn grid_update(&self, _k: &Kernels, _s: &CudaStream, _c: &Ctx) -> Result<bool, SimError> {
        Ok(false)
    }
}

/// What a mode adds to the step.
pub trait Hooks {
    /// Called after each stage was enqueued (the benchmark records events here).
    fn after(&mut self, _stage: Stage, _s: &CudaStream) -> Result<(), SimError> {
        Ok(())
    }
    /// Several GPUs: the exchange of shared blocks.
    fn exchange(&self) -> Option<&dyn Exchange> {
        None
    }
}

/// One GPU, no timing: no hooks.
pub struct NoHooks;
impl Hooks for NoHooks {}

/// Enqueue one step on `s` (parameters already uploaded), stopping after `last`.
pub fn enqueue_until(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    plan: &StepPlan,
    hooks: &mut dyn Hooks,
    last: Stage,
) -> Result<(), SimError> {
    let phases = plan.p2g.phases().len();
    for stage in plan.stages(c) {
        match stage {
            Stage::Rebuild => {
                rebuild::enqueue(k, s, c).map_err(err("rebuild"))?;
                if let Some(x) = hooks.exchange() {
                    x.after_rebuild(k, s, c)?;
                }
            }
            Stage::P2g(i) => match hooks.exchange() {
                // Several GPUs, separate P2G (the warp scatter, one phase): the gblocks next to a
                // shared block first, the exchange while the others run. With G2P2G the P2G
                // kernel runs only after a rebuild: one launch, the overlap is in the grid update.
                Some(x) if x.overlap() && c.grid_next == 0 => {
                    plan.p2g.enqueue_part(k, s, c, 1).map_err(err("p2g"))?;
                    x.start(k, s, c)?;
                    plan.p2g.enqueue_part(k, s, c, 2).map_err(err("p2g"))?;
                }
                Some(x) => {
                    plan.p2g.enqueue_phase(i, k, s, c).map_err(err("p2g"))?;
                    if i + 1 == phases {
                        x.start(k, s, c)?;
                    }
                }
                None => plan.p2g.enqueue_phase(i, k, s, c).map_err(err("p2g"))?,
            },
            Stage::GridUpdate => match hooks.exchange() {
                // Several GPUs: the pblocks no other GPU shares while the shared ones are summed,
                // then the shared ones.
                Some(x) if x.overlap() => {
                    grid_update::enqueue(k, s, c, 1).map_err(err("grid update"))?;
                    x.finish(k, s, c)?;
                    grid_update::enqueue(k, s, c, 2).map_err(err("grid update"))?;
                }
                Some(x) => {
                    x.finish(k, s, c)?;
                    if !x.grid_update(k, s, c)? {
                        grid_update::enqueue(k, s, c, 0).map_err(err("grid update"))?;
                    }
                }
                None => grid_update::enqueue(k, s, c, 0).map_err(err("grid update"))?,
            },
            Stage::MuslRemap => {
                g2p::enqueue_velocity(k, s, c).map_err(err("g2p (MUSL velocity)"))?;
                crate::step::p2g::enqueue_musl(k, s, c).map_err(err("p2g (MUSL re-map)"))?;
                grid_update::enqueue_musl(k, s, c).map_err(err("grid update (MUSL)"))?;
            }
            Stage::G2p => g2p::enqueue(k, s, c, plan.all_fluid).map_err(err("g2p"))?,
        }
        hooks.after(stage, s)?;
        if stage == last {
            break;
        }
    }
    Ok(())
}

/// Enqueue one whole step on `s` (parameters already uploaded).
pub fn enqueue_step(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    plan: &StepPlan,
    hooks: &mut dyn Hooks,
) -> Result<(), SimError> {
    enqueue_until(k, s, c, plan, hooks, Stage::G2p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_musl_step_has_the_remap_and_every_other_step_does_not() {
        let plan = StepPlan {
            p2g: &P2gPlan::Warp(crate::options::CkP2g::Direct),
            all_fluid: false,
        };
        let mls = Ctx::default();
        assert_eq!(
            plan.stages(&mls),
            vec![Stage::Rebuild, Stage::P2g(0), Stage::GridUpdate, Stage::G2p]
        );
        let usl = Ctx {
            transfer: Transfer::Gimp.code(),
            ..Ctx::default()
        };
        assert!(!plan.stages(&usl).contains(&Stage::MuslRemap));
        let musl = Ctx {
            update: crate::contract::update(Update::Musl),
            ..usl
        };
        assert_eq!(
            plan.stages(&musl),
            vec![
                Stage::Rebuild,
                Stage::P2g(0),
                Stage::GridUpdate,
                Stage::MuslRemap,
                Stage::G2p
            ]
        );
    }
}
