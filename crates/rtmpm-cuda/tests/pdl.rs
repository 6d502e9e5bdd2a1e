//! GPU tests of programmatic dependent launch (`--cuda-options pdl=on`, Hopper and newer): the
//! step's kernels after its first launched with the attribute
//! `CU_LAUNCH_ATTRIBUTE_PROGRAMMATIC_STREAM_SERIALIZATION`, each waiting (`griddepcontrol.wait`,
//! `kernels/common.cuh`: `step_kernel_entry`) for the kernel before it before it touches device
//! memory. The same kernels' arithmetic in the same order, so
//!
//! 1. on a GPU of compute capability 9.0 or newer the backend reports the launches on
//!    ([`CudaBackend::pdl`]), off without the switch;
//! 2. with isolated particles (each grid node gets one particle's contribution: P2G's atomic
//!    sums are exact and the run is deterministic) `pdl=on` gives `pdl=off`'s particles bit for
//!    bit after 240 steps (rebuilds of the mapping among them): water (the fluid kernels), jelly
//!    and snow (the general ones, snow with its plasticity), with G2P2G and with separate G2P
//!    and P2G kernels, from the step's CUDA graph and without it (`graph=off`: the attribute on a
//!    plain stream), CK-MPM's fused kernels and a classic transfer with MUSL; f64 in a test of
//!    its own;
//! 3. on the benchmark scenes (fluid dam 2M, jelly drop 2M, snow 1.33M; dense, so P2G's atomic
//!    sums are not deterministic) `pdl=on` differs from `pdl=off` no more than four times as
//!    much as two runs of `pdl=off` differ from each other, or 1e-4 dx.
//!
//! A kernel that read the previous kernel's output before its wait would read a grid or a
//! particle state of the step before, and move the particles by far more than any of this.
//!
//! `cargo test -p rtmpm-cuda --test pdl -- --include-ignored`; the GPU tests skip with a message
//! when no usable CUDA device is present.

mod common;

use common::{gpu, read, unit_cube_scene};
use rtmpm_cuda::{CudaBackend, CudaOptions};
use rtmpm_physics::Particles;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_physics::transfer::{SolverSettings, Transfer, Update};
use rtmpm_scene::{Scene, StepMode};
use rtmpm_sim::Backend;

const DT: f32 = 2e-4;
const STEPS: usize = 240;

/// The material of a test scene.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Water,
    Jelly,
    Snow,
}

/// Unit cube, dx = 1/128, gravity, fixed dt, one material.
fn scene(kind: Kind) -> Scene {
    let material = match kind {
        Kind::Water => Material::parse("water", 1000.0, "fluid", "bulk_modulus = 1e4"),
        Kind::Jelly => {
            Material::parse("jelly", 1000.0, "fixed_corotated", "mu = 4e4\nlambda = 6e4")
        }
        // Stomakhin et al. 2013's reference snow: E = 1.4e5 Pa, nu = 0.2.
        Kind::Snow => Material::parse(
            "snow",
            400.0,
            "snow",
            "mu = 58333\nlambda = 38889\ncritical_compression = 2.5e-2\n\
             critical_stretch = 7.5e-3\nhardening = 10",
        ),
    }
    .expect("material");
    unit_cube_scene("pdl", 1.0 / 128.0, DT, material)
}

/// Particles every 5.25 cells in [0.2, 0.8]^3 (3,375 of them: their stencils never share a
/// node, and start at every cell offset of a block; they stay clear of the walls), spinning
/// about the block's centre and moving down at 1 m/s, so that v and C are far from zero and of
/// mixed signs and the particles leave their free zones (rebuilds) within the run.
fn isolated(s: &Scene) -> Particles {
    let (lo, hi, h) = (Vec3::splat(0.2), Vec3::splat(0.8), 5.25 * s.dx);
    let n = ((hi - lo) / h).round().as_uvec3();
    let centre = 0.5 * (lo + hi);
    let omega = Vec3::new(1.0, 2.0, 0.5).normalize() * 5.0;
    let vol = (s.dx / 2.0).powi(3);
    let mut p = Particles::default();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let x = lo + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * h;
                let v = omega.cross(x - centre) + Vec3::new(0.0, -1.0, 0.0);
                p.push(x, v, 1000.0 * vol, vol, 0, 0.0);
                let last = p.len() - 1;
                p.c[last] = Mat3::from_cols_array(&[
                    0.0, omega.z, -omega.y, -omega.z, 0.0, omega.x, omega.y, -omega.x, 0.0,
                ]);
            }
        }
    }
    p
}

/// `steps` steps of `dt`, then every particle (the run must stay healthy).
fn run(s: &Scene, p: &Particles, o: CudaOptions, dt: f32, steps: usize) -> Particles {
    let pdl = o.pdl;
    let mut b = CudaBackend::new(s, p, o).expect("backend");
    // On a GPU of compute capability 9.0 or newer the switch must take effect (else this file
    // would compare pdl=off with itself).
    let hopper = rtmpm_cuda::probe().expect("probe").compute_capability.0 >= 9;
    assert_eq!(
        b.pdl(),
        pdl && hopper,
        "pdl {pdl}, Hopper or newer {hopper}"
    );
    for i in 0..steps {
        b.step(dt, i as f32 * dt).expect("step");
    }
    assert_eq!(b.check().expect("check"), None);
    read(&mut b)
}

/// Particles of two runs equal bit for bit.
fn assert_bit_identical(what: &str, a: &Particles, b: &Particles) {
    assert_eq!(a.len(), b.len(), "{what}: particle count");
    let v3 = |v: Vec3| v.to_array().map(f32::to_bits);
    let m3 = |m: Mat3| m.to_cols_array().map(f32::to_bits);
    for i in 0..a.len() {
        assert_eq!(v3(a.x[i]), v3(b.x[i]), "{what}: x of {i}");
        assert_eq!(v3(a.v[i]), v3(b.v[i]), "{what}: v of {i}");
        assert_eq!(m3(a.c[i]), m3(b.c[i]), "{what}: C of {i}");
        assert_eq!(m3(a.f[i]), m3(b.f[i]), "{what}: F of {i}");
    }
}

/// Largest distance between the positions of two runs.
fn max_dx(a: &Particles, b: &Particles) -> f32 {
    a.x.iter()
        .zip(&b.x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}

/// `pdl=off` and `pdl=on` with `extra` (`--cuda-options` syntax) on the isolated particles of
/// `s`: bit for bit, and the particles moved.
fn check_isolated(what: &str, s: &Scene, extra: &str) {
    let p = isolated(s);
    let opts = |pdl: &str| -> CudaOptions {
        format!("pdl={pdl},{extra}")
            .parse()
            .unwrap_or_else(|e| panic!("{what}: {e}"))
    };
    let off = run(s, &p, opts("off"), DT, STEPS);
    let on = run(s, &p, opts("on"), DT, STEPS);
    assert!(
        max_dx(&off, &p) > 0.5 * s.dx,
        "{what}: moved less than half a cell"
    );
    assert_bit_identical(what, &off, &on);
    println!("{what}: {} particles bit-identical", p.len());
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn pdl_gives_bit_identical_particles_on_isolated_particles() {
    if !gpu() {
        return;
    }
    for kind in [Kind::Water, Kind::Jelly, Kind::Snow] {
        let s = scene(kind);
        for extra in ["", "g2p2g=off", "graph=off"] {
            check_isolated(&format!("{kind:?} {extra}"), &s, extra);
        }
    }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn pdl_gives_bit_identical_particles_with_ck_mpm_and_musl() {
    if !gpu() {
        return;
    }
    for kind in [Kind::Water, Kind::Jelly] {
        // CK-MPM's fused kernels (p2g_ck_warp after a rebuild, g2p2g_ck), then its separate
        // kernels.
        let mut s = scene(kind);
        s.solver = SolverSettings {
            transfer: Transfer::CkMpm,
            ..Default::default()
        };
        check_isolated(&format!("{kind:?} ck-mpm"), &s, "");
        check_isolated(&format!("{kind:?} ck-mpm g2p2g=off"), &s, "g2p2g=off");
        // A classic transfer with MUSL: p2g_mpm, the grid update, the re-map (launched
        // without the attribute) and g2p_mpm after it.
        s.solver = SolverSettings {
            transfer: Transfer::Gimp,
            update: Update::Musl,
            flip: 0.95,
        };
        check_isolated(&format!("{kind:?} gimp musl"), &s, "");
    }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn pdl_gives_bit_identical_particles_in_f64() {
    if !gpu() {
        return;
    }
    for kind in [Kind::Water, Kind::Jelly] {
        check_isolated(&format!("{kind:?} f64"), &scene(kind), "f64=on");
    }
}

/// The benchmark scenes of `bench/` (dense: P2G's atomic sums are not deterministic) for 200
/// steps of their dt: `pdl=on` no further from `pdl=off` than four reruns' spread, or 1e-4 dx.
#[test]
#[ignore = "needs a CUDA GPU"]
fn on_the_benchmark_scenes_pdl_differs_no_more_than_a_rerun() {
    if !gpu() {
        return;
    }
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../bench");
    for file in ["fluid_dam_2m.toml", "jelly_drop_2m.toml", "snow_1m.toml"] {
        let s = Scene::from_file(&std::path::Path::new(dir).join(file)).expect("scene");
        let dt = match s.time.step {
            StepMode::Fixed { dt } => dt,
            _ => panic!("{file}: the benchmark scenes have a fixed dt"),
        };
        let p = s.sample_particles().expect("particles");
        let off = || CudaOptions::default();
        let on = || CudaOptions {
            pdl: true,
            ..Default::default()
        };
        let a = run(&s, &p, off(), dt, 200);
        let again = run(&s, &p, off(), dt, 200);
        let with = run(&s, &p, on(), dt, 200);
        assert!(max_dx(&a, &p) > 0.0, "{file}: nothing moved");
        let (rerun, other) = (max_dx(&a, &again), max_dx(&a, &with));
        println!(
            "{file}, {} particles: max |dx| rerun {rerun:e}, pdl=on {other:e} (dx {})",
            p.len(),
            s.dx
        );
        assert!(
            other <= (4.0 * rerun).max(1e-4 * s.dx),
            "{file}: pdl=on differs by {other:e}, a rerun by {rerun:e}"
        );
    }
}

/// The host side of the GPU tests above, without a GPU: the materials parse, the isolated
/// particles are spaced more than a stencil apart, and the benchmark scenes load with a fixed dt.
#[test]
fn the_test_scenes_build() {
    for kind in [Kind::Water, Kind::Jelly, Kind::Snow] {
        let s = scene(kind);
        let p = isolated(&s);
        assert!(p.len() > 1000, "{kind:?}: {} particles", p.len());
        let gap = (p.x[1] - p.x[0]).length();
        assert!(gap > 5.0 * s.dx, "{kind:?}: neighbours {gap} apart");
    }
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../bench");
    for file in ["fluid_dam_2m.toml", "jelly_drop_2m.toml", "snow_1m.toml"] {
        let s = Scene::from_file(&std::path::Path::new(dir).join(file)).expect("scene");
        assert!(matches!(s.time.step, StepMode::Fixed { .. }), "{file}");
    }
}
