//! The bookkeeping of the redo ([`super`]): the worlds put since the last step and what the
//! next step's P2G needs for them ([`PutWorlds::plan`]), the redos counted, the A/B switch.

use crate::contract::{REDO_RANGES, RedoWorlds};

/// `RTMPM_BATCH_REDO=old`: after a put the next step redoes the P2G of every world, as before
/// the redo of the worlds put alone; for comparing the two in one binary
/// (bench/python_batch_gpu.py). Read once.
pub fn old_redo() -> bool {
    static OLD: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OLD.get_or_init(|| std::env::var("RTMPM_BATCH_REDO").is_ok_and(|v| v.trim() == "old"))
}

/// `RTMPM_BATCH_REDO=wave`: the partial redo launches `redo_clear` and `redo_p2g`, a warp a
/// pblock or warp-list entry over a full wave, as before `redo_clear_lanes` and
/// `redo_p2g_lanes` (`kernels/redo.cu`); for comparing the two in one binary. Read once.
pub fn wave_redo() -> bool {
    static WAVE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *WAVE.get_or_init(|| std::env::var("RTMPM_BATCH_REDO").is_ok_and(|v| v.trim() == "wave"))
}

/// What the next step's P2G needs after the puts since the last step.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Redo {
    /// No world was put: the last fused scatter holds every world.
    Nothing,
    /// Every world's P2G again, in the step (`CTL_P2G_PENDING`).
    Full,
    /// The P2G of these runs of worlds only, before the step.
    Worlds(Box<RedoWorlds>),
}

/// The worlds put since the last step (host bookkeeping; repeats allowed until
/// [`PutWorlds::plan`]).
#[derive(Debug, Default)]
pub struct PutWorlds {
    worlds: Vec<u32>,
}

impl PutWorlds {
    /// World `w` was put.
    pub fn add(&mut self, w: usize) {
        self.worlds.push(w as u32);
    }

    /// Forget every world listed (the step redoes every world's P2G anyway).
    pub fn clear(&mut self) {
        self.worlds.clear();
    }

    /// True when no world was put since the last plan.
    pub fn is_empty(&self) -> bool {
        self.worlds.is_empty()
    }

    /// What the next step needs for the worlds listed, of a batch of `total` worlds, the list
    /// emptied: [`Redo::Nothing`] for none; [`Redo::Full`] when more than half of the worlds
    /// were put (the partial redo tests every pblock and warp entry against the runs and costs
    /// two launches of its own; past half of the worlds it would save less than half of the
    /// P2G, which the step's full redo does inside its own launches: not worth it, not
    /// measured finer) or when they make more than [`REDO_RANGES`] runs of consecutive worlds;
    /// else the runs, in world order.
    pub fn plan(&mut self, total: usize) -> Redo {
        let mut w = std::mem::take(&mut self.worlds);
        w.sort_unstable();
        w.dedup();
        if w.is_empty() {
            self.worlds = w;
            return Redo::Nothing;
        }
        let many = 2 * w.len() > total;
        let mut r = RedoWorlds::default();
        let mut full = many;
        for &x in &w {
            let n = r.count as usize;
            if n > 0 && r.hi[n - 1] == x {
                r.hi[n - 1] = x + 1;
            } else if n == REDO_RANGES {
                full = true;
                break;
            } else {
                (r.lo[n], r.hi[n], r.count) = (x, x + 1, r.count + 1);
            }
        }
        w.clear();
        self.worlds = w;
        if full {
            Redo::Full
        } else {
            Redo::Worlds(Box::new(r))
        }
    }
}

/// How the P2G after puts was redone so far ([`CudaBatch::redo_counts`]): plans of the
/// worlds put alone (queued; the kernels skip them when the step rebuilds, see the module)
/// and full redos asked of the step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RedoCounts {
    /// Partial redos queued.
    pub partial: u64,
    /// Full redos asked for.
    pub full: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn runs(r: &Redo) -> Vec<(u32, u32)> {
        match r {
            Redo::Worlds(r) => (0..r.count as usize).map(|i| (r.lo[i], r.hi[i])).collect(),
            _ => panic!("not a partial redo: {r:?}"),
        }
    }

    /// The worlds put make runs of consecutive worlds in world order, whatever the order and
    /// repeats; the list is empty after a plan (the next plan is `Nothing`).
    #[test]
    fn worlds_put_make_runs_in_world_order_and_the_list_empties() {
        let mut p = PutWorlds::default();
        assert_eq!(p.plan(256), Redo::Nothing);
        for w in [9, 3, 4, 200, 3, 5, 11, 10] {
            p.add(w);
        }
        let plan = p.plan(256);
        assert_eq!(runs(&plan), vec![(3, 6), (9, 12), (200, 201)]);
        assert!(p.is_empty());
        assert_eq!(p.plan(256), Redo::Nothing);
        // The runs past the count are zero: the kernels read `count` runs only.
        if let Redo::Worlds(r) = plan {
            assert!(r.lo[3..].iter().chain(&r.hi[3..]).all(|&x| x == 0));
        }
    }

    /// Half of the worlds put is still partial, one more is the full redo; repeats count once.
    #[test]
    fn more_than_half_of_the_worlds_put_is_the_full_redo() {
        let mut p = PutWorlds::default();
        (0..4).for_each(|w| p.add(2 * w));
        p.add(0);
        assert_eq!(runs(&p.plan(8)), vec![(0, 1), (2, 3), (4, 5), (6, 7)]);
        (0..5).for_each(|w| p.add(w));
        assert_eq!(p.plan(8), Redo::Full);
        assert!(p.is_empty());
        p.add(0);
        assert_eq!(p.plan(1), Redo::Full, "the one world of a batch of one");
    }

    /// `REDO_RANGES` runs fit the kernels' argument, one more is the full redo.
    #[test]
    fn more_runs_than_the_argument_holds_is_the_full_redo() {
        let mut p = PutWorlds::default();
        (0..REDO_RANGES).for_each(|i| p.add(3 * i));
        let plan = p.plan(1000);
        let r = runs(&plan);
        assert_eq!(r.len(), REDO_RANGES);
        assert_eq!(
            r[REDO_RANGES - 1],
            (3 * REDO_RANGES as u32 - 3, 3 * REDO_RANGES as u32 - 2)
        );
        (0..=REDO_RANGES).for_each(|i| p.add(3 * i));
        assert_eq!(p.plan(1000), Redo::Full);
        // A long run is one range, however many worlds.
        (100..400).for_each(|w| p.add(w));
        assert_eq!(runs(&p.plan(1000)), vec![(100, 400)]);
    }
}
