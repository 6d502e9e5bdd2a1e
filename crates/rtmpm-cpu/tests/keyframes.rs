//! Keyframed colliders in the CPU backend: keys that describe a constant motion move the
//! material exactly as the collider with that constant velocity does, and a keyframed paddle
//! drags the fluid it sweeps at the keyframes' speed.

mod common;

use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;

const BASE: &str = r#"name = "k"
gravity = [0.0, 0.0, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.0625
[time]
duration = 0.1
fps = 10
dt = 1e-3
[[material]]
name = "goo"
type = "herschel_bulkley"
density = 1000.0
bulk_modulus = 1e5
shear_modulus = 1e4
yield_stress = 10.0
consistency = 5.0
[[body]]
material = "goo"
shape = "box"
min = [0.25, 0.25, 0.25]
max = [0.75, 0.75, 0.75]
sampling = "regular"
[[collider]]
shape = "box"
min = [0.4, 0.2, 0.3]
max = [0.6, 0.8, 0.7]
condition = "sticky"
"#;

fn run(motion: &str) -> rtmpm_sim::Particles {
    let text = format!("{BASE}{motion}\n");
    let scene = Scene::from_toml(&text, "k").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, Some(1)).expect("backend");
    let mut sim = Simulation::new(scene, Box::new(backend));
    sim.advance_frame().expect("stable");
    let mut out = rtmpm_sim::Particles::default();
    sim.backend.read_particles(&mut out).expect("read");
    out
}

fn max_difference(a: &rtmpm_sim::Particles, b: &rtmpm_sim::Particles) -> f32 {
    a.x.iter()
        .zip(&b.x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}

#[test]
fn keys_of_a_constant_motion_equal_the_constant_velocity_collider() {
    let constant = run("velocity = [0.5, 0.0, 0.0]\nangular_velocity = [0.0, 2.0, 0.0]");
    // The same motion as keys: the pivot 0.5 m/s along x, a quarter of the 2 rad/s turn per
    // key (0.25 s apart: 0.5 rad).
    let keys = (0..5)
        .map(|k| {
            let t = 0.25 * k as f32;
            format!(
                "{{ t = {t}, position = [{}, 0.5, 0.5], rotation = [0.0, {}, 0.0] }}",
                0.5 + 0.5 * t,
                2.0 * t
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    let keyed = run(&format!("keyframes = [{keys}]"));
    // Same poses and velocities up to f32 rounding of the two formulas (quaternion against
    // axis-angle matrix): the particles end within 1e-5 m (dx = 0.0625 m).
    let d = max_difference(&constant, &keyed);
    assert!(d < 1e-5, "keyed and constant differ by {d} m");
    // And the material did move: the paddle drags it.
    let still = run("");
    assert!(max_difference(&constant, &still) > 0.01);
}

#[test]
fn a_keyed_paddle_drags_the_material_at_the_keys_speed() {
    // The paddle moves 0.1 m along z during the frame, then holds.
    let p = run("keyframes = [{ t = 0.0 }, { t = 0.1, position = [0.5, 0.5, 0.6] }]");
    // Particles whose whole stencil lies in the sticky paddle (the paddle is 0.2 m thick; the
    // lattice particles at x = 0.484 and 0.516 reach the nodes at x = 0.4375 .. 0.5625) move
    // with it at 1 m/s.
    let mut n = 0;
    for (x, v) in p.x.iter().zip(&p.v) {
        let rel = *x - glam::Vec3::new(0.5, 0.5, 0.6);
        if rel.x.abs() < 0.02 && rel.y.abs() < 0.2 && rel.z.abs() < 0.1 {
            n += 1;
            assert!(
                (*v - glam::Vec3::Z).length() < 1e-3,
                "particle at {x} moves at {v}"
            );
        }
    }
    assert!(n > 10, "{n} particles in the paddle");
}

#[test]
fn a_fast_keyed_segment_between_two_cfl_steps_is_followed() {
    // CFL steps (about 2.4 ms for the goo's sound speed) and a paddle that holds still, moves
    // 0.05 m along z in 1 ms (50 m/s) from t = 0.031, then holds: a step from before the key
    // to after the segment saw the paddle still at its start and then found it moved, having
    // passed through the material unseen. The step ends at the key and follows the segment,
    // so the material in the sticky paddle moves with it.
    let text = BASE.replace("dt = 1e-3", "cfl = 0.4\nmax_dt = 5e-3")
        + "keyframes = [{ t = 0.0 }, { t = 0.031 }, { t = 0.032, position = [0.5, 0.5, 0.55] }]\n";
    let scene = Scene::from_toml(&text, "k").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let centre =
        p.x.iter()
            .position(|x| (*x - glam::Vec3::splat(0.5)).length() < 0.03)
            .expect("a particle near the centre");
    let z0 = p.x[centre].z;
    let backend = CpuBackend::new(&scene, p, Some(1)).expect("backend");
    let mut sim = Simulation::new(scene, Box::new(backend));
    let mut fastest = 0.0f32;
    while sim.time < 0.04 {
        let dt = sim.next_dt().expect("a step");
        let (t0, t1) = (sim.time, sim.time + dt as f64);
        // The part of the step within the segment moves the paddle 50 m/s x that time.
        let inside = (t1.min(0.032) - t0.max(0.031)).max(0.0) as f32;
        fastest = fastest.max(50.0 * inside);
        sim.step_once(dt).expect("stable");
    }
    // No step lets the paddle move more than the CFL fraction of a cell unseen.
    assert!(
        fastest <= 0.4 * 0.0625 + 1e-6,
        "{fastest} m unseen in a step"
    );
    let mut out = rtmpm_sim::Particles::default();
    sim.backend.read_particles(&mut out).expect("read");
    // It moves with the paddle: 0.05 m, and at most one step's motion more (the step that
    // holds the segment's end moves the material at the segment's speed throughout: at most
    // the CFL fraction of a cell, 0.025 m). A paddle passed over unseen leaves it still.
    let dz = out.x[centre].z - z0;
    assert!(
        dz > 0.04 && dz < 0.05 + 0.4 * 0.0625,
        "the centre moved {dz} m along z"
    );
}

#[test]
fn a_blow_up_from_a_keyed_segment_within_the_failed_step_blames_the_collider() {
    // Fixed steps of 1 ms; the paddle jumps 0.1 m in the first 0.3 ms of the step from
    // t = 0.03 (333 m/s: 5 cells in the step) and holds still by the step's end. The material
    // it drags is flung faster than 2 cells per step: the advice names the keyframes that did
    // it, not the time step or the material's stiffness.
    let text = format!(
        "{BASE}keyframes = [{{ t = 0.0 }}, {{ t = 0.03 }}, \
         {{ t = 0.0303, position = [0.5, 0.5, 0.6] }}]\n"
    );
    let scene = Scene::from_toml(&text, "k").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, Some(1)).expect("backend");
    let mut sim = Simulation::new(scene, Box::new(backend));
    let e = sim.advance_frame().expect_err("a blow-up").to_string();
    assert!(
        e.contains("blew up") && e.contains("collider[0].keyframes"),
        "{e}"
    );
    assert!(!e.contains("softer material"), "{e}");
}
