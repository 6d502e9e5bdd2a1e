//! Double vs single precision on the CPU: the f64 backend computes the same physics as the f32
//! one (agreement within f32 rounding), and its state really is f64 (free fall exact to 1e-12).

use rtmpm_scene::{Precision, Scene};
use rtmpm_sim::Backend;

/// A small elastic block thrown up and sideways in a 1 m box: `vy0` up, 0.5 m/s along x.
fn scene(extra: &str) -> Scene {
    let text = format!(
        r#"
name = "throw"
gravity = [0.0, -9.81, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.05
[time]
duration = 1.0
fps = 10
dt = 1e-3
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 2.0e4
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "box"
min = [0.25, 0.45, 0.45]
max = [0.35, 0.55, 0.55]
particles_per_cell = 8
sampling = "regular"
velocity = [0.5, 2.0, 0.0]
{extra}
"#
    );
    Scene::from_toml(&text, "throw").expect("valid scene")
}

#[test]
fn scene_selects_precision() {
    assert_eq!(scene("").precision, Precision::F32);
    let s = scene("[solver]\nprecision = \"f64\"");
    assert_eq!(s.precision, Precision::F64);
    let e = Scene::from_toml(
        &format!(
            "{}\n[solver]\nprecision = \"f16\"",
            "[domain]\nmin=[0,0,0]\nmax=[1,1,1]\ndx=0.1\n[time]\nduration=1\ndt=1e-3"
        ),
        "bad",
    )
    .expect_err("f16 is not a precision");
    let text = e.to_string();
    assert!(
        text.contains("f32") && text.contains("f64") && text.contains("solver"),
        "{text}"
    );
}

/// Free fall of a stress-free block: every particle follows the discrete symplectic Euler
/// trajectory `x_n = x_0 + n dt v_0 + g dt^2 n (n + 1) / 2` exactly, up to rounding (P2G and G2P
/// reproduce a uniform velocity by the partition of unity). After 400 steps f64 is on it to
/// 1e-12 m; f32 is off by rounding (about 1e-6 m). Read from the backends' own state, not
/// through the f32 interface.
#[test]
fn f64_free_fall_is_exact_to_rounding() {
    let s = scene("");
    let p0 = s.sample_particles().expect("particles");
    let steps = 400usize;
    let mut b64 = rtmpm_cpu_f64::CpuBackend::new(&s, p0.clone(), Some(1)).expect("f64");
    let mut b32 = rtmpm_cpu::CpuBackend::new(&s, p0.clone(), Some(1)).expect("f32");
    for n in 0..steps {
        b64.step(1e-3, n as f32 * 1e-3).expect("step");
        b32.step(1e-3, n as f32 * 1e-3).expect("step");
    }
    // dt, v0 and g as the backends see them: the scene's f32 values, exactly widened.
    let dt = 1e-3f32 as f64;
    let (v0, g) = (s.bodies[0].velocity.as_dvec3(), s.gravity.as_dvec3());
    let n = steps as f64;
    let exact = |x0: glam::Vec3| x0.as_dvec3() + n * dt * v0 + g * (dt * dt * n * (n + 1.0) / 2.0);
    let err64 = b64
        .ids
        .iter()
        .zip(&b64.particles.x)
        .map(|(&id, &x)| (x - exact(p0.x[id as usize])).length())
        .fold(0.0, f64::max);
    let err32 = b32
        .ids
        .iter()
        .zip(&b32.particles.x)
        .map(|(&id, &x)| (x.as_dvec3() - exact(p0.x[id as usize])).length())
        .fold(0.0, f64::max);
    println!("free fall, {steps} steps: max position error f64 {err64:.3e} m, f32 {err32:.3e} m");
    assert!(err64 < 1e-12, "f64 free fall off by {err64:e} m");
    // The test can tell the precisions apart: f32 rounding is far above that.
    assert!(err32 > 1e3 * err64.max(1e-15), "f32 error {err32:e} m");
}

/// The same throw in both precisions, through the f32 interface: after 200 steps every
/// particle agrees within the f32 rounding the positions can accumulate, one ulp of the 1 m
/// domain per step (200 x 1.2e-7 m = 2.4e-5 m, half a thousandth of a cell).
#[test]
fn f64_agrees_with_f32() {
    let s = scene("");
    let p0 = s.sample_particles().expect("particles");
    let mut b64 = rtmpm_cpu_f64::CpuBackend::new(&s, p0.clone(), None).expect("f64");
    let mut b32 = rtmpm_cpu::CpuBackend::new(&s, p0.clone(), None).expect("f32");
    assert!(b64.name().contains("f64"), "{}", b64.name());
    for n in 0..200 {
        b64.step(1e-3, n as f32 * 1e-3).expect("step");
        b32.step(1e-3, n as f32 * 1e-3).expect("step");
    }
    let (mut a, mut b) = (
        rtmpm_physics::Particles::default(),
        rtmpm_physics::Particles::default(),
    );
    b64.read_particles(&mut a).expect("read");
    b32.read_particles(&mut b).expect("read");
    assert_eq!(a.len(), p0.len());
    let worst_x = (0..a.len())
        .map(|i| (a.x[i] - b.x[i]).length())
        .fold(0.0, f32::max);
    let worst_f = (0..a.len())
        .map(|i| {
            (a.f[i] - b.f[i])
                .abs()
                .to_cols_array()
                .into_iter()
                .fold(0.0, f32::max)
        })
        .fold(0.0, f32::max);
    println!("200 steps: max |x64 - x32| {worst_x:.3e} m, max |F64 - F32| {worst_f:.3e}");
    let extent = (s.domain_max - s.domain_min).max_element();
    let tol = 200.0 * f32::EPSILON * extent;
    assert!(
        worst_x < tol,
        "positions differ by {worst_x:e} m (tolerance {tol:e})"
    );
    assert!(
        worst_f < 1e-4,
        "deformation gradients differ by {worst_f:e}"
    );
    // And they are not the same computation: f64 rounds differently.
    assert!(worst_x > 0.0, "f64 and f32 gave bit-identical positions");
}
