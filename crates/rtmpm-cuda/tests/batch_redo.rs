//! The P2G of the worlds put since the last step redone for those worlds alone
//! (`CudaBatch::redo_puts`, `kernels/redo.cu`) against the full redo of every world
//! (`CudaBatch::set_full_redo`, as with `RTMPM_BATCH_REDO=old`), in f32 and f64 (needs a GPU;
//! skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_redo -- --nocapture`.

mod common;

use common::batch::{agrees, precise, sand_bed};
use common::gpu;
use rtmpm_cuda::CudaOptions;
use rtmpm_cuda::batch::{CudaBatch, Redo};
use rtmpm_physics::Particles;
use rtmpm_physics::math::IVec3;
use rtmpm_scene::Scene;
use std::collections::HashMap;

/// Worlds of the tests: six sand beds (9,408 particles each), their time step.
fn beds() -> (Vec<Scene>, Vec<Particles>, f32) {
    let world = Scene::from_toml(&sand_bed(0.109375), "sand_bed").expect("scene");
    let worlds = vec![world; 6];
    let p0 = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    (worlds, p0, 2.5e-4)
}

/// The batch of `worlds` in f32 or f64, `None` (with a message) where the device has no f64
/// batch of them.
fn batch(worlds: &[Scene], p0: &[Particles], f64: bool) -> Option<CudaBatch> {
    let options = CudaOptions { f64, ..precise() };
    match CudaBatch::new(worlds, p0, options) {
        Ok(b) => Some(b),
        Err(e) => {
            assert!(f64, "the f32 batch: {e}");
            println!("no f64 batch of these worlds ({e}): f32 only");
            None
        }
    }
}

fn rebuilds(b: &mut CudaBatch) -> u32 {
    b.backend().rebuild_count().expect("control words")
}

/// Worlds 1 and 4 reset to their initial particles and world 2 put as it is (a state given),
/// after 10 steps of six settling sand beds, with the redo of those three worlds alone (half of
/// the worlds: still the partial redo) and with the full redo of every world: one step on (no
/// rebuild at that step, so the partial redo is what ran) every particle of every world of the
/// two runs agrees within the agreement test's first-step tolerance, and 10 steps on within its
/// aggregates (`agrees`; not bit for bit: two GPU runs differ in the last bits, the atomic sums
/// of P2G); the reset worlds 10 steps on agree with a fresh batch's worlds after its first 10
/// steps (the first step particle by particle too). f32 here, f64 in the next test. About 10 s
/// on an H200 (mostly the program's compile on a cold cache).
#[test]
fn worlds_put_step_on_as_with_the_full_redo_and_as_fresh_worlds() {
    put_and_step_on(false);
}

/// [`worlds_put_step_on_as_with_the_full_redo_and_as_fresh_worlds`] in f64 (its own test: the
/// f64 programs' compiles on a cold cache).
#[test]
fn worlds_put_step_on_as_with_the_full_redo_and_as_fresh_worlds_f64() {
    put_and_step_on(true);
}

/// The puts, the steps on and the comparisons of the two tests above, in f32 or `f64`.
fn put_and_step_on(f64: bool) {
    if !gpu() {
        return;
    }
    let (worlds, p0, dt) = beds();
    let dx = worlds[0].dx;
    // (the worlds 1 and 10 steps after the puts, the redo counts) of a run.
    let run = |full: bool| {
        let mut b = batch(&worlds, &p0, f64)?;
        b.set_full_redo(full);
        assert!(b.keep_initial(&p0).expect("keep"), "the image kept");
        let mut t = 0.0f32;
        for _ in 0..10 {
            b.step(dt, t).expect("step");
            t += dt;
        }
        let now = b.read_worlds().expect("read");
        assert!(b.put_initial(&[4, 1]).expect("reset worlds 1 and 4"));
        b.put_worlds(&[(2, now[2].clone())]).expect("put world 2");
        let before = rebuilds(&mut b);
        b.step(dt, t).expect("step after the puts");
        t += dt;
        assert_eq!(
            rebuilds(&mut b),
            before,
            "f64 {f64}: the puts rebuilt the mapping (the partial redo was skipped)"
        );
        let one = b.read_worlds().expect("read");
        for _ in 1..10 {
            b.step(dt, t).expect("step");
            t += dt;
        }
        Some((one, b.read_worlds().expect("read"), b.redo_counts()))
    };
    let Some((part_one, part_ten, part_counts)) = run(false) else {
        return;
    };
    let (full_one, full_ten, full_counts) = run(true).expect("the full redo's batch");
    assert_eq!(
        (part_counts.partial, part_counts.full),
        (1, 0),
        "f64 {f64}: one partial redo for the three worlds put"
    );
    assert_eq!(
        (full_counts.partial, full_counts.full),
        (0, 2),
        "f64 {f64}: the full redo asked by each of the two puts"
    );
    let mut failures = Vec::new();
    for w in 0..6 {
        failures.extend(agrees(
            &format!("f64 {f64}: world {w}, redo of the worlds put against the full redo"),
            Some((&part_one[w], &full_one[w])),
            &part_ten[w],
            &full_ten[w],
            dx,
        ));
    }
    // A fresh batch's first 10 steps.
    let mut fresh = batch(&worlds, &p0, f64).expect("fresh batch");
    fresh.step(dt, 0.0).expect("step");
    let fresh_one = fresh.read_worlds().expect("read");
    for s in 1..10 {
        fresh.step(dt, s as f32 * dt).expect("step");
    }
    let fresh_ten = fresh.read_worlds().expect("read");
    for w in [1, 4] {
        failures.extend(agrees(
            &format!("f64 {f64}: world {w} reset, against a fresh batch's"),
            Some((&part_one[w], &fresh_one[w])),
            &part_ten[w],
            &fresh_ten[w],
            dx,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Nodes by grid coordinate.
type Nodes = HashMap<IVec3, [f64; 4]>;

fn coming(b: &mut CudaBatch) -> Nodes {
    b.backend()
        .coming_grid_nodes()
        .expect("grid")
        .into_iter()
        .collect()
}

/// The redo of worlds 1 and 4 after their reset (`redo_puts` before the step, the grid the
/// step reads then read back) leaves every node of the other worlds bit for bit as the last
/// fused scatter left it, and changes the nodes of worlds 1 and 4 (their particles now at rest
/// where they were falling). Then the full redo of every world (P2G only, `run_p2g_only`, into
/// the same grid: no rebuild, the same mapping) gives every node of every world within rounding
/// of what the partial redo left (the worlds put) and of what the fused scatter left (the
/// others): each node value's difference below 1e-5 (f32) or 1e-12 (f64) of the largest node
/// mass (masses) or momentum component (momenta) on the grid (the atomic sums in another
/// order). f32 and f64. About 10 s on an H200 (mostly compiles on a cold cache); the compute-sanitizer memcheck
/// target of the redo's kernels.
#[test]
fn the_redo_of_the_worlds_put_leaves_the_others_nodes_bit_for_bit() {
    if !gpu() {
        return;
    }
    let (worlds, p0, dt) = beds();
    for f64 in [false, true] {
        let Some(mut b) = batch(&worlds, &p0, f64) else {
            continue;
        };
        let stride = b.params().stride as i32;
        let world_of = |n: &IVec3| n.x.div_euclid(stride) as usize;
        assert!(b.keep_initial(&p0).expect("keep"));
        let mut t = 0.0f32;
        for _ in 0..10 {
            b.step(dt, t).expect("step");
            t += dt;
        }
        let before = coming(&mut b);
        let r0 = rebuilds(&mut b);
        assert!(b.put_initial(&[1, 4]).expect("reset"));
        match b.redo_puts().expect("redo") {
            Redo::Worlds(r) => assert_eq!(
                (r.count, &r.lo[..2], &r.hi[..2]),
                (2, &[1, 4][..], &[2, 5][..]),
                "the runs of worlds 1 and 4"
            ),
            other => panic!("f64 {f64}: not the partial redo: {other:?}"),
        }
        let partial = coming(&mut b);
        assert_eq!(rebuilds(&mut b), r0, "no rebuild");
        assert_eq!(
            partial.len(),
            before.len(),
            "the same nodes (the same mapping)"
        );
        let mut changed = [0usize; 6];
        for (n, v) in &partial {
            let w = world_of(n);
            let old = before.get(n).expect("a node of the grid before");
            let same = v.iter().zip(old).all(|(a, b)| a.to_bits() == b.to_bits());
            if w == 1 || w == 4 {
                changed[w] += usize::from(!same);
            } else {
                assert!(same, "f64 {f64}: node {n} of world {w} changed by the redo");
            }
        }
        assert!(
            changed[1] > 0 && changed[4] > 0,
            "f64 {f64}: the redo left the worlds reset as they were: {changed:?}"
        );
        // The full redo (the next put asks for it), P2G only.
        b.set_full_redo(true);
        assert!(b.put_initial(&[1]).expect("reset world 1 again"));
        b.backend().run_p2g_only(dt).expect("full P2G");
        let full = coming(&mut b);
        assert_eq!(rebuilds(&mut b), r0, "no rebuild");
        // The scales: the largest node mass, the largest momentum component (x and z of these
        // falling beds are mostly rounding: measured against the fall's y momentum).
        let mut scale = [0f64; 4];
        for v in full.values() {
            scale[0] = scale[0].max(v[0].abs());
            let p = v[1].abs().max(v[2].abs()).max(v[3].abs());
            scale[1..].iter_mut().for_each(|s| *s = s.max(p));
        }
        let tol = if f64 { 1e-12 } else { 1e-5 };
        for (n, v) in &full {
            let w = world_of(n);
            let p = partial.get(n).expect("a node of the partial redo's grid");
            for q in 0..4 {
                let d = (v[q] - p[q]).abs() / scale[q].max(1e-30);
                assert!(
                    d <= tol,
                    "f64 {f64}: world {w} node {n} value {q}: full {} against {} (relative {d:.2e})",
                    v[q],
                    p[q]
                );
            }
        }
    }
}

/// The partial redo's kernels of a lane an item (`redo_clear_lanes`, `redo_p2g_lanes`, the
/// default) and of a warp an item over a full wave (`redo_clear`, `redo_p2g`,
/// `CudaBatch::set_wave_redo`, `RTMPM_BATCH_REDO=wave`) leave the same grid after the reset of
/// worlds 0, 2 and 5 (three runs, half of the worlds): every node of worlds 1, 3 and 4 bit for bit
/// as the last fused
/// scatter left it, and every node of the worlds reset within rounding of each other (each
/// value's difference below 1e-5 (f32) or 1e-12 (f64) of the largest node mass or momentum
/// component: the atomic sums in another order), f32 and f64. The second redo clears and
/// scatters the same worlds again into the grid the first left (no step between: the same
/// mapping). About 10 s on an H200 (mostly compiles on a cold cache); a compute-sanitizer
/// memcheck target of the lane kernels.
#[test]
fn the_redo_of_a_lane_an_item_leaves_the_grid_of_the_redo_of_a_warp_an_item() {
    if !gpu() {
        return;
    }
    let (worlds, p0, dt) = beds();
    for f64 in [false, true] {
        let Some(mut b) = batch(&worlds, &p0, f64) else {
            continue;
        };
        let stride = b.params().stride as i32;
        let world_of = |n: &IVec3| n.x.div_euclid(stride) as usize;
        assert!(b.keep_initial(&p0).expect("keep"));
        let mut t = 0.0f32;
        for _ in 0..10 {
            b.step(dt, t).expect("step");
            t += dt;
        }
        let before = coming(&mut b);
        let r0 = rebuilds(&mut b);
        let reset = [0, 2, 5];
        let mut grids = Vec::new();
        for wave in [false, true] {
            b.set_wave_redo(wave);
            assert!(b.put_initial(&reset).expect("reset"));
            match b.redo_puts().expect("redo") {
                Redo::Worlds(r) => assert_eq!(r.count, 3, "f64 {f64}: the runs 0, 2 and 5"),
                other => panic!("f64 {f64}: not the partial redo: {other:?}"),
            }
            grids.push(coming(&mut b));
        }
        assert_eq!(rebuilds(&mut b), r0, "no rebuild");
        let (lanes, wave) = (&grids[0], &grids[1]);
        assert_eq!(
            lanes.len(),
            before.len(),
            "the same nodes (the same mapping)"
        );
        let mut scale = [0f64; 4];
        for v in wave.values() {
            scale[0] = scale[0].max(v[0].abs());
            let p = v[1].abs().max(v[2].abs()).max(v[3].abs());
            scale[1..].iter_mut().for_each(|s| *s = s.max(p));
        }
        let tol = if f64 { 1e-12 } else { 1e-5 };
        let mut changed = 0;
        for (n, v) in lanes {
            let w = world_of(n);
            let old = before.get(n).expect("a node of the grid before");
            let other = wave.get(n).expect("a node of the wave redo's grid");
            if reset.contains(&w) {
                changed += usize::from(v.iter().zip(old).any(|(a, b)| a.to_bits() != b.to_bits()));
                for q in 0..4 {
                    let d = (v[q] - other[q]).abs() / scale[q].max(1e-30);
                    assert!(
                        d <= tol,
                        "f64 {f64}: world {w} node {n} value {q}: lanes {} against wave {} \
                         (relative {d:.2e})",
                        v[q],
                        other[q]
                    );
                }
            } else {
                let same = |a: &[f64; 4], b: &[f64; 4]| {
                    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
                };
                assert!(
                    same(v, old) && same(other, old),
                    "f64 {f64}: node {n} of world {w} changed by a redo"
                );
            }
        }
        assert!(
            changed > 0,
            "f64 {f64}: the redo left the worlds reset as they were"
        );
    }
}
