//! The lockstep batch driver's rewind point on CPU worlds side by side (`lockstep_support`): a
//! backend that keeps its own rewind point (as the GPU does on the device) is read only when its
//! particles are needed, and rewinds to that point bit for bit as the host's copy does; a frozen
//! world that fails again ends the call with an error, not a loop.

mod common;
mod lockstep_support;

use common::bits;
use lockstep_support::{SLUMP, SideBySide, alone_steps, unwritten_keeping};
use rtmpm_driver::batch::WorldStatus;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_scene::BatchScene;
use rtmpm_sim::Particles;

#[test]
fn a_backend_keeping_its_rewind_point_is_read_only_when_its_particles_are_needed() {
    let (b, mut r) = unwritten_keeping(SLUMP, true);
    assert_eq!(r.sim.backend.reads, 1, "the state at the start");
    // 70 calls of one step (a frame end crossed): nothing read back.
    for _ in 0..70 {
        assert!(r.advance_steps(1).expect("step").is_empty());
    }
    assert_eq!(r.sim.backend.reads, 1, "no call read the worlds");
    for world in &r.worlds {
        assert_eq!((world.steps(), world.frame()), (70, 1));
    }
    r.sync().expect("sync");
    assert_eq!(r.sim.backend.reads, 2);
    r.sync().expect("sync again");
    assert_eq!(r.sim.backend.reads, 2, "a second sync reads nothing");
    for (w, world) in r.worlds.iter().enumerate() {
        assert_eq!(
            bits(world.particles()),
            bits(&alone_steps(&b.worlds[w], 70)),
            "world {w}"
        );
    }
    // A checkpoint needs the particles: it reads them, once.
    assert!(r.advance_steps(3).expect("steps").is_empty());
    let dir = std::env::temp_dir().join(format!("rtmpm-lockstep-lazy-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    r.checkpoint(&dir, SLUMP, "slump.toml").expect("checkpoint");
    std::fs::remove_dir_all(&dir).expect("clean up");
    assert_eq!(r.sim.backend.reads, 3);
    assert_eq!(
        bits(r.worlds[0].particles()),
        bits(&alone_steps(&b.worlds[0], 73))
    );
}

/// One run of blow-ups and resets in calls of a few steps: world 2 made to blow up within the
/// second call (its particles sped up to 10^5 m/s before its 10th step, behind the driver's
/// back), a call, world 1 reset to a body at 10^5 m/s (it blows up in the next call, world 2
/// frozen before it), then world 2 reset to its start; the batch at the end, synced, and every
/// world as the backend held it after world 1's blow-up (the frozen ones parked and stepped).
fn resets_and_blow_ups(keeps_point: bool) -> (BatchScene, LockstepRun<SideBySide>, Vec<Particles>) {
    let (b, mut r) = unwritten_keeping(SLUMP, keeps_point);
    r.sim.backend.poison = Some((2, 9));
    assert!(r.advance_steps(7).expect("steps").is_empty());
    assert_eq!(r.advance_steps(5).expect("steps"), [2]);
    // Frozen at its last good state, the start of the call: its separate run of 7 steps.
    assert_eq!(
        bits(r.worlds[2].particles()),
        bits(&alone_steps(&b.worlds[2], 7)),
        "world 2 keeps its state of the call's start"
    );
    assert!(r.advance_steps(3).expect("steps").is_empty());
    let mut fast = b.worlds[1].sample_particles().expect("sample");
    fast.v
        .iter_mut()
        .for_each(|v| *v = glam::Vec3::new(1e5, 0.0, 0.0));
    r.reset_worlds(vec![(1, fast)]).expect("reset");
    assert_eq!(r.advance_steps(4).expect("steps"), [1]);
    let held = r.sim.backend.read_all().expect("read");
    let start = b.worlds[2].sample_particles().expect("sample");
    r.reset_worlds(vec![(2, start)]).expect("reset");
    assert!(r.advance_steps(6).expect("steps").is_empty());
    r.sync().expect("sync");
    (b, r, held)
}

#[test]
fn a_rewind_to_the_backends_own_point_equals_the_host_rewind_bit_for_bit() {
    let (b, host, host_held) = resets_and_blow_ups(false);
    let (_, kept, kept_held) = resets_and_blow_ups(true);
    // The backend held the same worlds after the second rewind, the frozen world 2 (parked
    // again from its last good state, as the host's rewind parks it) among them.
    for w in 0..3 {
        assert_eq!(
            bits(&kept_held[w]),
            bits(&host_held[w]),
            "world {w} as held"
        );
    }
    for w in 0..3 {
        let (a, k) = (&host.worlds[w], &kept.worlds[w]);
        assert_eq!(k.status, a.status, "world {w}");
        assert_eq!(bits(k.particles()), bits(a.particles()), "world {w}");
        assert_eq!((k.steps(), k.frame()), (a.steps(), a.frame()), "world {w}");
        assert_eq!(k.time().to_bits(), a.time().to_bits(), "world {w}");
    }
    assert!(matches!(kept.worlds[1].status, WorldStatus::Frozen { .. }));
    assert_eq!(kept.worlds[2].steps(), 6);
    assert_eq!(kept.worlds[1].steps(), 0, "frozen at its reset");
    // World 0 went through both rewinds: bit for bit its separate run of 25 steps (in f32
    // builds: a rewind puts the worlds back through the particles' f32 interface, so an f64
    // world rewound after its first steps goes on from its state rounded, in both modes alike);
    // world 2 is its separate run of 6 steps from its reset.
    if cfg!(not(feature = "f64")) {
        assert_eq!(
            bits(kept.worlds[0].particles()),
            bits(&alone_steps(&b.worlds[0], 25))
        );
    }
    assert_eq!(
        bits(kept.worlds[2].particles()),
        bits(&alone_steps(&b.worlds[2], 6))
    );
    // A frozen world keeps its last good state: world 1's fast start.
    let fast = kept.worlds[1].particles();
    assert!(
        fast.v.iter().all(|v| v.x == 1e5),
        "world 1 keeps its reset state"
    );
    // The host's copy read the worlds after every call; the backend's point only when needed
    // (the start, the first rewind, the second, the end's sync).
    assert!(
        kept.sim.backend.reads < host.sim.backend.reads,
        "{} reads against {}",
        kept.sim.backend.reads,
        host.sim.backend.reads
    );
    assert_eq!(kept.sim.backend.reads, 4);
}

/// A world that fails again once frozen and parked (here sped up to 10^5 m/s before every step,
/// behind the driver's back) ends the call with an error naming it, after one rewind, whether
/// the rewind point is the host's copy or the backend's own: the driver never rewinds twice for
/// one world (stepping the same blow-up again and again).
#[test]
fn a_frozen_world_that_fails_again_ends_the_call_with_an_error_not_a_loop() {
    for keeps_point in [false, true] {
        let (_, mut r) = unwritten_keeping(SLUMP, keeps_point);
        r.sim.backend.relapse = Some(1);
        let e = r
            .advance_steps(5)
            .expect_err("a parked world that fails again ends the call");
        let e = format!("{e:#}");
        assert!(
            e.contains("world 1 (its particle") && e.contains("failed again"),
            "keeps_point {keeps_point}: {e}"
        );
        assert!(e.contains("blew up"), "the failure itself is said: {e}");
        // The failed step, then the step again from the rewind point (world 1 frozen), which
        // fails in world 1 once more: two steps, one rewind.
        assert_eq!(r.sim.backend.steps, 2, "keeps_point {keeps_point}");
        assert!(matches!(
            r.worlds[1].status,
            WorldStatus::Frozen { frame: 0, .. }
        ));
        assert_eq!(r.running(), 2);
    }
}

/// How calls check their steps: at once (`defer` false), or returning before their last check
/// ([`LockstepRun::set_deferred_checks`]) with the backend keeping the next call's point in a
/// second slot (`two`: saved before the last call's check is made), queueing its checks' reads
/// (`queues`, `Worlds::queue_check`), and calls queueing their steps before the last call's
/// check where they can (`pipeline`, [`LockstepRun::set_pipelined`]: with `two` and `queues`).
#[derive(Clone, Copy, Debug)]
struct Mode {
    defer: bool,
    two: bool,
    queues: bool,
    pipeline: bool,
}

const AT_ONCE: Mode = Mode {
    defer: false,
    two: false,
    queues: false,
    pipeline: false,
};

/// The deferred modes: one slot, two, two with queued reads, and those pipelined.
const DEFERRED: [Mode; 4] = [
    Mode {
        defer: true,
        two: false,
        queues: false,
        pipeline: true,
    },
    Mode {
        defer: true,
        two: true,
        queues: false,
        pipeline: true,
    },
    Mode {
        defer: true,
        two: true,
        queues: true,
        pipeline: false,
    },
    Mode {
        defer: true,
        two: true,
        queues: true,
        pipeline: true,
    },
];

impl Mode {
    /// Run `r` this way (its checks late, as the GPU's).
    fn set(self, r: &mut LockstepRun<SideBySide>) {
        r.sim.backend.checks_late = true;
        r.sim.backend.two_points = self.two;
        r.sim.backend.queues = self.queues;
        r.set_pipelined(self.pipeline);
        r.set_deferred_checks(self.defer).expect("defer");
    }

    /// What three calls whose second blows up leave counted on the backend: (next points
    /// saved, taken up, pipelined steps dropped). The second and third calls keep their points
    /// ahead; the second's is taken up (the first call's check passes), the third's dropped
    /// (the second's check rewinds), with the third's steps when pipelined.
    fn counts(self) -> (usize, usize, usize) {
        match (self.two, self.queues && self.pipeline) {
            (false, _) => (0, 0, 0),
            (true, false) => (2, 1, 0),
            (true, true) => (2, 1, 1),
        }
    }
}

/// Calls of steps on worlds whose check is not cheap (made at a call's end): world 2 made to
/// blow up within the second call, the worlds `reset` reset after that call, then a third
/// call and a sync, the checks made as `mode` says. The worlds each call returned frozen, and
/// the run.
fn late_checks(mode: Mode, reset: &[usize]) -> (Vec<Vec<usize>>, LockstepRun<SideBySide>) {
    let (b, mut r) = unwritten_keeping(SLUMP, true);
    let defer = mode.defer;
    mode.set(&mut r);
    r.sim.backend.poison = Some((2, 9));
    let mut calls = vec![r.advance_steps(7).expect("steps")];
    calls.push(r.advance_steps(5).expect("steps"));
    assert_eq!(r.check_pending(), defer);
    let starts = reset
        .iter()
        .map(|&w| (w, b.worlds[w].sample_particles().expect("sample")))
        .collect();
    r.reset_worlds(starts).expect("reset");
    calls.push(r.advance_steps(6).expect("steps"));
    r.sync().expect("sync");
    assert!(!r.check_pending(), "a sync makes the pending check");
    (calls, r)
}

#[test]
fn calls_returning_before_their_check_end_as_calls_that_check_at_once() {
    let (at_once, mut a) = late_checks(AT_ONCE, &[1]);
    assert_eq!(at_once, [vec![], vec![2], vec![]]);
    let ha = a.sim.backend.read_all().expect("read");
    // With a second slot, each call after the first keeps its point before the last call's
    // check: the third call's before the check that finds the second's blow-up (the rewind
    // then goes back to the second call's point, and the third keeps its point again);
    // pipelined, the third call's steps are taken before that check too, then dropped.
    for mode in DEFERRED {
        let two = format!("{mode:?}");
        let (deferred, mut d) = late_checks(mode, &[1]);
        // The blow-up is returned by the call that found it: the one after its steps when
        // deferred.
        assert_eq!(deferred, [vec![], vec![], vec![2]], "two {two}");
        // The reset made while the check was pending was made again after the rewind: every
        // world ends bit for bit as when the second call found the blow-up itself.
        for w in 0..3 {
            let (x, y) = (&a.worlds[w], &d.worlds[w]);
            assert_eq!(y.status, x.status, "two {two}: world {w}");
            assert_eq!(
                bits(y.particles()),
                bits(x.particles()),
                "two {two}: world {w}"
            );
            assert_eq!(
                (y.steps(), y.frame()),
                (x.steps(), x.frame()),
                "two {two}: world {w}"
            );
            assert_eq!(
                y.time().to_bits(),
                x.time().to_bits(),
                "two {two}: world {w}"
            );
        }
        assert!(matches!(d.worlds[2].status, WorldStatus::Frozen { .. }));
        assert_eq!(d.worlds[1].steps(), 6, "world 1 from its reset");
        assert_eq!(d.worlds[0].steps(), 18);
        // The backends hold the same worlds (the frozen one parked alike).
        let hd = d.sim.backend.read_all().expect("read");
        for w in 0..3 {
            assert_eq!(bits(&hd[w]), bits(&ha[w]), "two {two}: world {w} as held");
        }
        let b = &d.sim.backend;
        assert_eq!((b.next_saves, b.next_uses, b.drops), mode.counts(), "{two}");
    }
}

/// Calls of 45, 10 and 6 steps (the second crossing the frame end at step 50), world 2 made to
/// blow up in step `poison` of the second, world 1 reset after it; checks deferred with `defer`,
/// and with `queues` the backend queues what a check reads (`Worlds::queue_check`: the frame
/// end's check inside the call queued too, made as the next call begins, at that frame end's
/// clock). The worlds each call returned frozen, and the run, synced.
fn frame_end_inside(mode: Mode, poison: usize) -> (Vec<Vec<usize>>, LockstepRun<SideBySide>) {
    let (b, mut r) = unwritten_keeping(SLUMP, true);
    mode.set(&mut r);
    r.sim.backend.poison = Some((2, poison));
    let mut calls = vec![r.advance_steps(45).expect("steps")];
    calls.push(r.advance_steps(10).expect("steps"));
    let start = vec![(1, b.worlds[1].sample_particles().expect("sample"))];
    r.reset_worlds(start).expect("reset");
    calls.push(r.advance_steps(6).expect("steps"));
    r.sync().expect("sync");
    assert!(
        r.sim.backend.queued.is_empty(),
        "every queued check was made"
    );
    (calls, r)
}

#[test]
fn checks_queued_at_a_frame_end_inside_a_call_end_as_checks_made_at_once() {
    // World 2 blows up in step 48 (before the frame end at 50: found by that frame end's check)
    // or in step 53 (after it: found by the call's last check).
    for poison in [47, 52] {
        let (at_once, a) = frame_end_inside(AT_ONCE, poison);
        assert_eq!(at_once, [vec![], vec![2], vec![]], "poison {poison}");
        for mode in DEFERRED {
            let queues = mode.queues;
            let (deferred, d) = frame_end_inside(mode, poison);
            let what = format!("poison {poison}, {mode:?}");
            // Found a call late, but by a frame end's check inside the call that is not queued
            // (made at once, as before the queued checks).
            let late = queues || poison > 50;
            let expected = if late {
                [vec![], vec![], vec![2]]
            } else {
                [vec![], vec![2], vec![]]
            };
            assert_eq!(deferred, expected, "{what}");
            // Said as at once (the frame end's step and time where that check found it).
            for w in 0..3 {
                let (x, y) = (&a.worlds[w], &d.worlds[w]);
                assert_eq!(y.status, x.status, "{what}: world {w}");
                assert_eq!(
                    bits(y.particles()),
                    bits(x.particles()),
                    "{what}: world {w}"
                );
                assert_eq!(
                    (y.steps(), y.frame()),
                    (x.steps(), x.frame()),
                    "{what}: world {w}"
                );
                assert_eq!(y.time().to_bits(), x.time().to_bits(), "{what}: world {w}");
            }
            assert_eq!(d.sim.step, a.sim.step, "{what}");
        }
    }
}

/// World 2 reset after a first call (its origin then), made to blow up in the second, every
/// world reset after that call (the shared clock back to 0), a third call; with `defer` the
/// blow-up's check is pending through that reset. The worlds each call returned frozen, and
/// the run, synced.
fn reset_all_pending(mode: Mode) -> (Vec<Vec<usize>>, LockstepRun<SideBySide>) {
    let (b, mut r) = unwritten_keeping(SLUMP, true);
    mode.set(&mut r);
    r.sim.backend.poison = Some((2, 9));
    let start = |w: usize| (w, b.worlds[w].sample_particles().expect("sample"));
    let mut calls = vec![r.advance_steps(7).expect("steps")];
    r.reset_worlds(vec![start(2)]).expect("reset");
    calls.push(r.advance_steps(5).expect("steps"));
    r.reset_worlds((0..3).map(start).collect()).expect("reset");
    calls.push(r.advance_steps(6).expect("steps"));
    r.sync().expect("sync");
    (calls, r)
}

#[test]
fn a_reset_of_every_world_while_a_check_is_pending_ends_as_after_the_check() {
    // The check is made at the clock the steps ended at (not the reset's 0: the blow-up is
    // said at its world's own step, after its reset), then the reset made again.
    let (at_once, a) = reset_all_pending(AT_ONCE);
    assert_eq!(at_once, [vec![], vec![2], vec![]]);
    for mode in DEFERRED {
        let two = format!("{mode:?}");
        let (deferred, d) = reset_all_pending(mode);
        assert_eq!(deferred, [vec![], vec![], vec![2]], "two {two}");
        for w in 0..3 {
            let (x, y) = (&a.worlds[w], &d.worlds[w]);
            assert_eq!(y.status, x.status, "two {two}: world {w}");
            assert_eq!(
                bits(y.particles()),
                bits(x.particles()),
                "two {two}: world {w}"
            );
            assert_eq!(
                (y.steps(), y.time().to_bits()),
                (6, x.time().to_bits()),
                "two {two}: world {w}"
            );
        }
        assert_eq!(d.sim.step, 6);
        let b = &d.sim.backend;
        assert_eq!((b.next_saves, b.next_uses, b.drops), mode.counts(), "{two}");
    }
}
