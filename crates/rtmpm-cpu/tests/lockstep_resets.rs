//! Worlds of a lockstep batch reset while the others run, on CPU worlds side by side
//! (`lockstep_support`): a reset world starts its clock again and the others are untouched (bit
//! for bit their separate runs); resets that cannot work are refused before any world changes.

mod common;
mod lockstep_support;

use common::bits;
use lockstep_support::{SLUMP, alone, unwritten};

#[test]
fn a_reset_world_starts_its_clock_again_and_the_others_are_untouched() {
    let (b, mut r) = unwritten(SLUMP);
    for _ in 0..2 {
        assert!(r.advance_frame().expect("frame").is_empty());
    }
    let start = b.worlds[1].sample_particles().expect("sample");
    r.reset_worlds(vec![(1, start.clone())]).expect("reset");
    assert_eq!(bits(r.worlds[1].particles()), bits(&start));
    assert_eq!((r.worlds[1].frame(), r.worlds[1].steps()), (0, 0));
    for _ in 0..2 {
        assert!(r.advance_frame().expect("frame").is_empty());
    }
    let w1 = &r.worlds[1];
    assert_eq!((w1.frame(), w1.steps()), (2, 100));
    assert!((w1.time() - 0.1).abs() < 1e-9, "{}", w1.time());
    // Static walls: the reset world, stepped at later times, is its separate run of 2 frames.
    assert_eq!(bits(w1.particles()), bits(&alone(&b.worlds[1], 2)));
    for w in [0, 2] {
        assert_eq!(r.worlds[w].frame(), 4);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 4)),
            "world {w} was touched by world 1's reset"
        );
    }
    // Resetting every world puts the shared clock back to 0.
    let starts = (0..3)
        .map(|w| (w, b.worlds[w].sample_particles().expect("sample")))
        .collect();
    r.reset_worlds(starts).expect("reset all");
    assert_eq!((r.sim.time, r.sim.step, r.sim.frame), (0.0, 0, 0));
    assert!(r.advance_frame().expect("frame").is_empty());
    for w in 0..3 {
        assert_eq!(bits(r.worlds[w].particles()), bits(&alone(&b.worlds[w], 1)));
    }
}

#[test]
fn resets_that_cannot_work_are_refused_before_any_world_changes() {
    // A collider moving with the shared clock: a partial reset is refused, naming it.
    let text = SLUMP.replace(
        "[batch]",
        "[[collider]]\nshape = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [0.1, 0.5, 0.5]\n\
         velocity = [0.1, 0.0, 0.0]\n[batch]",
    );
    let (b, mut r) = unwritten(&text);
    assert!(r.advance_frame().expect("frame").is_empty());
    let before = bits(r.worlds[1].particles());
    let start = |w: usize| b.worlds[w].sample_particles().expect("sample");
    let e = r.reset_worlds(vec![(1, start(1))]).unwrap_err().to_string();
    assert!(
        e.contains("collider 0 moves") && e.contains("reset every world"),
        "{e}"
    );
    assert_eq!(bits(r.worlds[1].particles()), before);
    assert_eq!(r.worlds[1].frame(), 1);
    let e = r.reset_worlds(vec![(5, start(0))]).unwrap_err().to_string();
    assert!(e.contains("no world 5: the batch has 3"), "{e}");
    let mut short = start(0);
    short.x.truncate(10);
    let e = r.reset_worlds(vec![(0, short)]).unwrap_err().to_string();
    assert!(e.contains("world 0 has") && e.contains("10 given"), "{e}");
    // Every world at once: the clock goes back to 0, so the collider is where it started.
    r.reset_worlds((0..3).map(|w| (w, start(w))).collect())
        .expect("reset all");
    assert_eq!(r.sim.step, 0);
}
