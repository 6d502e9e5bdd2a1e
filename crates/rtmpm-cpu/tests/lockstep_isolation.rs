//! The lockstep batch driver (`rtmpm_driver::batch::lockstep`: every world held by one backend,
//! one time step for all, as the GPU runs a batch) on CPU worlds side by side
//! (`lockstep_support`): at a fixed step every world gives, bit for bit, its separate run, in
//! frames and in calls of steps that cross frame ends.

mod common;
mod lockstep_support;

use common::bits;
use lockstep_support::{SLUMP, alone, alone_steps, frames, lockstep, unwritten};

#[test]
fn at_a_fixed_step_every_world_is_its_separate_run_bit_for_bit() {
    let (b, r) = lockstep(SLUMP, &frames(3));
    assert_eq!((r.sim.frame, r.running()), (3, 3));
    let mut seen = Vec::new();
    for (w, world) in r.worlds.iter().enumerate() {
        let separate = alone(&b.worlds[w], 3);
        assert!(separate.len() > 300);
        assert_eq!(bits(world.particles()), bits(&separate), "world {w}");
        seen.push(bits(&separate));
    }
    assert_ne!(seen[0], seen[1], "the sweep matters");
}

#[test]
fn steps_cross_frame_ends_and_each_world_is_its_separate_run() {
    let (b, mut r) = unwritten(SLUMP);
    // 70 steps of 1 ms: a frame (50 steps) and 20 more, in two calls.
    assert!(r.advance_steps(33).expect("steps").is_empty());
    assert!(r.advance_steps(37).expect("steps").is_empty());
    assert_eq!((r.sim.step, r.sim.frame), (70, 1));
    for (w, world) in r.worlds.iter().enumerate() {
        assert_eq!((world.steps(), world.frame()), (70, 1));
        // 20 steps of the f32 dt (1e-3 + 4.7e-11) past the frame's end at 0.05 s.
        assert!((world.time() - 0.07).abs() < 1e-8, "{}", world.time());
        assert_eq!(
            bits(world.particles()),
            bits(&alone_steps(&b.worlds[w], 70)),
            "world {w}"
        );
    }
}
