//! The put over the put worlds' gblocks (`batch_put_gblocks`, `kernels/batch.cu`) against the
//! put of every slot (`batch_put_world`), and when the batch uses which
//! (`rtmpm_cuda::batch::PutSlots`) (needs a GPU; skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_put_slots -- --include-ignored --nocapture`.

mod common;

use common::batch::{DT, bit_identical, precise, wedge_worlds};
use common::gpu;
use rtmpm_cuda::CudaOptions;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_physics::Particles;
use rtmpm_physics::math::{Mat3, Vec3};

/// World `w`'s particles of `p` changed in every word a put writes, and the last `13 w` dropped
/// (each world its own count): moved a tenth of a cell up (every particle still in its block's
/// free zone, the domain's x range), moving at `(w + 1) / 10` m/s along y, `C` and `F` and the
/// plastic word
/// nudged, mass and initial volume scaled.
fn changed(p: &Particles, w: usize, dx: f32) -> Particles {
    let mut q = Particles::default();
    for i in 0..p.len() - 13 * w {
        q.push(
            p.x[i] + Vec3::new(0.0, 0.1 * dx, 0.0),
            Vec3::new(0.0, 0.1 * (w + 1) as f32, 0.0),
            p.mass[i] * 1.25,
            p.vol0[i] * 0.75,
            p.material[i],
            p.plastic[i] + 0.01,
        );
        let at = q.len() - 1;
        (q.c[at], q.f[at]) = (
            p.c[i] + Mat3::IDENTITY * 0.5,
            p.f[i] * 1.001 + Mat3::from_cols(Vec3::ZERO, Vec3::X * 1e-3, Vec3::ZERO),
        );
    }
    q
}

/// The state's words as stored (every slot, in the last rebuild's order).
fn state(b: &mut CudaBatch) -> Vec<u8> {
    b.backend().read_state_bytes().expect("state").0
}

/// A put over the put worlds' gblocks (the default once the batch has stepped twice) leaves the
/// state, every word of every slot, bit for bit as the put of every slot then leaves it, in f32
/// and f64: given states of runs of worlds (0 and 2-3, `put_worlds`: each run's own image) and
/// a reset from the kept image (1 and 4, `put_initial`: rows of the whole batch). The second
/// put writes every word of the put worlds' particles again, so a slot or a word the first left
/// out, or a word it put wrong, would differ; the worlds not put are the same as before bit for
/// bit (a slot of theirs written would show) and the worlds put hold what was given. About 10 s
/// on an H200 (most of it the programs' compiles on a cold cache); a compute-sanitizer memcheck
/// target of `batch_put_gblocks`.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_put_over_the_gblocks_leaves_what_the_put_of_every_slot_leaves() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(5);
    let dx = worlds[0].dx;
    let start: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let p0: Vec<Particles> = start
        .iter()
        .enumerate()
        .map(|(w, p)| changed(p, w, 0.0))
        .collect();
    for f64 in [false, true] {
        let options = CudaOptions { f64, ..precise() };
        let mut b = match CudaBatch::new(&worlds, &p0, options) {
            Ok(b) => b,
            Err(e) => {
                assert!(f64, "the f32 batch: {e}");
                println!("no f64 batch of these worlds ({e}): f32 only");
                continue;
            }
        };
        assert!(!b.gblock_put_next(), "f64 {f64}: before the first step");
        assert!(b.keep_initial(&p0).expect("keep"), "the image kept");
        for s in 0..20 {
            b.step(DT, s as f32 * DT).expect("step");
        }
        assert!(b.gblock_put_next(), "f64 {f64}: after 20 steps");
        let before = b.read_worlds().expect("read");
        let given: Vec<(usize, Particles)> = [0, 2, 3]
            .into_iter()
            .map(|w| (w, changed(&before[w], 0, dx)))
            .collect();
        b.put_worlds(&given).expect("put over the gblocks");
        assert!(b.gblock_put_next(), "f64 {f64}: a put within the domain");
        let over_gblocks = state(&mut b);
        let put = b.read_worlds().expect("read");
        b.set_gblock_puts(false);
        b.put_worlds(&given).expect("put of every slot");
        assert!(
            over_gblocks == state(&mut b),
            "f64 {f64}: the put over the gblocks differs from the put of every slot"
        );
        for (w, p) in &given {
            assert!(
                put[*w].x == p.x && put[*w].v == p.v && put[*w].mass == p.mass,
                "f64 {f64}: world {w} does not hold what was given"
            );
        }
        for w in [1, 4] {
            assert!(
                bit_identical(&put[w], &before[w]),
                "f64 {f64}: world {w} touched"
            );
        }
        b.set_gblock_puts(true);
        assert!(b.put_initial(&[4, 1]).expect("reset over the gblocks"));
        let over_gblocks = state(&mut b);
        let reset = b.read_worlds().expect("read");
        b.set_gblock_puts(false);
        assert!(b.put_initial(&[4, 1]).expect("reset of every slot"));
        assert!(
            over_gblocks == state(&mut b),
            "f64 {f64}: the reset over the gblocks differs from the reset of every slot"
        );
        for w in [1, 4] {
            assert!(
                reset[w].x == p0[w].x && reset[w].v == p0[w].v,
                "f64 {f64}: world {w} is not its initial particles"
            );
        }
        for w in [0, 2, 3] {
            assert!(
                bit_identical(&reset[w], &put[w]),
                "f64 {f64}: world {w} touched by the reset"
            );
        }
    }
}

/// When a put may use the gblocks' slot ranges (`CudaBatch::gblock_put_next`): not before two
/// steps, not for two steps after a rewind (the state in the point's order) or after a put of a
/// particle outside the domain's x range; a put within it keeps them. The puts in doubt (over
/// every slot) still put what they are given. About 5 s on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn the_gblock_put_waits_two_steps_after_a_rewind_or_a_put_outside_the_domain() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(3);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    let mut t = 0.0;
    let mut step = |b: &mut CudaBatch| {
        b.step(DT, t).expect("step");
        t += DT;
    };
    step(&mut b);
    assert!(!b.gblock_put_next(), "after one step");
    step(&mut b);
    assert!(b.gblock_put_next(), "after two steps");
    assert!(b.save_point().expect("point"));
    step(&mut b);
    b.restore_point().expect("rewind");
    assert!(!b.gblock_put_next(), "after a rewind");
    step(&mut b);
    step(&mut b);
    assert!(b.gblock_put_next(), "two steps after a rewind");
    b.put_world(1, &p0[1]).expect("put within the domain");
    assert!(b.gblock_put_next(), "a put within the domain");
    let mut out = p0[1].clone();
    let hi = worlds[1].domain_max.x;
    out.x[0].x = hi + 0.5 * worlds[1].dx;
    b.put_world(1, &out).expect("put outside the domain");
    assert!(!b.gblock_put_next(), "a put outside the domain's x range");
    assert!(
        b.read_worlds().expect("read")[1].x == out.x,
        "the put in doubt put what it was given"
    );
    step(&mut b);
    step(&mut b);
    assert!(b.gblock_put_next(), "two steps after it");
    assert!(b.bad_world().expect("check").is_none());
}
