//! What the tests of worlds in a batch (`tests/batch_*.rs`) share: the precise options they
//! compare with, the wedge example's worlds, the sand bed of the put and benchmark tests, and
//! the comparison of a batch's world with its separate run (the agreement test's tolerances,
//! `tests/agreement.rs`).

use rtmpm_cuda::CudaOptions;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::{BatchScene, Scene};
use std::path::{Path, PathBuf};

/// Precise math, as the agreement tests compare.
pub fn precise() -> CudaOptions {
    CudaOptions {
        fast_math: false,
        ..CudaOptions::default()
    }
}

/// The time step of the wedge worlds' tests.
pub const DT: f32 = 1e-3;

/// The wedge example, `scenes/wedge_slump.toml` (a batch of 16 worlds).
pub fn wedge_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/wedge_slump.toml")
}

/// The wedge example's 16 worlds (yield stress 25..1600 Pa), each with its own gravity too
/// (strength 0.6..1.35 g, and a sideways pull of -1, 0 or +1 m/s^2 along x).
pub fn wedge_worlds(count: usize) -> Vec<Scene> {
    let b = BatchScene::from_file(&wedge_path()).expect("wedge_slump.toml");
    b.worlds
        .into_iter()
        .take(count)
        .enumerate()
        .map(|(w, mut s)| {
            s.gravity = Vec3::new((w % 3) as f32 - 1.0, -9.81 * (0.6 + 0.05 * w as f32), 0.0);
            s
        })
        .collect()
}

/// The largest distance and the largest velocity difference of a particle of `a` from the
/// same particle of `b`.
pub fn max_diff(a: &Particles, b: &Particles) -> (f32, f32) {
    assert_eq!(a.len(), b.len());
    let mut dx = 0.0f32;
    let mut dv = 0.0f32;
    for i in 0..a.len() {
        dx = dx.max((a.x[i] - b.x[i]).length());
        dv = dv.max((a.v[i] - b.v[i]).length());
    }
    (dx, dv)
}

/// True when the positions and velocities of `a` and `b` are the same bit for bit.
pub fn bit_identical(a: &Particles, b: &Particles) -> bool {
    let bits = |p: &Particles| {
        p.x.iter()
            .chain(&p.v)
            .flat_map(|v| v.to_array())
            .map(f32::to_bits)
            .collect::<Vec<_>>()
    };
    bits(a) == bits(b)
}

/// The agreement test's tolerances (tests/agreement.rs) between a world of the batch and its
/// separate run: after one step every particle (|dx| <= 1e-5 dx + 1e-6, |dv| <= 1e-3 of the
/// speed scale); after `steps` the centre of mass within 0.1 cell, kinetic energy within 2 %,
/// bounding box within a cell.
pub fn agrees(
    what: &str,
    one_step: Option<(&Particles, &Particles)>,
    a: &Particles,
    b: &Particles,
    dx: f32,
) -> Vec<String> {
    let mut failures = Vec::new();
    if let Some((a1, b1)) = one_step {
        let vscale = a1.v.iter().map(|v| v.length()).fold(1e-3f32, f32::max);
        let (wx, wv) = max_diff(a1, b1);
        if wx > 1e-5 * dx.max(1e-3) + 1e-6 || wv > 1e-3 * vscale {
            failures.push(format!(
                "{what}: first step differs: |dx| {wx:.3e}, |dv| {wv:.3e}"
            ));
        }
    }
    let d = a.aggregate_difference(b);
    let (wx, wv) = max_diff(a, b);
    let dxd = dx as f64;
    println!(
        "{what}: |d com| {:.3e} m ({:.4} dx), KE {:.4e} vs {:.4e} ({:.3} %), |d bbox| {:.2} dx, max particle |dx| {wx:.3e} m |dv| {wv:.3e} m/s",
        d.com,
        d.com / dxd,
        a.kinetic_energy(),
        b.kinetic_energy(),
        100.0 * d.kinetic,
        d.bbox / dxd
    );
    if d.com > 0.1 * dxd || d.kinetic > 0.02 || d.bbox > dxd {
        failures.push(format!("{what}: aggregates differ"));
    }
    failures
}

/// A small sand bed: 14 x 6 x 14 cells of sand at 8 particles a cell (9,408 particles) dropped
/// 3 cells onto a sticky floor in a 32 x 20 x 32-cell box (dx = 1/64 m), fixed dt.
pub fn sand_bed(half: f32) -> String {
    let lo = 0.25 - half;
    let hi = 0.25 + half;
    let (dmin, dmax) = (0.0, 0.5 + 2.0 * (half - 0.109375).max(0.0));
    let shift = (dmax - 0.5) / 2.0;
    format!(
        r#"
name = "sand_bed"
seed = 1
[domain]
min = [{dmin}, 0.0, {dmin}]
max = [{dmax}, 0.3125, {dmax}]
dx = 0.015625
[time]
duration = 1.0
fps = 50
dt = 2.5e-4
[walls]
condition = "slip"
faces.y_min = {{ condition = "sticky" }}
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 35.0
[[body]]
material = "sand"
shape = "box"
min = [{a}, 0.09375, {a}]
max = [{b}, 0.1875, {b}]
particles_per_cell = 8
sampling = "regular"
"#,
        a = lo + shift,
        b = hi + shift
    )
}
