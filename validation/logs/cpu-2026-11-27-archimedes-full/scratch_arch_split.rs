//! Scratch (not committed): the full Archimedes run (dx / 4, 3 s) for one density on the CPU
//! backend in two halves, A (frames 0-30, then a checkpoint) and B (resume, frames 30-60,
//! measured by checks::float over the last 10 frames as `rtmpm validate` does).
#![cfg(feature = "rigid")]
use rtmpm_core::Scene;
use rtmpm_core::checks;
use rtmpm_core::cpu::CpuBackend;
use rtmpm_core::io::checkpoint::Checkpoint;
use rtmpm_core::sim::{Backend, Simulation};
const ARCHIMEDES: &str = include_str!("../../../validation/archimedes.toml");

#[test]
#[ignore]
fn half() {
    let density: f64 = std::env::var("DENSITY").unwrap().parse().unwrap();
    let path = std::path::PathBuf::from(std::env::var("CKPT").unwrap());
    let t0 = std::time::Instant::now();
    if std::env::var("PART").unwrap() == "A" {
        let base = checks::refine(ARCHIMEDES, 4).unwrap();
        let base = checks::edit_toml(&base, &[("time.duration", 3.0.into())]).unwrap();
        let text = checks::edit_toml(&base, &[("rigid_body.0.density", density.into())]).unwrap();
        let scene = Scene::from_toml(&text, "archimedes.toml").unwrap();
        let p = scene.sample_particles().unwrap();
        println!("dx {} particles {}", scene.dx, p.len());
        let backend = CpuBackend::new(&scene, p, None).unwrap();
        let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
        for _ in 0..30 {
            sim.advance_frame().unwrap();
            let b = sim.backend.rigid_poses();
            println!("t {:.3} {:?} wall {:.0} s", sim.time, b[0], t0.elapsed().as_secs_f64());
        }
        let mut p = rtmpm_core::Particles::default();
        sim.backend.read_particles(&mut p).unwrap();
        let ck = Checkpoint {
            scene_toml: text,
            scene_origin: "archimedes.toml".into(),
            time: sim.time,
            step: sim.step,
            frame: sim.frame,
            bodies: sim.backend.rigid_poses(),
            particles: p,
        };
        ck.save(&path).unwrap();
        println!("saved frame {} step {} time {}", ck.frame, ck.step, ck.time);
    } else {
        let back = Checkpoint::load(&path).unwrap();
        // The second half: the scene's remaining 1.5 s, so that float runs frames 30-60 and
        // averages the last 10 (2.5-3.0 s), as the uninterrupted run does.
        let text = checks::edit_toml(&back.scene_toml, &[("time.duration", 1.5.into())]).unwrap();
        let scene = Scene::from_toml(&text, "archimedes.toml").unwrap();
        let backend = CpuBackend::new(&scene, back.particles, None).unwrap();
        let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
        sim.time = back.time;
        sim.step = back.step;
        sim.frame = back.frame;
        sim.backend.set_rigid_poses(&back.bodies).unwrap();
        println!("resumed frame {} step {} time {}", sim.frame, sim.step, sim.time);
        let f = checks::float(&mut sim, |t, y| {
            println!("t {t:.3} centre {y:.5} wall {:.0} s", t0.elapsed().as_secs_f64())
        })
        .unwrap();
        let expect = density / 1000.0;
        let v = f.volume_fraction.unwrap();
        println!(
            "density {density}: fraction {:.4} ({:+.2} %), volume {:.4} ({:+.2} %), mean tilt {:.1} deg, centre {:.5}, surface {:.5}, t end {:.3}",
            f.fraction, (f.fraction / expect - 1.0) * 100.0, v, (v / expect - 1.0) * 100.0,
            f.mean_tilt_degrees, f.centre, f.surface, sim.time
        );
    }
}
