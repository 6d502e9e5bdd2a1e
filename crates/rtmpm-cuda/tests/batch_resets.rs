//! Worlds of a GPU batch (`rtmpm_cuda::batch::CudaBatch`) put back while the others run: a
//! reset world goes on as a fresh run of its own and a blown-up one is reported as itself, the
//! others untouched; worlds put at once hold what one put a world leaves; a put rebuilds the
//! mapping only where a particle leaves its block's free zone (needs a GPU; skips with a
//! message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_resets -- --include-ignored --nocapture`.

mod common;

use common::batch::{DT, agrees, bit_identical, precise, sand_bed, wedge_worlds};
use common::{gpu, read};
use rtmpm_cuda::CudaBackend;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

/// A reset world (put back to its initial particles mid-run) goes on as a fresh run of its own,
/// and the other worlds as in the same batch without the reset; a world that blows up (gravity
/// of 10^7 m/s^2) is reported as that world, and the others still agree with their separate runs.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_reset_or_blown_up_world_leaves_the_others_as_they_were() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(4);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let run = |reset_at: Option<usize>, steps: usize| {
        let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
        for s in 0..steps {
            if reset_at == Some(s) {
                b.put_world(1, &p0[1]).expect("reset world 1");
            }
            b.step(DT, s as f32 * DT).expect("step");
        }
        b.read_worlds().expect("read")
    };
    let plain = run(None, 100);
    let again = run(None, 100);
    let reset = run(Some(50), 100);
    let alone_50 = {
        let mut b = CudaBackend::new(&worlds[1], &p0[1], precise()).expect("world 1");
        for s in 0..50 {
            b.step(DT, s as f32 * DT).expect("step");
        }
        read(&mut b)
    };
    let mut failures = Vec::new();
    let dx = worlds[0].dx;
    for w in [0, 2, 3] {
        println!(
            "world {w}: bit-identical to the batch without the reset: {}; two runs of the same batch bit-identical: {}",
            bit_identical(&reset[w], &plain[w]),
            bit_identical(&again[w], &plain[w])
        );
        failures.extend(agrees(
            &format!("world {w} beside a reset"),
            None,
            &reset[w],
            &plain[w],
            dx,
        ));
    }
    // World 1 after its reset at step 50 and 50 more steps: a 50-step run of its own.
    failures.extend(agrees(
        "world 1 reset at 50, 50 steps on",
        None,
        &reset[1],
        &alone_50,
        dx,
    ));
    let d = reset[1].aggregate_difference(&plain[1]);
    assert!(
        d.com > 0.1 * dx as f64,
        "the reset changed nothing: |d com| {:.3e}",
        d.com
    );

    // Blow-up: world 2's gravity 10^7 m/s^2.
    let mut bad = worlds.clone();
    bad[2].gravity = Vec3::new(0.0, -1e7, 0.0);
    let mut b = CudaBatch::new(&bad, &p0, precise()).expect("batch");
    let mut reported = None;
    for s in 0..100 {
        b.step(DT, s as f32 * DT).expect("step");
        if let Some((w, p)) = b.bad_world().expect("check") {
            reported.get_or_insert((s, w, p.index));
            assert_eq!(
                w, 2,
                "the blow-up reported in world {w}, particle {}",
                p.index
            );
        }
    }
    let (s, w, i) = reported.expect("world 2 blew up and was reported");
    println!("blow-up: world {w} particle {i} reported at step {s}");
    let got = b.read_worlds().expect("read");
    for w in [0, 1, 3] {
        failures.extend(agrees(
            &format!("world {w} beside a blow-up"),
            None,
            &got[w],
            &plain[w],
            dx,
        ));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Worlds put at once (`CudaBatch::put_worlds`: runs of consecutive worlds packed as one, one
/// upload) hold what one `put_world` a world leaves, bit for bit, the worlds not listed
/// untouched; a world listed twice ends with its last; a list with one bad entry is refused
/// before any world changes.
#[test]
#[ignore = "needs a CUDA GPU"]
fn worlds_put_at_once_hold_what_one_put_a_world_leaves() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(5);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    for s in 0..20 {
        b.step(DT, s as f32 * DT).expect("step");
    }
    let before = b.read_worlds().expect("read");
    // World w's new state: its initial particles, moving at (w + 1) m/s along x.
    let moving = |w: usize, speed: f32| {
        let mut p = p0[w].clone();
        p.v.iter_mut().for_each(|v| *v = Vec3::new(speed, 0.0, 0.0));
        p
    };
    let list = vec![
        (3, moving(3, 9.0)),
        (0, moving(0, 1.0)),
        (1, moving(1, 2.0)),
        (3, moving(3, 4.0)),
    ];
    let mut short = p0[4].clone();
    short.x.pop();
    let refused = b.put_worlds(&[(0, moving(0, 7.0)), (4, short)]);
    assert!(
        refused.is_err(),
        "a world given too few particles is refused"
    );
    let untouched = b.read_worlds().expect("read");
    for w in 0..5 {
        assert!(
            bit_identical(&untouched[w], &before[w]),
            "world {w} changed by a refused put"
        );
    }
    b.put_worlds(&list).expect("put worlds at once");
    let at_once = b.read_worlds().expect("read");
    for (w, p) in &list {
        b.put_world(*w, p).expect("put one world");
    }
    let one_each = b.read_worlds().expect("read");
    for w in 0..5 {
        assert!(
            bit_identical(&at_once[w], &one_each[w]),
            "world {w}: put at once differs from one put a world"
        );
    }
    for w in [2, 4] {
        assert!(bit_identical(&at_once[w], &before[w]), "world {w} touched");
    }
    for (w, speed) in [(0, 1.0), (1, 2.0), (3, 4.0)] {
        let p = &at_once[w];
        assert!(
            p.v.iter().all(|v| *v == Vec3::new(speed, 0.0, 0.0)),
            "world {w}'s v"
        );
        assert!(
            p.x.iter()
                .zip(&p0[w].x)
                .all(|(a, b)| (*a - *b).length() < 1e-6),
            "world {w}'s x"
        );
    }
    assert!(b.put_bytes() > 0);
    // Steps go on from the worlds put (the next step rebuilds the mapping).
    for s in 0..5 {
        b.step(DT, s as f32 * DT).expect("step after the put");
    }
    assert!(b.bad_world().expect("check").is_none());
}

/// A put rebuilds the particle-to-block mapping only where a particle put leaves the free zone
/// of the gblock its slot is sorted into (`kernels/batch.cu`): four sand beds after 10 steps
/// (settled by a few thousandths of a cell), world 1 put back as it is, world 2 reset to its
/// start and world 0 put at its start moved one cell along x and one back along z (still in
/// every zone: a base may go 4 cells below its block and 5 above its block's first) cost no
/// rebuild, and all three go on as their separate runs from those states (every particle after
/// one step within the agreement test's first-step tolerance, the aggregates after 20): the
/// mapping they kept holds them. World 3 put 3 cells along x (the particles of each block's
/// last cell column leave its zone) asks for a rebuild at the next step, and goes on as its
/// separate run from there too. About 10 s on an H200 (most of it the programs' compiles on a
/// cold cache).
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_put_rebuilds_the_mapping_only_where_a_particle_leaves_its_zone() {
    if !gpu() {
        return;
    }
    let dt = 2.5e-4;
    let world = Scene::from_toml(&sand_bed(0.109375), "sand_bed").expect("scene");
    let worlds = vec![world.clone(); 4];
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut b = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    let mut t = 0.0f32;
    for _ in 0..10 {
        b.step(dt, t).expect("step");
        t += dt;
    }
    let now = b.read_worlds().expect("read");
    let rebuilds = |b: &mut CudaBatch| b.backend().rebuild_count().expect("control words");
    let before = rebuilds(&mut b);
    let moved = |p: &Particles, by: Vec3| {
        let mut q = p.clone();
        q.x.iter_mut().for_each(|x| *x += by * world.dx);
        q
    };
    let shifted = moved(&p0[3], Vec3::new(3.0, 0.0, 0.0));
    // The separate runs from the states put, and the batch's worlds after the same steps.
    let starts = [
        (0, moved(&p0[0], Vec3::new(1.0, 0.0, -1.0))),
        (1, now[1].clone()),
        (2, p0[2].clone()),
    ];
    b.put_worlds(&starts).expect("put worlds 0, 1 and 2");
    b.step(dt, t).expect("step after the put");
    assert_eq!(
        rebuilds(&mut b),
        before,
        "worlds put within their blocks' free zones rebuilt the mapping"
    );
    let one_step = b.read_worlds().expect("read");
    b.put_world(3, &shifted)
        .expect("put world 3 three cells along x");
    b.step(dt, t + dt).expect("step after the shifted put");
    assert_eq!(
        rebuilds(&mut b),
        before + 1,
        "a world put three cells away did not rebuild the mapping"
    );
    let shifted_one = b.read_worlds().expect("read");
    for s in 2..21 {
        b.step(dt, t + s as f32 * dt).expect("step");
    }
    let got = b.read_worlds().expect("read");
    let alone = |p: &Particles, steps: usize| {
        let mut one = CudaBackend::new(&world, p, precise()).expect("world alone");
        let mut out = Vec::new();
        for s in 0..steps {
            one.step(dt, s as f32 * dt).expect("step");
            if s == 0 || s + 1 == steps {
                out.push(read(&mut one));
            }
        }
        out
    };
    let mut failures = Vec::new();
    let dx = world.dx;
    for (w, p) in &starts {
        let runs = alone(p, 21);
        failures.extend(agrees(
            &format!("world {w} put without a rebuild"),
            Some((&one_step[*w], &runs[0])),
            &got[*w],
            &runs[1],
            dx,
        ));
    }
    let runs = alone(&shifted, 20);
    failures.extend(agrees(
        "world 3 put three cells along x",
        Some((&shifted_one[3], &runs[0])),
        &got[3],
        &runs[1],
        dx,
    ));
    for (w, cells) in [(3, 2.0), (0, 1.0)] {
        let d = got[w].aggregate_difference(&got[2]);
        assert!(
            d.com > cells * dx as f64,
            "world {w} is not where it was put, more than {cells} cells from world 2: |d com| \
             {:.3e}",
            d.com
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// World `w`'s particles of `p` made its own: the last `13 w` dropped and every velocity
/// `(w + 1) / 20` m/s along x, so that a world put from another world's range (or a range off by
/// a few particles) differs from it.
fn own(p: &Particles, w: usize) -> Particles {
    let mut q = Particles::default();
    for i in 0..p.len() - 13 * w {
        q.push(
            p.x[i],
            Vec3::new(0.05 * (w + 1) as f32, 0.0, 0.0),
            p.mass[i],
            p.vol0[i],
            p.material[i],
            p.plastic[i],
        );
        let at = q.len() - 1;
        (q.c[at], q.f[at]) = (p.c[i], p.f[i]);
    }
    q
}

/// A reset from the image the batch keeps of its initial particles (`CudaBatch::keep_initial`,
/// `put_initial`: launches reading the kept image in place, its rows of the whole batch's
/// particles) puts the worlds listed (out of order, one twice: runs 1-2 and 4) bit for bit as a put
/// of those particles (`put_worlds`, packed and uploaded) does, in f32 and f64: they hold their own
/// initial particles (each world its own count and velocity, so another world's range or an offset
/// range would show), and the others are left bit for bit as they were. 10 steps on, every world
/// of the two batches agrees within the tolerance of the batch tests (`agrees`), not bit for bit:
/// two runs of one batch on the GPU differ in the last bits (the atomic sums of P2G; the unlisted
/// worlds already differ between the two runs before the puts).
/// Before `keep_initial` the batch keeps nothing (`Ok(false)`, nothing changed); initial
/// particles that do not fit the worlds are refused. About 10 s on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_reset_from_the_kept_image_puts_back_exactly_the_worlds_listed() {
    if !gpu() {
        return;
    }
    let worlds = wedge_worlds(5);
    let p0: Vec<Particles> = worlds
        .iter()
        .enumerate()
        .map(|(w, s)| own(&s.sample_particles().expect("particles"), w))
        .collect();
    for f64 in [false, true] {
        let options = rtmpm_cuda::CudaOptions { f64, ..precise() };
        if let Err(e) = CudaBatch::new(&worlds, &p0, options.clone()) {
            assert!(f64, "the f32 batch: {e}");
            println!("no f64 batch of these worlds ({e}): f32 only");
            continue;
        }
        let run = |kept: bool| {
            let mut b = CudaBatch::new(&worlds, &p0, options.clone()).expect("batch");
            for s in 0..20 {
                b.step(DT, s as f32 * DT).expect("step");
            }
            let before = b.read_worlds().expect("read");
            let list = [4, 2, 1, 2];
            if kept {
                assert!(
                    !b.put_initial(&list).expect("nothing kept yet"),
                    "kept nothing"
                );
                assert!(
                    bit_identical(&b.read_worlds().expect("read")[1], &before[1]),
                    "a put with nothing kept changed world 1"
                );
                assert!(
                    b.keep_initial(&p0[..4]).is_err(),
                    "4 worlds' particles for 5"
                );
                let mut short = p0.clone();
                short[3].x.pop();
                assert!(
                    b.keep_initial(&short).is_err(),
                    "world 3 short of a particle"
                );
                assert!(b.keep_initial(&p0).expect("keep"), "the image kept");
                assert!(b.initial_bytes() > 0);
                assert!(b.put_initial(&list).expect("put from the image"));
            } else {
                let starts: Vec<(usize, Particles)> =
                    list.iter().map(|&w| (w, p0[w].clone())).collect();
                b.put_worlds(&starts).expect("put worlds");
            }
            let put = b.read_worlds().expect("read");
            for s in 20..30 {
                b.step(DT, s as f32 * DT).expect("step");
            }
            (before, put, b.read_worlds().expect("read"))
        };
        let (before, kept_put, kept_on) = run(true);
        let (_, packed_put, packed_on) = run(false);
        for w in [1, 2, 4] {
            assert!(
                bit_identical(&kept_put[w], &packed_put[w]),
                "f64 {f64}: world {w} put from the kept image differs from the packed put"
            );
        }
        let dx = worlds[0].dx;
        let failures: Vec<String> = (0..5)
            .flat_map(|w| {
                agrees(
                    &format!("f64 {f64}: world {w} 10 steps after the puts"),
                    None,
                    &kept_on[w],
                    &packed_on[w],
                    dx,
                )
            })
            .collect();
        assert!(failures.is_empty(), "{failures:#?}");
        for w in [0, 3] {
            assert!(bit_identical(&kept_put[w], &before[w]), "world {w} touched");
        }
        for w in [1, 2, 4] {
            let p = &kept_put[w];
            assert_eq!(p.len(), p0[w].len());
            assert!(
                p.v.iter().all(|v| *v == p0[w].v[0]) && p.x == p0[w].x,
                "f64 {f64}: world {w} is not its initial particles"
            );
        }
    }
}
