//! Scratch (not committed): the Archimedes check of `rtmpm validate` (full: dx / 4, 3 s) for one
//! density on the CPU backend, with the same scene edits and measurement.
#![cfg(feature = "rigid")]
use rtmpm_core::Scene;
use rtmpm_core::checks;
use rtmpm_core::cpu::CpuBackend;
use rtmpm_core::sim::Simulation;
const ARCHIMEDES: &str = include_str!("../../../validation/archimedes.toml");

#[test]
#[ignore]
fn full() {
    let density: f64 = std::env::var("DENSITY").unwrap().parse().unwrap();
    let base = checks::refine(ARCHIMEDES, 4).unwrap();
    let base = checks::edit_toml(&base, &[("time.duration", 3.0.into())]).unwrap();
    let text = checks::edit_toml(&base, &[("rigid_body.0.density", density.into())]).unwrap();
    let scene = Scene::from_toml(&text, "archimedes.toml").unwrap();
    let p = scene.sample_particles().unwrap();
    println!("dx {} particles {}", scene.dx, p.len());
    let backend = CpuBackend::new(&scene, p, None).unwrap();
    let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
    let t0 = std::time::Instant::now();
    let f = checks::float(&mut sim, |t, y| {
        println!("t {t:.3} centre {y:.5} wall {:.0} s", t0.elapsed().as_secs_f64())
    })
    .unwrap();
    let expect = density / 1000.0;
    let v = f.volume_fraction.unwrap();
    println!(
        "density {density}: fraction {:.4} ({:+.2} %), volume {:.4} ({:+.2} %), mean tilt {:.1} deg, centre {:.5}, surface {:.5}, {:.0} s",
        f.fraction, (f.fraction / expect - 1.0) * 100.0, v, (v / expect - 1.0) * 100.0,
        f.mean_tilt_degrees, f.centre, f.surface, t0.elapsed().as_secs_f64()
    );
}
