//! The host bodies' timings on this machine (ignored: they print, they check nothing): a step's
//! advance of worlds at rest and of moving tools, the pose reads and the pose path of a script
//! posing a tool in 256 worlds. Run one with `cargo test --release -p rtmpm-cuda --features
//! rigid --lib NAME -- --ignored --nocapture`.

use super::*;

/// A step's advance of 256 worlds whose kinematic tool stands still (bench/python_batch_gpu.py's
/// bare, calls and reset modes) with the worlds at rest skipped and with every world stepped
/// (`RTMPM_BATCH_REST=old`), on this machine (`cargo test --release -p rtmpm-cuda --features
/// rigid --lib rest_advance_timing -- --ignored --nocapture`; no GPU). Medians of 200 steps.
#[test]
#[ignore = "a timing, not a check"]
fn rest_advance_timing() {
    use std::time::Instant;
    let n = 256;
    for skip in [true, false] {
        let mut h = HostBodies::new(
            (0..n).map(|_| tool_world()).collect(),
            vec![0],
            BodyPoses::Deferred,
        );
        let mut times = Vec::new();
        for _ in 0..200 {
            let t0 = Instant::now();
            h.advance_skipping(None, 4e-4, skip);
            times.push(t0.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{}: a step's advance of {n} worlds at rest {:.1} us (median of 200), {} stepped at the last",
            if skip {
                "at rest skipped"
            } else {
                "every world stepped (RTMPM_BATCH_REST=old)"
            },
            1e6 * times[100],
            h.stepped()
        );
    }
}

/// The lockstep driver's reads of every world's poses (twice a call: as the advance begins
/// and after it) on this machine, 256 worlds of one tool behind the batch's lock: world by
/// world (`world_rigid_poses_into`, a lock a world) against `each_poses` (one lock), caches
/// warm and flushed (`cargo test --release -p rtmpm-cuda --features rigid --lib
/// pose_reads_timing -- --ignored --nocapture`; no GPU). Medians of 200.
#[test]
#[ignore = "a timing, not a check"]
fn pose_reads_timing() {
    use std::sync::Mutex;
    use std::time::Instant;
    let n = 256;
    let h = Mutex::new(HostBodies::new(
        (0..n).map(|w| world(w, false)).collect(),
        vec![0],
        BodyPoses::Deferred,
    ));
    let mut kept: Vec<Vec<BodyPose>> = vec![Vec::new(); n];
    let mut junk = vec![0u8; 64 << 20];
    for cold in [false, true] {
        let (mut one, mut all) = (Vec::new(), Vec::new());
        for _ in 0..200 {
            let mut flush = || {
                if cold {
                    for (i, b) in junk.iter_mut().enumerate().step_by(64) {
                        *b = b.wrapping_add(i as u8);
                    }
                }
            };
            flush();
            let t0 = Instant::now();
            for (w, out) in kept.iter_mut().enumerate() {
                h.lock().expect("lock").poses_into(w, out);
            }
            one.push(t0.elapsed().as_secs_f64());
            flush();
            let t0 = Instant::now();
            h.lock().expect("lock").each_poses(&mut |w, p| {
                kept[w].clear();
                kept[w].extend_from_slice(p);
            });
            all.push(t0.elapsed().as_secs_f64());
        }
        let med = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            1e6 * v[v.len() / 2]
        };
        println!(
            "caches {}: every world's poses read world by world {:.1} us, at once {:.1} us \
             ({n} worlds, medians of 200)",
            if cold { "flushed" } else { "warm" },
            med(one),
            med(all)
        );
    }
    std::hint::black_box(&junk);
}

/// Where a script's pose call goes on the host (`cargo test --release -p rtmpm-cuda
/// --features rigid --lib pose_path_timing -- --ignored --nocapture`; no GPU): 256 worlds of
/// one kinematic tool (bench/python_batch_gpu.py's), 200 calls of [every world advanced on
/// every core (a step's `after_step`); with `cold`, 64 MB written (the rest of a step's host
/// work and the device's, which leave the worlds' memory out of this thread's caches); the
/// call: each world's tool read, moved, and the 256 poses given (`set_body_poses`); the next
/// step's upload (`records`)], for the rapier worlds posed at once as before the rows
/// (`plain`), `body_poses=eager`, `deferred_serial` and `deferred`. Prints the median microseconds of the call
/// and of the upload.
#[test]
#[ignore = "a timing, not a check"]
fn pose_path_timing() {
    use std::time::Instant;
    let n = 256;
    let mut junk = vec![0u8; 64 << 20];
    let med = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        1e6 * v[v.len() / 2]
    };
    for cold in [false, true] {
        for mode in ["plain", "eager", "deferred_serial", "deferred"] {
            let mut h = HostBodies::new(
                (0..n).map(|_| tool_world()).collect(),
                vec![0],
                match mode {
                    "deferred" => BodyPoses::Deferred,
                    "deferred_serial" => BodyPoses::DeferredSerial,
                    _ => BodyPoses::Eager,
                },
            );
            let mut plain = Plain((0..n).map(|_| tool_world()).collect(), vec![0]);
            let (mut call, mut upload, mut advance) = (Vec::new(), Vec::new(), Vec::new());
            for c in 0..200 {
                let t0 = Instant::now();
                if mode == "plain" {
                    let none = [Exchange::default()];
                    plain.0.par_iter_mut().for_each(|w| w.advance(&none, 4e-4));
                } else {
                    h.advance(None, 4e-4);
                }
                advance.push(t0.elapsed().as_secs_f64());
                if cold {
                    for (i, b) in junk.iter_mut().enumerate().step_by(64) {
                        *b = b.wrapping_add(i as u8);
                    }
                }
                let y = 0.22 - 1e-5 * c as f32;
                let t0 = Instant::now();
                if mode == "plain" {
                    for w in plain.0.iter_mut() {
                        let mut p = w.pose(0).expect("tool");
                        p.position.y = y;
                        p.velocity = Vec3::new(0.0, -0.2, 0.0);
                        w.set_pose(0, &p).expect("pose");
                    }
                } else {
                    let poses: Vec<(usize, BodyPose)> = (0..n)
                        .map(|w| {
                            let mut p = h.pose(w, 0).expect("tool");
                            p.position.y = y;
                            p.velocity = Vec3::new(0.0, -0.2, 0.0);
                            (w, p)
                        })
                        .collect();
                    h.set_body_poses(0, &poses).expect("poses");
                }
                call.push(t0.elapsed().as_secs_f64());
                let t0 = Instant::now();
                let bytes = if mode == "plain" {
                    plain.records().len()
                } else {
                    h.records().len()
                };
                std::hint::black_box(bytes);
                upload.push(t0.elapsed().as_secs_f64());
            }
            println!(
                "{mode:>8}, caches {}: the call {:.1} us, the next upload {:.1} us, a step's \
                 advance of the worlds {:.1} us (medians of 200, {n} worlds)",
                if cold { "flushed" } else { "warm" },
                med(call),
                med(upload),
                med(advance)
            );
        }
    }
    std::hint::black_box(&junk);
}

/// A step's advance of 256 worlds whose kinematic tool moves down at 0.2 m/s
/// (bench/python_batch_gpu.py's `--moving-tool`, and its pose and loop modes' steps) on this
/// machine, through rapier's step (`RTMPM_KINEMATIC=rapier`) and by the worlds' own integration
/// of their tools (`RigidWorld::advance`), first the worlds' advance alone on one thread, then
/// the batch's (with its rows) spread over the cores in each way of [`Fan`] (`cargo test
/// --release -p rtmpm-cuda --features rigid --lib moving_advance_timing -- --ignored
/// --nocapture`; no GPU). Medians of 200 steps.
#[test]
#[ignore = "a timing, not a check"]
fn moving_advance_timing() {
    use std::time::Instant;
    let n = 256;
    let moving = |rapier: bool| {
        let mut w = tool_world();
        if rapier {
            w = w.with_rapier_steps();
        }
        let mut p = w.pose(0).expect("tool");
        p.velocity = Vec3::new(0.0, -0.2, 0.0);
        w.set_pose(0, &p).expect("pose");
        w
    };
    let fans = [
        (true, Fan::Cores(1)),
        (false, Fan::Cores(1)),
        (false, Fan::Cores(16)),
        (false, Fan::Cores(64)),
        (false, Fan::Serial),
    ];
    // The rapier worlds' advance alone, one after the other on this thread (no rows).
    for rapier in [true, false] {
        let mut worlds: Vec<RigidWorld> = (0..n).map(|_| moving(rapier)).collect();
        let none = [Exchange::default()];
        let mut times = Vec::new();
        for _ in 0..200 {
            let t0 = Instant::now();
            for w in worlds.iter_mut() {
                w.advance(&none, 4e-4);
            }
            times.push(t0.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{}: RigidWorld::advance of {n} worlds of a moving tool on one thread {:.1} us \
             (median of 200)",
            if rapier {
                "rapier's step"
            } else {
                "own integration"
            },
            1e6 * times[100]
        );
    }
    for (rapier, fan) in fans {
        let worlds = (0..n).map(|_| moving(rapier)).collect();
        let mut h = HostBodies::new(worlds, vec![0], BodyPoses::Deferred);
        let mut times = Vec::new();
        for _ in 0..200 {
            let t0 = Instant::now();
            h.advance_fanned(None, 4e-4, true, fan);
            times.push(t0.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{}, {fan:?}: a step's advance of {n} worlds of a moving tool {:.1} us (median of \
             200, min {:.1}), {} stepped",
            if rapier {
                "rapier's step"
            } else {
                "own integration"
            },
            1e6 * times[100],
            1e6 * times[0],
            h.stepped()
        );
    }
}
