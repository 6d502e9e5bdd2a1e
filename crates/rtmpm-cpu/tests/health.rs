//! The health check after a step: a particle gone NaN is reported as not finite, at the NaN
//! position the step computed (not at the domain's corner the position is clamped to), and a
//! NaN deformation gradient alone is caught too.

use glam::{Mat3, Vec3};
mod common;

use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use rtmpm_sim::{ParticleEdit, SimError};

const SCENE: &str = r#"
name = "health"
gravity = [0.0, -9.81, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.1
fps = 50
dt = 5e-4
[[material]]
name = "jelly"
type = "neo_hookean"
density = 1000.0
youngs_modulus = 1e5
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "box"
min = [0.2, 0.2, 0.2]
max = [0.3, 0.3, 0.3]
"#;

fn simulation() -> Simulation<CpuBackend> {
    let scene = Scene::from_toml(SCENE, "health").expect("scene");
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    Simulation::with_backend(scene, Box::new(backend))
}

/// The blow-up of one step after `edit` changed particle `k`.
fn blowup_after(edit: impl Fn(usize, &mut [Vec3], &mut [Mat3])) -> rtmpm_sim::Blowup {
    let mut sim = simulation();
    let mut p = rtmpm_sim::Particles::default();
    rtmpm_sim::Backend::read_particles(sim.backend.as_mut(), &mut p).expect("read");
    let (mut v, mut f) = (p.v.clone(), p.f.clone());
    edit(17, &mut v, &mut f);
    sim.backend
        .set_fields(&ParticleEdit {
            v: Some(&v),
            f: Some(&f),
            ..Default::default()
        })
        .expect("edit");
    // The step checks the particles itself (or the next check does).
    match sim.step_once(5e-4).and_then(|()| sim.check()) {
        Err(SimError::Blowup(b)) => *b,
        other => panic!("no blow-up: {other:?}"),
    }
}

#[test]
fn a_nan_velocity_is_reported_as_nan_where_it_is() {
    let b = blowup_after(|k, v, _| v[k] = Vec3::new(f32::NAN, 0.0, 0.0));
    let text = SimError::Blowup(Box::new(b.clone())).to_string();
    assert!(b.reason.contains("not finite"), "{text}");
    assert!(!text.contains("cells per step"), "{text}");
    // The step's NaN position, not the clamped corner (0, 0, 0) of the domain.
    assert!(b.position.is_nan(), "{text}");
    assert!(b.velocity.is_nan(), "{text}");
    assert!(text.contains("NaN"), "{text}");
}

#[test]
fn a_nan_deformation_gradient_alone_is_caught() {
    let b = blowup_after(|k, _, f| f[k] = Mat3::from_diagonal(Vec3::new(1.0, f32::NAN, 1.0)));
    assert!(b.reason.contains("deformation gradient"), "{}", b.reason);
}
