//! GPU tests of the fused kernels' instruction cuts: the stencil node addressing
//! (`--cuda-options addressing=pairs|blocks`, `kernels/stencil.cuh`) and the warp-uniform warp
//! loop (`uniform_loop=on|off`, `kernels/g2p/g2p2g.cu`). The defaults (pair addressing, uniform
//! loop) read and scatter the same nodes with the same arithmetic as the kernels before them
//! (`addressing=blocks,uniform_loop=off`, whose PTX is main's before the change, byte for byte), so
//!
//! 1. with isolated particles (each grid node gets one particle's contribution, so P2G's atomic
//!    sums are exact and the run is deterministic) the two give bit-identical particles after 60
//!    steps, water (the fluid kernels) and jelly (the general ones), f32 and f64, with G2P2G and
//!    with separate G2P and P2G kernels; the particles start at every cell offset of the blocks,
//!    so the stencils start at every node of their pairs;
//! 2. in a dense scene they differ no more than four times as much as two runs of the default
//!    differ from each other (P2G's atomic sums are not deterministic), or 1e-4 dx;
//! 3. the warp scatter's rows unrolled (`row_unroll=planes|all`, off by default) give the
//!    default's particles bit for bit (isolated water and jelly, f32, G2P2G);
//! 4. the second round of cuts (`lean_lanes`, `seg_clamp`, `zero_terms=skip`, `flat_checks`,
//!    `state_index=wide`, off by default) give the default's particles bit for bit, all
//!    together but `zero_terms` (f32 and f64, fused and separate kernels), and with it up to the
//!    sign of a zero, on isolated
//!    clusters of 1 to 12 particles at one position (so that the warp reduction runs 0 to 4
//!    shuffle rounds on segments of those lengths while every node still gets one segment's
//!    sum, deterministic), and in a dense scene no further from the default than a rerun;
//! 5. `fused_defaults=auto` (the fluid kernel set `row_unroll=planes` + the cuts but
//!    `lean_lanes`, the general set today's code) gives today's particles: water up to the
//!    sign of a zero, jelly bit for bit (the same program), f32 and f64, fused and separate kernels.
//!
//! "The default" above is today's code of the fused kernels' switches, given explicitly
//! ([`today`]), so that the tests keep their meaning when `fused_defaults` changes its default.
//!
//! The first GPU test to run compiles the file's 22 kernel sets side by side in parallel threads
//! into the PTX cache ([`compile_every_kernel_set`]; NVRTC compiles a program on one core); every
//! test then reads its programs from the cache and runs its kernel sets in parallel threads: the
//! file takes about two compiles' time on 16 cores plus its runs, instead of 22 compiles in a row
//! (past 505 s before).
//!
//! `cargo test -p rtmpm-cuda --test addressing -- --include-ignored`; the GPU tests skip with a
//! message when no usable CUDA device is present.

mod common;

use common::{gpu, read, unit_cube_scene};
use rtmpm_cuda::{CudaBackend, CudaOptions, FusedCode, FusedSwitches, KernelCuts, RowUnroll};
use rtmpm_physics::Particles;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

const DT: f32 = 2e-4;

/// Unit cube, dx = 1/32, gravity, fixed dt; water or jelly.
fn scene(water: bool) -> Scene {
    let material = if water {
        Material::parse("water", 1000.0, "fluid", "bulk_modulus = 1e4").expect("water")
    } else {
        Material::parse("jelly", 1000.0, "fixed_corotated", "mu = 4e4\nlambda = 6e4")
            .expect("jelly")
    };
    unit_cube_scene("addressing", 1.0 / 32.0, DT, material)
}

/// Particles at spacing `h` (in cells) in [lo, hi], spinning about the block's centre and moving
/// down at 1 m/s, so that v and C are far from zero and of mixed signs.
fn block(s: &Scene, lo: Vec3, hi: Vec3, h: f32) -> Particles {
    let h = h * s.dx;
    let n = ((hi - lo) / h).round().as_uvec3();
    let centre = 0.5 * (lo + hi);
    let omega = Vec3::new(1.0, 2.0, 0.5).normalize() * 5.0;
    let vol = (s.dx / 2.0).powi(3);
    let mut p = Particles::default();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let x = lo + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * h;
                let v = omega.cross(x - centre) + Vec3::new(0.0, -1.0, 0.0);
                p.push(x, v, 1000.0 * vol, vol, 0, 0.0);
                let last = p.len() - 1;
                p.c[last] = Mat3::from_cols_array(&[
                    0.0, omega.z, -omega.y, -omega.z, 0.0, omega.x, omega.y, -omega.x, 0.0,
                ]);
            }
        }
    }
    p
}

/// `new`: the defaults; else the kernels before the cuts (`addressing=blocks,uniform_loop=off`).
/// Both with today's code of the fused kernels' other switches ([`today`]).
fn options(new: bool, f64: bool, g2p2g: bool) -> CudaOptions {
    CudaOptions {
        stencil_pairs: new,
        uniform_loop: new,
        f64,
        g2p2g,
        ..today()
    }
}

/// The defaults with today's code of the fused kernels in every kernel set (`row_unroll=off`,
/// no cut; whatever `fused_defaults` defaults to).
fn today() -> CudaOptions {
    CudaOptions {
        fused: FusedSwitches::all(FusedCode::default()),
        ..Default::default()
    }
}

/// `steps` steps, then every particle (the run must stay healthy).
fn run(s: &Scene, p: &Particles, o: CudaOptions, steps: usize) -> Particles {
    let mut b = CudaBackend::new(s, p, o).expect("backend");
    for i in 0..steps {
        b.step(DT, i as f32 * DT).expect("step");
    }
    assert_eq!(b.check().expect("check"), None);
    read(&mut b)
}

/// `f(job)` for every job, in parallel threads (at most one a core), the results in the jobs'
/// order. A job is a kernel set's runs: its first run compiles the program into the PTX cache,
/// the others read it there, and the jobs' compiles run side by side.
fn parallel<J: Sync, R: Send>(jobs: &[J], f: impl Fn(&J) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut out: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(job) = jobs.get(i) else { break };
                        done.push((i, f(job)));
                    }
                    done
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a test thread panicked"))
            .collect()
    });
    out.sort_by_key(|(i, _)| *i);
    out.into_iter().map(|(_, r)| r).collect()
}

/// Every kernel set of this file's tests compiled into the PTX cache once, side by side in
/// parallel threads: the first GPU test to run pays for all (22 programs, about two compiles'
/// time on 16 cores instead of 22 compiles in a row), the others read theirs from the cache.
fn compile_every_kernel_set() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let unrolled = |unroll| CudaOptions {
            fused: FusedSwitches::all(FusedCode {
                row_unroll: unroll,
                ..Default::default()
            }),
            ..Default::default()
        };
        let mut sets: Vec<(bool, CudaOptions)> = Vec::new();
        for water in [true, false] {
            for f64 in [false, true] {
                let mut os = vec![
                    today(),
                    options(false, f64, true),
                    all_cuts(false),
                    all_cuts(true),
                ];
                // Jelly's auto is today's program.
                if water {
                    os.push(auto());
                }
                sets.extend(os.into_iter().map(|o| (water, CudaOptions { f64, ..o })));
            }
            for unroll in [RowUnroll::Planes, RowUnroll::All] {
                sets.push((water, unrolled(unroll)));
            }
        }
        let t = std::time::Instant::now();
        parallel(&sets, |(water, o)| {
            let s = scene(*water);
            let p = block(&s, Vec3::splat(0.2), Vec3::splat(0.8), 5.25);
            drop(CudaBackend::new(&s, &p, o.clone()).expect("backend"));
        });
        println!(
            "{} kernel sets compiled in {:.0} s",
            sets.len(),
            t.elapsed().as_secs_f64()
        );
    });
}

/// `--cuda-options fused_defaults=auto`.
fn auto() -> CudaOptions {
    "fused_defaults=auto".parse().expect("fused_defaults=auto")
}

/// Largest distance between the positions of two runs.
fn max_dx(a: &Particles, b: &Particles) -> f32 {
    a.x.iter()
        .zip(&b.x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_new_kernels_give_bit_identical_particles_to_the_kernels_before_them() {
    if !gpu() {
        return;
    }
    compile_every_kernel_set();
    // One particle every 5.25 cells: stencils never share a node while the particles move
    // less than a cell, and the starts run through every cell offset in a block (and past
    // the 4-node blocks, so that a stencil's nodes fall in one, two of its pair's blocks).
    let particles = |s: &Scene| block(s, Vec3::splat(0.2), Vec3::splat(0.8), 5.25);
    // A job a kernel set (scene, precision, kernels): G2P2G and separate kernels on it.
    let mut jobs = Vec::new();
    for water in [true, false] {
        for f64 in [false, true] {
            for new in [false, true] {
                jobs.push((water, f64, new));
            }
        }
    }
    let runs = parallel(&jobs, |&(water, f64, new)| {
        let s = scene(water);
        let p = particles(&s);
        [true, false].map(|g2p2g| run(&s, &p, options(new, f64, g2p2g), 60))
    });
    for (job, (&(water, f64, new), before)) in jobs.iter().zip(&runs).enumerate() {
        if new {
            continue;
        }
        let (after, p) = (&runs[job + 1], particles(&scene(water)));
        assert_eq!(jobs[job + 1], (water, f64, true));
        for (g, g2p2g) in [true, false].into_iter().enumerate() {
            let what = format!("water {water}, f64 {f64}, g2p2g {g2p2g}");
            let (before, new) = (&before[g], &after[g]);
            assert!(max_dx(before, &p) > 0.0, "{what}: nothing moved");
            for i in 0..p.len() {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(before.x[i]), bits(new.x[i]), "{what}: x of {i}");
                assert_eq!(bits(before.v[i]), bits(new.v[i]), "{what}: v of {i}");
                assert_eq!(before.c[i], new.c[i], "{what}: C of {i}");
                assert_eq!(before.f[i], new.f[i], "{what}: F of {i}");
            }
            println!("{what}: {} particles bit-identical", p.len());
        }
    }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn in_a_dense_scene_the_new_kernels_differ_no_more_than_a_rerun() {
    if !gpu() {
        return;
    }
    compile_every_kernel_set();
    // Two particles per cell per axis.
    let particles = |s: &Scene| block(s, Vec3::splat(0.3), Vec3::new(0.6, 0.55, 0.6), 0.5);
    // Jobs: the default twice (a rerun), the kernels before once; water and jelly.
    let jobs: Vec<(bool, bool)> = [true, false]
        .into_iter()
        .flat_map(|water| [(water, true), (water, false)])
        .collect();
    let runs = parallel(&jobs, |&(water, new)| {
        let s = scene(water);
        let p = particles(&s);
        let reps = if new { 2 } else { 1 };
        (0..reps)
            .map(|_| run(&s, &p, options(new, false, true), 100))
            .collect::<Vec<_>>()
    });
    for (w, water) in [true, false].into_iter().enumerate() {
        let s = scene(water);
        let (a, again, before) = (&runs[2 * w][0], &runs[2 * w][1], &runs[2 * w + 1][0]);
        let (rerun, other) = (max_dx(a, again), max_dx(a, before));
        println!(
            "water {water}, {} particles: max |dx| rerun {rerun:e}, kernels before {other:e} (dx {})",
            a.len(),
            s.dx
        );
        // A wrong node read or scattered moves particles by far more than this floor.
        assert!(
            other <= (4.0 * rerun).max(1e-4 * s.dx),
            "the kernels before differ by {other:e}, a rerun by {rerun:e}"
        );
    }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_unrolled_rows_give_bit_identical_particles() {
    if !gpu() {
        return;
    }
    compile_every_kernel_set();
    let unrolls = [RowUnroll::Off, RowUnroll::Planes, RowUnroll::All];
    let jobs: Vec<(bool, RowUnroll)> = [true, false]
        .into_iter()
        .flat_map(|water| unrolls.map(|u| (water, u)))
        .collect();
    let runs = parallel(&jobs, |&(water, unroll)| {
        let s = scene(water);
        let p = block(&s, Vec3::splat(0.2), Vec3::splat(0.8), 5.25);
        let code = FusedCode {
            row_unroll: unroll,
            ..Default::default()
        };
        let o = CudaOptions {
            fused: FusedSwitches::all(code),
            ..Default::default()
        };
        (p.clone(), run(&s, &p, o, 60))
    });
    for (w, water) in [true, false].into_iter().enumerate() {
        let (p, default) = &runs[3 * w];
        assert!(max_dx(default, p) > 0.0, "water {water}: nothing moved");
        for (u, unroll) in unrolls.into_iter().enumerate().skip(1) {
            let what = format!("water {water}, {unroll:?}");
            let unrolled = &runs[3 * w + u].1;
            for i in 0..p.len() {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(default.x[i]), bits(unrolled.x[i]), "{what}: x of {i}");
                assert_eq!(bits(default.v[i]), bits(unrolled.v[i]), "{what}: v of {i}");
                assert_eq!(default.c[i], unrolled.c[i], "{what}: C of {i}");
                assert_eq!(default.f[i], unrolled.f[i], "{what}: F of {i}");
            }
            println!("{what}: {} particles bit-identical", p.len());
        }
    }
}

/// `block`'s sites, each holding `1 + site % 12` identical particles (same position, velocity,
/// mass): a warp holds them in adjacent lanes (the rebuild sorts by cell), so the warp
/// reduction sums segments of 1 to 12 lanes; identical particles make the sums independent of
/// their order in the bucket, and the sites' stencils share no node.
fn clusters(s: &Scene, lo: Vec3, hi: Vec3, h: f32) -> Particles {
    let sites = block(s, lo, hi, h);
    let mut p = Particles::default();
    for i in 0..sites.len() {
        for _ in 0..1 + i % 12 {
            p.push(sites.x[i], sites.v[i], sites.mass[i], sites.vol0[i], 0, 0.0);
            let last = p.len() - 1;
            p.c[last] = sites.c[i];
        }
    }
    p
}

/// Every cut of the second round on (`--cuda-options lean_lanes=on,seg_clamp=on,
/// zero_terms=skip,flat_checks=on,state_index=wide`); `zero_terms: false` leaves out the one
/// that may change the sign of a zero.
fn all_cuts(zero_terms: bool) -> CudaOptions {
    let code = FusedCode {
        cuts: KernelCuts {
            lean_lanes: true,
            seg_clamp: true,
            zero_terms,
            flat_checks: true,
        },
        wide_state_index: true,
        ..Default::default()
    };
    CudaOptions {
        fused: FusedSwitches::all(code),
        ..Default::default()
    }
}

/// Particles of two runs equal bit for bit (`signed_zeros`), or as numbers (-0 == +0).
fn assert_identical(what: &str, a: &Particles, b: &Particles, signed_zeros: bool) {
    assert_eq!(a.len(), b.len(), "{what}: particle count");
    let key = |x: f32| {
        if signed_zeros || x != 0.0 {
            x.to_bits()
        } else {
            0
        }
    };
    let v3 = |v: Vec3| v.to_array().map(key);
    let m3 = |m: Mat3| m.to_cols_array().map(key);
    for i in 0..a.len() {
        assert_eq!(v3(a.x[i]), v3(b.x[i]), "{what}: x of {i}");
        assert_eq!(v3(a.v[i]), v3(b.v[i]), "{what}: v of {i}");
        assert_eq!(m3(a.c[i]), m3(b.c[i]), "{what}: C of {i}");
        assert_eq!(m3(a.f[i]), m3(b.f[i]), "{what}: F of {i}");
    }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_second_round_of_cuts_gives_bit_identical_particles() {
    if !gpu() {
        return;
    }
    compile_every_kernel_set();
    // The kernel sets, each compiled once and run with G2P2G and with separate kernels: today's
    // code; the cuts together but zero_terms (each alone is a subset of the same arithmetic: one
    // compile a layout and precision instead of five), bit for bit; every cut, up to the sign of
    // a zero; fused_defaults=auto (water: planes + the cuts but lean_lanes, up to the sign of a
    // zero; jelly: today's program, bit for bit, run in the default's job: the same PTX).
    #[derive(Clone, Copy, PartialEq, Debug)]
    enum Set {
        Today,
        CutsButZeroTerms,
        AllCuts,
        Auto,
    }
    let options_of = |set: Set, f64: bool, g2p2g: bool| {
        let o = match set {
            Set::Today => today(),
            Set::CutsButZeroTerms => all_cuts(false),
            Set::AllCuts => all_cuts(true),
            Set::Auto => auto(),
        };
        CudaOptions { f64, g2p2g, ..o }
    };
    let mut jobs: Vec<(bool, bool, Vec<Set>)> = Vec::new();
    for water in [true, false] {
        for f64 in [false, true] {
            if water {
                jobs.push((water, f64, vec![Set::Today]));
                jobs.push((water, f64, vec![Set::Auto]));
            } else {
                jobs.push((water, f64, vec![Set::Today, Set::Auto]));
            }
            jobs.push((water, f64, vec![Set::CutsButZeroTerms]));
            jobs.push((water, f64, vec![Set::AllCuts]));
        }
    }
    let runs = parallel(&jobs, |(water, f64, sets)| {
        let s = scene(*water);
        let p = clusters(&s, Vec3::splat(0.2), Vec3::splat(0.8), 5.25);
        sets.iter()
            .flat_map(|&set| {
                [true, false]
                    .map(|g2p2g| ((set, g2p2g), run(&s, &p, options_of(set, *f64, g2p2g), 60)))
            })
            .collect::<Vec<_>>()
    });
    let mut compared = 0;
    for water in [true, false] {
        let s = scene(water);
        let p = clusters(&s, Vec3::splat(0.2), Vec3::splat(0.8), 5.25);
        for f64 in [false, true] {
            // This scene's and precision's runs, by kernel set and G2P2G.
            let of = |set: Set, g2p2g: bool| {
                jobs.iter()
                    .zip(&runs)
                    .filter(|((w, f, _), _)| (*w, *f) == (water, f64))
                    .flat_map(|(_, r)| r)
                    .find(|(k, _)| *k == (set, g2p2g))
                    .map(|(_, parts)| parts)
                    .expect("every kernel set ran")
            };
            for g2p2g in [true, false] {
                let default = of(Set::Today, g2p2g);
                assert!(max_dx(default, &p) > 0.0, "water {water}: nothing moved");
                // Jelly's auto is today's program: bit for bit.
                let auto_exact = !water;
                for (set, signed_zeros) in [
                    (Set::CutsButZeroTerms, true),
                    (Set::AllCuts, false),
                    (Set::Auto, auto_exact),
                ] {
                    let what = format!("water {water}, f64 {f64}, g2p2g {g2p2g}, {set:?}");
                    assert_identical(&what, default, of(set, g2p2g), signed_zeros);
                    println!("{what}: {} particles identical", p.len());
                    compared += 1;
                }
            }
        }
    }
    assert_eq!(compared, 24);
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn in_a_dense_scene_the_second_round_of_cuts_differs_no_more_than_a_rerun() {
    if !gpu() {
        return;
    }
    compile_every_kernel_set();
    let particles = |s: &Scene| block(s, Vec3::splat(0.3), Vec3::new(0.6, 0.55, 0.6), 0.5);
    // Jobs: today's code twice (a rerun), every cut once; water and jelly.
    let jobs: Vec<(bool, bool)> = [true, false]
        .into_iter()
        .flat_map(|water| [(water, false), (water, true)])
        .collect();
    let runs = parallel(&jobs, |&(water, cut)| {
        let s = scene(water);
        let p = particles(&s);
        if cut {
            vec![run(&s, &p, all_cuts(true), 100)]
        } else {
            (0..2).map(|_| run(&s, &p, today(), 100)).collect()
        }
    });
    for (w, water) in [true, false].into_iter().enumerate() {
        let s = scene(water);
        let (a, again, cut) = (&runs[2 * w][0], &runs[2 * w][1], &runs[2 * w + 1][0]);
        let (rerun, other) = (max_dx(a, again), max_dx(a, cut));
        println!(
            "water {water}, {} particles: max |dx| rerun {rerun:e}, all cuts {other:e} (dx {})",
            a.len(),
            s.dx
        );
        assert!(
            other <= (4.0 * rerun).max(1e-4 * s.dx),
            "the cuts differ by {other:e}, a rerun by {rerun:e}"
        );
    }
}
