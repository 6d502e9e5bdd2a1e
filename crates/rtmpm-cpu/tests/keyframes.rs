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
