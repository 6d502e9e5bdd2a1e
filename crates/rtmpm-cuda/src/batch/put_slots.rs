//! Which slots a put's launch visits (`kernels/batch.cu`): every slot of the batch, each tested
//! by its particle's id (`batch_put_world`, as first written), or the slots of the put worlds'
//! gblocks only (`batch_put_gblocks`, the default), and when the second may be used.
//!
//! Why: the slots are in the last rebuild's order, a world's spread over the whole state, so
//! `batch_put_world` reads the id of every slot of every world (a full wave of threads) for a
//! reset of a few worlds, and each slot put then loads its words one after another. A reset of
//! 4 worlds of 1,024 particles in a batch of 256 took 18.5 us of device time a call on an H200
//! (session 16's timeline). `batch_put_gblocks` tests the gblocks instead (a thread for eight,
//! the first slot of each), puts the slots of the put worlds' gblocks a lane a slot, all of a
//! slot's loads at once, and finds the gblock of a slot without a search.
//!
//! The gblocks' slot ranges. The last rebuild sorted the slots by gblock (gblock `g`'s from its
//! bucket start to the next gblock's), and a gblock's slots hold its world's particles only when
//! every particle sorted lay within its world's stripe along x: then its stencil base's block is
//! its world's ([`crate::batch::layout::world_stride`]: a stripe holds every block a position of
//! the domain's x range reaches, the neighbour blocks of the free zone too). G2P clamps every
//! particle to the domain, so a rebuild of particles that have all been through a G2P (or were put
//! within the domain's x range) sorts them so. Two steps after anything else (the batch's first
//! step, [`super::CudaBatch::restore_point`]: the state in the point's order, not the last
//! rebuild's; [`super::CudaBatch::drop_queued_steps`]: the error word cleared after a rebuild it
//! may have stopped; a put of a particle outside the domain's x range: the next rebuild may sort it
//! into another world's block, and the G2P after clamps it and asks for the rebuild that sorts it
//! back), every rebuild since has been of such particles. Until then ([`PutSlots::trusted`]), and
//! with `RTMPM_BATCH_PUT=old` ([`old_puts`]), a put launches `batch_put_world` over every slot. The
//! kernel itself tests every slot where no rebuild has sorted the slots, after an error and where
//! every step rebuilds. The launch: `CudaBatch::launch_put` (`batch/put.rs`). Both kernels write
//! the same words into the same slots and leave the same rebuild flag (the zone of the same gblock
//! checked).

use rtmpm_physics::Particles;

/// `RTMPM_BATCH_PUT=old`: every put launches `batch_put_world` over every slot, as before the
/// put over the put worlds' gblocks; for comparing the two in one binary
/// (bench/python_batch_gpu.py). Read once.
pub fn old_puts() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_PUT").is_ok_and(|v| v.trim() == "old"))
}

/// Steps after which the gblocks' slot ranges hold one world each again (see the module).
const DOUBT_STEPS: u8 = 2;

/// Whether the gblocks' slot ranges of the last rebuild can be trusted to hold one world each
/// (see the module): the steps still to go before they can.
#[derive(Clone, Copy, Debug)]
pub struct PutSlots {
    doubt: u8,
}

impl Default for PutSlots {
    /// A batch before its first step: not trusted.
    fn default() -> Self {
        PutSlots { doubt: DOUBT_STEPS }
    }
}

impl PutSlots {
    /// The slots may have been sorted from particles outside their stripes, or into another
    /// order than the last rebuild's: not trusted for the next two steps.
    pub fn doubt(&mut self) {
        self.doubt = DOUBT_STEPS;
    }

    /// A step was taken.
    pub fn stepped(&mut self) {
        self.doubt = self.doubt.saturating_sub(1);
    }

    /// The ranges can be used.
    pub fn trusted(&self) -> bool {
        self.doubt == 0
    }
}

/// Every particle of `p` lies within `[lo, hi]` along x (what a put may leave without doubting
/// the slot ranges; NaN does not).
pub(super) fn within_x(p: &Particles, lo: f32, hi: f32) -> bool {
    p.x.iter().all(|x| x.x >= lo && x.x <= hi)
}

#[cfg(test)]
mod tests {
    use super::{PutSlots, within_x};
    use rtmpm_physics::Particles;
    use rtmpm_physics::math::Vec3;

    /// Not trusted at first and for two steps after each doubt, whatever came before; trusted
    /// from the second step on.
    #[test]
    fn the_ranges_are_trusted_two_steps_after_the_last_doubt() {
        let mut s = PutSlots::default();
        assert!(!s.trusted(), "before the first step");
        s.stepped();
        assert!(!s.trusted(), "after one step");
        s.stepped();
        assert!(s.trusted(), "after two");
        s.stepped();
        assert!(s.trusted());
        s.doubt();
        assert!(!s.trusted(), "after a doubt");
        s.stepped();
        s.doubt();
        s.stepped();
        assert!(!s.trusted(), "one step after the last doubt");
        s.stepped();
        assert!(s.trusted(), "two steps after it");
    }

    /// Within the x range, its ends included; y and z are not looked at; NaN is not within.
    #[test]
    fn within_x_takes_the_range_s_ends_and_not_nan() {
        let mut p = Particles::default();
        for x in [0.0, 0.5, 1.0] {
            p.push(Vec3::new(x, -7.0, 9.0), Vec3::ZERO, 1.0, 1.0, 0, 0.0);
        }
        assert!(within_x(&p, 0.0, 1.0));
        assert!(!within_x(&p, 0.0, 0.99));
        assert!(!within_x(&p, 0.01, 1.0));
        p.x[1].x = f32::NAN as _;
        assert!(!within_x(&p, 0.0, 1.0));
        assert!(within_x(&Particles::default(), 0.0, 1.0), "no particles");
    }
}
