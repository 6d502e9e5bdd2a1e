//! Emitters in the CPU backend: the emitted mass after t equals rate x t within one particle,
//! the particles appear with the emitter's velocity and material, and bad emitters are refused.

mod common;

use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;

/// The scene of `rtmpm validate --case emitter_mass`.
const FOUNTAIN: &str = include_str!("../../../validation/emitter_mass.toml");

fn simulation(text: &str) -> Simulation {
    let scene = Scene::from_toml(text, "e").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    Simulation::new(scene, Box::new(backend))
}

#[test]
fn emitted_mass_is_rate_times_time_within_one_particle() {
    let mut sim = simulation(FOUNTAIN);
    let mut p = rtmpm_sim::Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    let body = p.len();
    let em = sim.scene.emitters[0].clone();
    // The sand's own mass stays; the water's mass grows as rate (t - start) while emitting.
    let e = rtmpm_driver::checks::emission(&mut sim).expect("stable");
    println!("{e:?}");
    assert!(e.worst_particles <= 1.0 + 1e-6, "{e:?}");
    assert!((e.expected - 900.0).abs() < 1e-9, "{e:?}");
    sim.backend.read_particles(&mut p).expect("read");
    assert_eq!(sim.emitted()[0], 900);
    assert_eq!(p.len(), body + 900);
    // The emitted particles are water with the emitter's mass; those emitted in the last step
    // still move upwards (they left the emitter at 1.5 m/s).
    let water: Vec<usize> = (0..p.len()).filter(|&i| p.material[i] == 0).collect();
    assert!(
        water.iter().all(|&i| i >= body),
        "emitted particles follow the bodies' ones"
    );
    assert!(water.iter().all(|&i| p.mass[i] == em.particle_mass));
    assert!(water.iter().all(|&i| p.x[i].is_finite()));
}

#[test]
fn emission_does_not_depend_on_the_step_sizes() {
    // A fixed step and the CFL step emit the same particles at the same places.
    let fixed = FOUNTAIN.replacen("cfl = 0.4", "dt = 5e-4", 1);
    let mut a = simulation(FOUNTAIN);
    let mut b = simulation(&fixed);
    for _ in 0..4 {
        a.advance_frame().expect("stable");
        b.advance_frame().expect("stable");
    }
    assert_eq!(a.emitted(), b.emitted());
    assert_eq!(a.emitted()[0], 300);
    let pos = |s: &Simulation, j: u64| s.scene.emitters[0].position(j);
    assert_eq!(pos(&a, 17), pos(&b, 17));
}

#[test]
fn volume_rate_and_bad_emitters() {
    let volume = FOUNTAIN.replacen("rate = 3000.0", "volume_rate = 1e-3", 1);
    let s = Scene::from_toml(&volume, "e").unwrap();
    // 1e-3 m^3/s of particles of (dx / 2)^3.
    let per = (0.0625f64 / 2.0).powi(3);
    assert!((s.emitters[0].rate - 1e-3 / per).abs() < 1e-6 * s.emitters[0].rate);
    let bad = |from: &str, to: &str, field: &str| {
        assert!(FOUNTAIN.contains(from), "{from}");
        let e = Scene::from_toml(&FOUNTAIN.replacen(from, to, 1), "e").unwrap_err();
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert!(e.hint.is_some() && e.line.is_some(), "{e}");
        e
    };
    // Outside the domain minus the walls.
    let e = bad(
        "max = [0.55, 0.35, 0.55]",
        "max = [0.55, 0.99, 0.55]",
        "emitter[0].shape",
    );
    assert!(e.to_string().contains("domain minus the walls"), "{e}");
    bad("rate = 3000.0", "rate = -1.0", "emitter[0].rate");
    bad("rate = 3000.0", "", "emitter[0].rate");
    bad(
        "rate = 3000.0",
        "rate = 3000.0\nvolume_rate = 1e-3",
        "emitter[0].volume_rate",
    );
    bad("stop = 0.4", "stop = 0.05", "emitter[0].stop");
    bad(
        "material = \"water\"\nshape",
        "material = \"mud\"\nshape",
        "emitter[0].material",
    );
    bad("rate = 3000.0", "rate = 1e12", "emitter[0].rate");
    bad(
        "shape = \"box\"\nmin = [0.45",
        "shape = \"mesh\"\nmin = [0.45",
        "emitter[0].shape",
    );
}

#[test]
fn a_blow_up_from_an_emitter_that_stopped_within_the_failed_step_blames_the_emitter() {
    // Fixed steps of 1 ms; a jet at 500 m/s (8 cells a step) emits from t = 0.02 to 0.0205,
    // within one step: its particles are flung faster than 2 cells a step. At the step's end
    // the emitter has stopped; the advice still names it, not the time step or a stiffness.
    let text = "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.0625\n\
        [time]\nduration = 0.05\nfps = 20\ndt = 1e-3\n\
        [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e5\n\
        [[emitter]]\nname = \"jet\"\nmaterial = \"water\"\nshape = \"box\"\n\
        min = [0.45, 0.2, 0.45]\nmax = [0.55, 0.3, 0.55]\nvelocity = [0.0, 500.0, 0.0]\n\
        rate = 200000.0\nstart = 0.02\nstop = 0.0205\n";
    let mut sim = simulation(text);
    let e = sim.advance_frame().expect_err("a blow-up").to_string();
    assert!(
        e.contains("blew up")
            && e.contains("emitter[0] `jet`")
            && e.contains("emitter[0].velocity"),
        "{e}"
    );
}
