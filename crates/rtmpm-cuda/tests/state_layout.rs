//! GPU tests of the particle state layouts (`contract::StateLayout`):
//!
//! 1. the 20-word fluid layout gives bit-identical particles to the 29-word layout (isolated
//!    particles, whose grid nodes each get one particle's contribution, so P2G's atomic sums are
//!    exact and the run is deterministic), and in a dense scene differs from it no more than
//!    four times as much as two runs of the 29-word layout differ from each other (P2G's atomic
//!    sums are not deterministic), or 1e-4 dx;
//! 2. upload then download returns the packed values in every layout (the compact v and C
//!    within the codec's bound, decoded on the device by the export kernel as on the host);
//! 3. the compact state's positions after 100 steps stay within 0.01 dx of the f32 run (the
//!    figure was fixed before any run; the test prints the measured distances);
//! 4. the device codec (`kernels/codec.cuh`) gives the host codec's words (`src/state/codec/mod.rs`).
//!
//! `cargo test -p rtmpm-cuda --test state_layout -- --include-ignored`; the GPU tests skip with
//! a message when no usable CUDA device is present.

use cudarc::driver::{CudaContext, LaunchConfig, PushKernelArg};
use rtmpm_cuda::compile::{KernelOptions, compile_unit, nvrtc_available};
use rtmpm_cuda::contract::StateLayout;
use rtmpm_cuda::state::codec;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_physics::Particles;
use rtmpm_physics::boundary::Walls;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::{Mat3, Vec3};
use rtmpm_scene::{OutputSettings, ParticleState, Scene, StepMode, TimeSettings};
use rtmpm_sim::Backend;

fn gpu() -> bool {
    match probe() {
        Ok(d) => {
            println!("device: {d:?}");
            true
        }
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

/// Unit cube, dx = 1/32, gravity, fixed dt; water (Tait-free linear EOS) or jelly.
fn scene(water: bool) -> Scene {
    let material = if water {
        Material::parse("water", 1000.0, "fluid", "bulk_modulus = 1e4").expect("water")
    } else {
        Material::parse("jelly", 1000.0, "fixed_corotated", "mu = 4e4\nlambda = 6e4")
            .expect("jelly")
    };
    Scene {
        name: "state-layout".into(),
        source: None,
        domain_min: Vec3::ZERO,
        domain_max: Vec3::ONE,
        dx: 1.0 / 32.0,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        time: TimeSettings {
            duration: 1.0,
            fps: 30.0,
            step: StepMode::Fixed { dt: 2e-4 },
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

/// Particles at spacing `h` in [lo, hi], spinning about the block's centre (5 rad/s about a
/// tilted axis) and moving down at 1 m/s, so that v and C are far from zero and of mixed signs.
fn block(s: &Scene, lo: Vec3, hi: Vec3, h: f32) -> Particles {
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
                // A rigid rotation's velocity gradient.
                p.c[last] = Mat3::from_cols_array(&[
                    0.0, omega.z, -omega.y, -omega.z, 0.0, omega.x, omega.y, -omega.x, 0.0,
                ]);
            }
        }
    }
    p
}

/// Dense: two particles per cell per axis.
fn dense(s: &Scene) -> Particles {
    block(s, Vec3::splat(0.3), Vec3::new(0.6, 0.55, 0.6), s.dx / 2.0)
}

/// Isolated: one particle every 5 cells per axis (stencils 3 nodes wide never overlap while a
/// particle moves less than a cell).
fn isolated(s: &Scene) -> Particles {
    block(s, Vec3::splat(0.2), Vec3::splat(0.8), 5.0 * s.dx)
}

fn options(layout: StateLayout, f64: bool, g2p2g: bool) -> CudaOptions {
    CudaOptions {
        f64,
        g2p2g,
        fluid_state: layout.fluid(),
        compact_state: layout.compact(),
        ..Default::default()
    }
}

/// `steps` steps of `dt`, then every particle.
fn run(s: &Scene, p: &Particles, o: CudaOptions, want: StateLayout, steps: usize) -> Particles {
    let mut b = CudaBackend::new(s, p, o).expect("backend");
    assert_eq!(b.state_layout(), want);
    for i in 0..steps {
        b.step(2e-4, i as f32 * 2e-4).expect("step");
    }
    assert_eq!(b.check().expect("check"), None);
    let mut out = Particles::default();
    b.read_particles(&mut out).expect("read");
    out
}

/// Largest distance between the positions of two runs.
fn max_dx(a: &Particles, b: &Particles) -> f32 {
    a.x.iter()
        .zip(&b.x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}

/// Root mean square of the distances.
fn rms_dx(a: &Particles, b: &Particles) -> f32 {
    let s: f64 =
        a.x.iter()
            .zip(&b.x)
            .map(|(p, q)| (*p - *q).length_squared() as f64)
            .sum();
    (s / a.len().max(1) as f64).sqrt() as f32
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_fluid_layout_gives_bit_identical_particles_to_the_29_word_layout() {
    if !gpu() {
        return;
    }
    let water = scene(true);
    let p = isolated(&water);
    println!("{} isolated water particles", p.len());
    for f64 in [false, true] {
        // G2P2G's fluid variant, and the general kernel variants (separate G2P and P2G).
        for g2p2g in [true, false] {
            let full = run(
                &water,
                &p,
                options(StateLayout::Full, f64, g2p2g),
                StateLayout::Full,
                60,
            );
            let fluid = run(
                &water,
                &p,
                options(StateLayout::Fluid, f64, g2p2g),
                StateLayout::Fluid,
                60,
            );
            let what = format!("f64 {f64}, g2p2g {g2p2g}");
            assert!(max_dx(&full, &p) > 0.0, "{what}: nothing moved");
            for i in 0..p.len() {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(full.x[i]), bits(fluid.x[i]), "{what}: x of {i}");
                assert_eq!(bits(full.v[i]), bits(fluid.v[i]), "{what}: v of {i}");
                assert_eq!(full.c[i], fluid.c[i], "{what}: C of {i}");
                assert_eq!(full.f[i], fluid.f[i], "{what}: F of {i}");
            }
            println!("{what}: bit-identical");
        }
    }
    // Jelly keeps the 29-word layout (the fluid layout is for scenes of fluids only).
    let jelly = scene(false);
    let b = CudaBackend::new(&jelly, &isolated(&jelly), CudaOptions::default()).expect("backend");
    assert_eq!(b.state_layout(), StateLayout::Full);
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn in_a_dense_scene_the_fluid_layout_differs_no_more_than_a_rerun() {
    if !gpu() {
        return;
    }
    let water = scene(true);
    let p = dense(&water);
    for g2p2g in [true, false] {
        let o = |l| options(l, false, g2p2g);
        let a = run(&water, &p, o(StateLayout::Full), StateLayout::Full, 100);
        let again = run(&water, &p, o(StateLayout::Full), StateLayout::Full, 100);
        let fluid = run(&water, &p, o(StateLayout::Fluid), StateLayout::Fluid, 100);
        let (rerun, layout) = (max_dx(&a, &again), max_dx(&a, &fluid));
        println!(
            "g2p2g {g2p2g}, {} particles: max |dx| rerun {rerun:e}, fluid layout {layout:e} (dx {})",
            p.len(),
            water.dx
        );
        // A wrong word read or written moves particles by far more than this floor.
        assert!(
            layout <= (4.0 * rerun).max(1e-4 * water.dx),
            "the fluid layout moved particles by {layout:e}, a rerun by {rerun:e}"
        );
    }
}

/// The host's image of `p` in `l`, unpacked: what a download must give.
fn packed(s: &Scene, p: &Particles, l: StateLayout) -> Particles {
    let fluid = rtmpm_cuda::state::fluid_materials(s);
    let bytes = rtmpm_cuda::state::pack(p, &fluid, l, false, p.len(), None).expect("pack");
    let mut out = Particles::default();
    rtmpm_cuda::state::unpack(&bytes, p.len(), p.len(), l, false, &mut out).expect("unpack");
    out
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn upload_and_download_return_the_packed_values_in_every_layout() {
    if !gpu() {
        return;
    }
    for (water, layouts) in [
        (
            true,
            vec![
                StateLayout::Full,
                StateLayout::Fluid,
                StateLayout::CompactFluid,
            ],
        ),
        (false, vec![StateLayout::Full, StateLayout::Compact]),
    ] {
        let s = scene(water);
        let p = dense(&s);
        for l in layouts {
            let mut b = CudaBackend::new(&s, &p, options(l, false, true)).expect("backend");
            assert_eq!(b.state_layout(), l);
            let mut got = Particles::default();
            b.read_particles(&mut got).expect("read");
            let want = packed(&s, &p, l);
            assert_eq!(got, want, "water {water}, {l:?}");
            // The device's decoding (export kernel) gives the host's values, bit for bit.
            let v = b.read_vec3_ordered(l.v()).expect("v");
            let x = b.read_vec3_ordered(l.x()).expect("x");
            for i in 0..p.len() {
                assert_eq!(
                    &v[3 * i..3 * i + 3],
                    &want.v[i].to_array(),
                    "{l:?}: v of {i}"
                );
                assert_eq!(
                    &x[3 * i..3 * i + 3],
                    &want.x[i].to_array(),
                    "{l:?}: x of {i}"
                );
            }
            // Within the stated bound of the uploaded values (exact but for C in compact).
            let (mut worst_v, mut worst_c) = (0.0f64, 0.0f64);
            for i in 0..p.len() {
                let (v0, c0) = (p.v[i].to_array(), p.c[i].to_cols_array());
                let (v1, c1) = (got.v[i].to_array(), got.c[i].to_cols_array());
                let mv = v0.iter().fold(0f32, |m, a| m.max(a.abs()));
                let mc = c0.iter().fold(0f32, |m, a| m.max(a.abs()));
                // v is f32 in every layout: exact.
                assert_eq!(v1, v0, "{l:?}: v of {i}");
                for k in 0..3 {
                    let e = (v1[k] as f64 - v0[k] as f64).abs();
                    worst_v = worst_v.max(e / mv.max(f32::MIN_POSITIVE) as f64);
                }
                for k in 0..9 {
                    let e = (c1[k] as f64 - c0[k] as f64).abs();
                    assert!(e <= codec::bound(mc, codec::C_BITS), "{l:?}: C of {i}");
                    worst_c = worst_c.max(e / mc.max(f32::MIN_POSITIVE) as f64);
                }
                assert_eq!(got.x[i], p.x[i]);
                assert_eq!((got.mass[i], got.vol0[i]), (p.mass[i], p.vol0[i]));
            }
            println!(
                "water {water}, {l:?}: round trip exact; v, C relative errors {worst_v:e}, {worst_c:e}"
            );
            if !l.compact() {
                assert_eq!((worst_v, worst_c), (0.0, 0.0));
            }
        }
    }
}

/// Bound fixed before any run: positions of the compact state within 0.01 dx of the f32 run's
/// after 100 steps (RMS within 0.001 dx).
#[test]
#[ignore = "needs a CUDA GPU"]
fn the_compact_state_stays_within_a_hundredth_of_a_cell_of_f32_over_100_steps() {
    if !gpu() {
        return;
    }
    for water in [true, false] {
        let s = scene(water);
        let p = dense(&s);
        let (plain, compact) = if water {
            (StateLayout::Fluid, StateLayout::CompactFluid)
        } else {
            (StateLayout::Full, StateLayout::Compact)
        };
        for g2p2g in [true, false] {
            let a = run(&s, &p, options(plain, false, g2p2g), plain, 100);
            let again = run(&s, &p, options(plain, false, g2p2g), plain, 100);
            let c = run(&s, &p, options(compact, false, g2p2g), compact, 100);
            // The scene option selects the same layout.
            let mut sc = s.clone();
            sc.particle_state = ParticleState::Compact;
            let c2 = run(&sc, &p, options(plain, false, g2p2g), compact, 100);
            let (m, r, rerun, m2) = (
                max_dx(&a, &c),
                rms_dx(&a, &c),
                max_dx(&a, &again),
                max_dx(&a, &c2),
            );
            println!(
                "water {water}, g2p2g {g2p2g}: compact vs f32 after 100 steps: max |dx| {m:e} m = \
                 {:.2e} dx, rms {:.2e} dx; scene option {:.2e} dx; f32 rerun {:.2e} dx; moved {:.2e} dx",
                m / s.dx,
                r / s.dx,
                m2 / s.dx,
                rerun / s.dx,
                max_dx(&a, &p) / s.dx
            );
            assert!(max_dx(&a, &p) > 0.1 * s.dx, "nothing moved");
            assert!(m < 0.01 * s.dx && m2 < 0.01 * s.dx, "max {m:e}, {m2:e}");
            assert!(r < 0.001 * s.dx, "rms {r:e}");
        }
    }
}

/// The codec's device twin: every input encoded and decoded by `kernels/codec.cuh`.
const CODEC_CHECK: &str = r#"
#include "codec.cuh"
extern "C" __global__ void codec_check(const float* c, unsigned n, unsigned* cw, float* cd) {
    unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    unsigned w[5];
    codec_encode_c(c + 9 * i, w);
    for (int k = 0; k < 5; ++k) cw[5 * i + k] = w[k];
    codec_decode_c(w, cd + 9 * i);
}
"#;

fn codec_options(fast_math: bool) -> KernelOptions {
    KernelOptions::all_models((9, 0), fast_math, false)
}

#[test]
fn the_codec_check_compiles() {
    if !nvrtc_available() {
        assert!(
            std::env::var_os("RTMPM_REQUIRE_NVRTC").is_none(),
            "RTMPM_REQUIRE_NVRTC is set but libnvrtc.so.13 cannot be loaded"
        );
        println!("skipped: libnvrtc.so.13 not found");
        return;
    }
    for fast_math in [false, true] {
        let ptx = compile_unit("codec_check.cu", CODEC_CHECK, &codec_options(fast_math))
            .expect("compiles");
        assert!(ptx.contains(".entry codec_check("));
    }
}

/// Inputs of every kind: random magnitudes over the whole range, zeros, denormals, huge values,
/// non-finite components, mixed scales.
fn codec_inputs() -> (Vec<[f32; 3]>, Vec<[f32; 9]>) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(19);
    let mut v = vec![
        [0.0; 3],
        [-0.0, 0.0, 1.0],
        [f32::from_bits(1), -f32::from_bits(7), 0.0],
        [f32::MAX, -f32::MAX, 1.0],
        [f32::NAN, 1.0, 2.0],
        [f32::INFINITY, 0.0, 0.0],
        [2.0 - 2f32.powi(-20), 1e-7, -3.0],
    ];
    while v.len() < 20_000 {
        let e = rng.random_range(-140..127);
        v.push(std::array::from_fn(|_| {
            rng.random_range(-1.0f32..1.0) * 2f32.powi(e + rng.random_range(-30..3))
        }));
    }
    let c = v
        .iter()
        .enumerate()
        .map(|(i, a)| std::array::from_fn(|k| a[k % 3] * if (i + k) % 4 == 0 { 1e-3 } else { 1.0 }))
        .collect();
    (v, c)
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_device_codec_gives_the_host_codec_s_words() {
    if !gpu() {
        return;
    }
    let (_, c) = codec_inputs();
    let n = c.len();
    for fast_math in [false, true] {
        let ptx = compile_unit("codec_check.cu", CODEC_CHECK, &codec_options(fast_math))
            .expect("compiles");
        let ctx = CudaContext::new(0).expect("context");
        let s = ctx.default_stream();
        let module = ctx
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .expect("module");
        let k = module.load_function("codec_check").expect("kernel");
        let d_c = s.clone_htod(&c.concat()).expect("upload");
        let mut cw = s.alloc_zeros::<u32>(5 * n).expect("alloc");
        let mut cd = s.alloc_zeros::<f32>(9 * n).expect("alloc");
        let n32 = n as u32;
        let cfg = LaunchConfig {
            grid_dim: (n.div_ceil(128) as u32, 1, 1),
            block_dim: (128, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: every buffer holds what the kernel indexes for i < n.
        unsafe {
            s.launch_builder(&k)
                .arg(&d_c)
                .arg(&n32)
                .arg(&mut cw)
                .arg(&mut cd)
                .launch(cfg)
        }
        .expect("launch");
        let cw = s.clone_dtoh(&cw).expect("read");
        let cd = s.clone_dtoh(&cd).expect("read");
        let denormal = |a: &[f32]| a.iter().any(|x| x.is_subnormal());
        let (mut exact, mut flushed) = (0, 0);
        for i in 0..n {
            let hc = codec::encode_c(c[i]);
            let same = cw[5 * i..5 * i + 5] == hc;
            if !fast_math || !denormal(&c[i]) {
                assert!(same, "fast_math {fast_math}: input {i} {:?}", c[i]);
                exact += 1;
            } else {
                // --use_fast_math flushes denormal inputs to zero: within the bound.
                if c[i].iter().all(|x| x.is_finite()) {
                    let m = c[i].iter().fold(0f32, |m, x| m.max(x.abs()));
                    for k in 0..9 {
                        let e = (cd[9 * i + k] as f64 - c[i][k] as f64).abs();
                        assert!(e <= codec::bound(m, codec::C_BITS), "input {i}");
                    }
                }
                flushed += 1;
            }
            // The device decodes the words as the host does.
            let hcd = codec::decode_c(std::array::from_fn(|k| cw[5 * i + k]));
            for k in 0..9 {
                assert_eq!(cd[9 * i + k].to_bits(), hcd[k].to_bits(), "decode C {i}");
            }
        }
        println!(
            "fast_math {fast_math}: {exact} inputs bit-identical, {flushed} with denormals within the bound"
        );
    }
}
