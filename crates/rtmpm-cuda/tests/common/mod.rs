//! Helpers shared by the GPU test files of worlds in a batch (`tests/batch_*.rs`: the batch's
//! worlds against their separate runs) and of several GPUs (`tests/multi_gpu_*.rs`: several
//! GPUs against one): whether a GPU is there, reading a backend's particles; the comparisons of
//! a batch's worlds ([`batch`]) and the set-up of the runs on several GPUs ([`multi`]).
#![allow(dead_code)] // each test binary uses its part

pub mod batch;
pub mod multi;

use rtmpm_physics::Particles;
use rtmpm_physics::boundary::Walls;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::{OutputSettings, Scene, StepMode, TimeSettings};
use rtmpm_sim::Backend;

/// True when a usable CUDA GPU is there; else says why the test is skipped.
pub fn gpu() -> bool {
    match rtmpm_cuda::probe() {
        Ok(_) => true,
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

/// Every particle of `b`.
pub fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}

/// A unit cube of one material, cell size `dx`, gravity, the fixed step `dt`, default walls and
/// solver, no bodies (the kernel tests place their own particles): the scene of the kernel
/// switch tests (`tests/addressing.rs`, `tests/pdl.rs`).
pub fn unit_cube_scene(name: &str, dx: f32, dt: f32, material: Material) -> Scene {
    Scene {
        name: name.into(),
        source: None,
        domain_min: Vec3::ZERO,
        domain_max: Vec3::ONE,
        dx,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        time: TimeSettings {
            duration: 1.0,
            fps: 30.0,
            step: StepMode::Fixed { dt },
            damping: Default::default(),
        },
        materials: vec![material],
        bodies: vec![],
        colliders: vec![],
        emitters: vec![],
        rigid_bodies: vec![],
        joints: vec![],
        walls: Walls::default(),
        output: OutputSettings {
            dir: "out".into(),
            stress: false,
            jacobian: false,
            ..Default::default()
        },
        render: Default::default(),
        seed: 0,
        solver: Default::default(),
        precision: Default::default(),
        particle_state: Default::default(),
        files: Vec::new(),
    }
}
