//! The lockstep batch driver on CPU worlds side by side (`lockstep_support`): a world that blows
//! up is frozen at its last good state (in a frame: its last frame, the frame run again from
//! there; in a call of steps: the call's start, its particle named in that world), and the
//! others end bit for bit as if it had never been there.

mod common;
mod lockstep_support;

use common::bits;
use lockstep_support::{SLUMP, alone, alone_steps, frames, lockstep, unwritten};
use rtmpm_driver::batch::WorldStatus;

#[test]
fn a_world_that_blows_up_is_frozen_and_the_others_end_as_without_it() {
    // World 1's body starts far too fast and blows up in frame 1; worlds 0 and 2 must end as
    // their separate runs, although frame 1 was stepped, rewound and stepped again.
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let (b, r) = lockstep(&text, &frames(3));
    match &r.worlds[1].status {
        WorldStatus::Frozen { frame, reason } => {
            assert_eq!(*frame, 0);
            assert!(reason.contains("blew up"), "{reason}");
        }
        other => panic!("world 1 should be frozen: {other:?}"),
    }
    let initial = b.worlds[1].sample_particles().expect("sample");
    assert_eq!(r.worlds[1].particles().x, initial.x, "kept at frame 0");
    for w in [0, 2] {
        assert_eq!(r.worlds[w].status, WorldStatus::Running);
        assert_eq!(
            bits(r.worlds[w].particles()),
            bits(&alone(&b.worlds[w], 3)),
            "world {w} differs from its separate run"
        );
    }
    assert_eq!(r.sim.frame, 3);
}

#[test]
fn a_world_that_blows_up_within_steps_is_frozen_and_the_others_go_on() {
    let text = SLUMP.replace(
        "\"material[0].yield_stress\" = [20, 150, 600]",
        "\"body[0].velocity\" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]",
    );
    let (b, mut r) = unwritten(&text);
    assert_eq!(r.advance_steps(10).expect("steps"), [1]);
    let WorldStatus::Frozen { reason, .. } = &r.worlds[1].status else {
        panic!("world 1 should be frozen");
    };
    // The particle is named by its index in world 1 (world 0, before it, holds as many: an
    // index over all worlds would be at least that count).
    let n = r.worlds[1].particles().len();
    let named: usize = reason
        .split("particle ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no particle in {reason}"));
    assert_eq!(r.worlds[0].particles().len(), n);
    assert!(named < n, "{reason}");
    assert_eq!(r.worlds[1].steps(), 0, "kept at its last good state");
    for w in [0, 2] {
        assert_eq!(r.worlds[w].steps(), 10);
        let separate = alone_steps(&b.worlds[w], 10);
        assert_eq!(bits(r.worlds[w].particles()), bits(&separate), "world {w}");
    }
}
