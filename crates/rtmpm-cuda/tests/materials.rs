//! Every material model on the GPU against its Rust twin: the kernels' own stress and return map
//! (`kernels/material/*.cuh`, through the generated dispatch) for random deformation gradients,
//! velocity gradients and plastic states, compared with the f64 Rust models (rtmpm-physics-f64) on the
//! same inputs; and the 3x3 SVD on hard matrices. The device code is `kernels/material_check.cu`
//! beside this file, compiled by NVRTC against the kernel headers like the pipeline: the compile
//! runs wherever NVRTC is (CI), the comparison on a GPU
//! (`cargo test -p rtmpm-cuda --test materials -- --include-ignored`).
//!
//! Tolerances, fixed before the first GPU run: the GPU in f64 matches the Rust f64 models to
//! 1e-9 (relative; the same formulas, only libm's and CUDA's transcendentals differ in the last
//! bits), in f32 with fast math to 1e-3 (f32 rounding, fast transcendentals and the SVD's
//! iterations in f32).

use cudarc::driver::{CudaContext, LaunchConfig, PushKernelArg};
use rand::{Rng, SeedableRng};
use rtmpm_cuda::compile::{KernelOptions, compile_unit, nvrtc_available};
use rtmpm_cuda::contract::{MaterialGpu, materials};
use rtmpm_physics::material::MaterialParams;
use rtmpm_physics_f64::material::Material;

const CHECK: &str = include_str!("kernels/material_check.cu");

/// The materials checked: every model of the registry, some with several variants.
const MATERIALS: &[(&str, &str)] = &[
    ("fluid", "bulk_modulus = 1e5"),
    ("fluid", "bulk_modulus = 2e5\ngamma = 7\nviscosity = 0.5"),
    (
        "fixed_corotated",
        "youngs_modulus = 1e5\npoisson_ratio = 0.3",
    ),
    ("neo_hookean", "youngs_modulus = 1e5\npoisson_ratio = 0.4"),
    ("snow", "youngs_modulus = 1.4e5\npoisson_ratio = 0.2"),
    (
        "drucker_prager",
        "youngs_modulus = 3.5e5\npoisson_ratio = 0.3\nfriction_angle = 35\ncohesion = 0.01",
    ),
    (
        "drucker_prager",
        "youngs_modulus = 3.5e5\npoisson_ratio = 0.3\ncone = \"plane_strain\"",
    ),
    (
        "von_mises",
        "youngs_modulus = 1e6\npoisson_ratio = 0.3\nyield_stress = 1e4\nhardening_modulus = 1e5",
    ),
    (
        "herschel_bulkley",
        "bulk_modulus = 1e5\nshear_modulus = 1e4\nyield_stress = 100\nconsistency = 10",
    ),
    (
        "herschel_bulkley",
        "bulk_modulus = 1e5\neos = \"tait\"\nshear_modulus = 1e4\nyield_stress = 50\nconsistency = 20\nflow_index = 0.5",
    ),
    (
        "herschel_bulkley",
        "bulk_modulus = 1e5\nshear_modulus = 1e4\nyield_stress = 100\nconsistency = 0",
    ),
    (
        "nacc",
        "youngs_modulus = 5e5\npoisson_ratio = 0.3\nbeta = 0.5\nxi = 1\nalpha0 = -0.01",
    ),
];

/// Range of the plastic scalar drawn for a model (around its initial value).
fn plastic_range(kind: &str) -> (f64, f64) {
    match kind {
        "snow" => (0.7, 1.3),
        "drucker_prager" => (0.0, 0.2),
        "von_mises" => (0.0, 0.05),
        "herschel_bulkley" => (0.0, 0.5),
        "nacc" => (-0.03, 0.005),
        _ => (0.0, 0.0),
    }
}

fn every_model_is_checked() {
    for m in rtmpm_physics::material::Model::ALL {
        assert!(
            MATERIALS.iter().any(|(k, _)| *k == m.name),
            "add a {} material to the GPU check",
            m.name
        );
    }
}

type M3 = glam::DMat3;

fn rotation(rng: &mut impl Rng) -> M3 {
    let axis = glam::DVec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    M3::from_axis_angle(
        axis.try_normalize().unwrap_or(glam::DVec3::Z),
        rng.random_range(0.0..6.3),
    )
}

/// `n` deformation gradients `R1 diag(exp(s)) R2` (stretches of 5 %, 20 % and 50 %), and as
/// many velocity gradients.
fn inputs(n: usize, rng: &mut impl Rng) -> (Vec<M3>, Vec<M3>) {
    let mut f = vec![M3::IDENTITY];
    while f.len() < n {
        let a = [0.05, 0.05, 0.2, 0.5][f.len() % 4];
        let s = glam::DVec3::new(
            rng.random_range(-a..a),
            rng.random_range(-a..a),
            rng.random_range(-a..a),
        )
        .exp();
        f.push(rotation(rng) * M3::from_diagonal(s) * rotation(rng));
    }
    let c = (0..n)
        .map(|_| M3::from_cols_array(&std::array::from_fn(|_| rng.random_range(-2.0..2.0))))
        .collect();
    (f, c)
}

fn options(f64: bool) -> KernelOptions {
    KernelOptions::all_models((9, 0), true, f64)
}

#[test]
fn the_material_check_compiles_for_every_model() {
    every_model_is_checked();
    if !nvrtc_available() {
        assert!(
            std::env::var_os("RTMPM_REQUIRE_NVRTC").is_none(),
            "RTMPM_REQUIRE_NVRTC is set but libnvrtc.so.13 cannot be loaded"
        );
        println!("skipped: libnvrtc.so.13 not found");
        return;
    }
    for f64 in [false, true] {
        let ptx = compile_unit("material_check.cu", CHECK, &options(f64)).expect("compiles");
        assert!(ptx.contains(".entry material_check(") && ptx.contains(".entry svd_check("));
    }
}

/// The device's results for one precision: (tau, projected F, plastic) per material and input.
struct Device {
    tau: Vec<f64>,
    fe: Vec<f64>,
    plastic: Vec<f64>,
}

fn run_on_gpu(
    f64: bool,
    mats: &[(u32, Vec<f64>)],
    f: &[M3],
    c: &[M3],
    plastic: &[f64],
    dt: f64,
) -> Device {
    let ptx = compile_unit("material_check.cu", CHECK, &options(f64)).expect("compiles");
    let ctx = CudaContext::new(0).expect("context");
    let s = ctx.default_stream();
    let module = ctx
        .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
        .expect("module");
    let k = module.load_function("material_check").expect("kernel");
    let n = f.len();
    let items = n * mats.len();
    let flat = |m: &[M3]| {
        m.iter()
            .flat_map(|x| x.to_cols_array())
            .collect::<Vec<f64>>()
    };
    let cfg = LaunchConfig {
        grid_dim: (items.div_ceil(128) as u32, 1, 1),
        block_dim: (128, 1, 1),
        shared_mem_bytes: 0,
    };
    let (n_mats, n32) = (mats.len() as u32, n as u32);
    macro_rules! run {
        ($t:ty) => {{
            let table: Vec<MaterialGpu<$t>> = materials(
                &mats
                    .iter()
                    .map(|(kind, p)| (*kind, p.iter().map(|x| *x as $t).collect::<Vec<$t>>()))
                    .collect::<Vec<_>>(),
            )
            .expect("materials");
            let bytes: Vec<u8> = bytemuck::cast_slice(&table).to_vec();
            let d_mats = s.clone_htod(&bytes).expect("upload");
            let conv = |v: Vec<f64>| v.into_iter().map(|x| x as $t).collect::<Vec<$t>>();
            let d_f = s.clone_htod(&conv(flat(f))).expect("upload");
            let d_c = s.clone_htod(&conv(flat(c))).expect("upload");
            let d_p = s.clone_htod(&conv(plastic.to_vec())).expect("upload");
            let mut d_tau = s.alloc_zeros::<$t>(9 * items).expect("alloc");
            let mut d_fe = s.alloc_zeros::<$t>(9 * items).expect("alloc");
            let mut d_po = s.alloc_zeros::<$t>(items).expect("alloc");
            let dt = dt as $t;
            // SAFETY: every buffer holds what the kernel indexes (items x 9 or items, n x 9).
            unsafe {
                s.launch_builder(&k)
                    .arg(&d_mats)
                    .arg(&n_mats)
                    .arg(&n32)
                    .arg(&d_f)
                    .arg(&d_c)
                    .arg(&d_p)
                    .arg(&dt)
                    .arg(&mut d_tau)
                    .arg(&mut d_fe)
                    .arg(&mut d_po)
                    .launch(cfg)
                    .expect("launch")
            };
            let back = |d: &cudarc::driver::CudaSlice<$t>| {
                s.clone_dtoh(d)
                    .expect("download")
                    .into_iter()
                    .map(|x| x as f64)
                    .collect::<Vec<f64>>()
            };
            Device {
                tau: back(&d_tau),
                fe: back(&d_fe),
                plastic: back(&d_po),
            }
        }};
    }
    if f64 { run!(f64) } else { run!(f32) }
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn every_material_on_the_gpu_matches_rust() {
    every_model_is_checked();
    if rtmpm_cuda::probe().is_err() {
        println!("skipped: no usable CUDA GPU");
        return;
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let n = 512;
    let (f, c) = inputs(n, &mut rng);
    let dt = 1e-3;
    let models: Vec<Material> = MATERIALS
        .iter()
        .map(|(kind, fields)| {
            Material::new(
                kind,
                1000.0,
                MaterialParams::parse(kind, fields).expect("params"),
            )
            .unwrap_or_else(|e| panic!("{kind}: {e}"))
        })
        .collect();
    let plastic: Vec<f64> = MATERIALS
        .iter()
        .zip(&models)
        .flat_map(|((kind, _), m)| {
            let (lo, hi) = plastic_range(kind);
            let p0 = m.model.initial_plastic();
            (0..n)
                .map(|i| {
                    if i == 0 || hi <= lo {
                        p0
                    } else {
                        rng.random_range(lo..hi)
                    }
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let table: Vec<(u32, Vec<f64>)> = models
        .iter()
        .map(|m| (m.model.code(), m.model.gpu_params()))
        .collect();
    let mut failures = Vec::new();
    for (f64, tol) in [(true, 1e-9), (false, 1e-3)] {
        // The reference sees the inputs the device sees (rounded to f32 for the f32 kernels).
        let round = |x: f64| if f64 { x } else { x as f32 as f64 };
        let fr: Vec<M3> = f
            .iter()
            .map(|m| M3::from_cols_array(&m.to_cols_array().map(round)))
            .collect();
        let cr: Vec<M3> = c
            .iter()
            .map(|m| M3::from_cols_array(&m.to_cols_array().map(round)))
            .collect();
        let pr: Vec<f64> = plastic.iter().map(|&p| round(p)).collect();
        let table_r: Vec<(u32, Vec<f64>)> = table
            .iter()
            .map(|(k, p)| (*k, p.iter().map(|&x| round(x)).collect()))
            .collect();
        let d = run_on_gpu(f64, &table_r, &fr, &cr, &pr, dt);
        for (mi, ((kind, fields), m)) in MATERIALS.iter().zip(&models).enumerate() {
            let scale = m.model.wave_modulus() * 1e-4;
            let (mut e_tau, mut e_f, mut e_p) = (0f64, 0f64, 0f64);
            for k in 0..n {
                let i = mi * n + k;
                let tau = m.model.kirchhoff(fr[k], pr[i], cr[k]);
                let mut p = pr[i];
                let fe = m.model.project(fr[k], &mut p, dt);
                let gt = M3::from_cols_array(&std::array::from_fn(|q| d.tau[9 * i + q]));
                let gf = M3::from_cols_array(&std::array::from_fn(|q| d.fe[9 * i + q]));
                let norm = |a: M3| a.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
                e_tau = e_tau.max(norm(gt - tau) / (norm(tau) + scale));
                e_f = e_f.max(norm(gf - fe) / norm(fe).max(1e-12));
                e_p = e_p.max((d.plastic[i] - p).abs() / (p.abs() + 1e-2));
            }
            let prec = if f64 { "f64" } else { "f32" };
            println!(
                "{prec} {kind:17} {:55} tau {e_tau:.2e}  F {e_f:.2e}  plastic {e_p:.2e}",
                fields.replace('\n', ", ")
            );
            if !(e_tau <= tol && e_f <= tol && e_p <= tol) {
                failures.push(format!(
                    "{prec} {kind} ({fields}): tau {e_tau:.2e} F {e_f:.2e} plastic {e_p:.2e}"
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "beyond tolerance:\n{}",
        failures.join("\n")
    );
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn the_svd_on_the_gpu_reconstructs_hard_matrices() {
    if rtmpm_cuda::probe().is_err() {
        println!("skipped: no usable CUDA GPU");
        return;
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let (r1, r2) = (rotation(&mut rng), rotation(&mut rng));
    let d = |a: f64, b: f64, c: f64| M3::from_diagonal(glam::DVec3::new(a, b, c));
    let mut hard = vec![
        r1 * d(1.0, 0.5, 1e-6) * r2,
        r1 * d(1e3, 1.0, 1e-3) * r2,
        r1 * d(1.2, 0.9, -0.3) * r2,
        M3::from_cols(
            glam::DVec3::new(0.3, -0.4, 1.2) * -2.0,
            glam::DVec3::new(0.3, -0.4, 1.2) * 0.1,
            glam::DVec3::new(0.3, -0.4, 1.2) * 0.7,
        ),
        M3::ZERO,
        d(2.0, 2.0, 2.0),
        r1 * d(1.0, 1.0, 0.5) * r2,
    ];
    hard.extend(inputs(64, &mut rng).0);
    let ctx = CudaContext::new(0).expect("context");
    let s = ctx.default_stream();
    for (f64, tol) in [(true, 1e-12), (false, 1e-5)] {
        let ptx = compile_unit("material_check.cu", CHECK, &options(f64)).expect("compiles");
        let module = ctx
            .load_module(cudarc::nvrtc::Ptx::from_src(ptx))
            .expect("module");
        let k = module.load_function("svd_check").expect("kernel");
        let n = hard.len();
        let flat: Vec<f64> = hard.iter().flat_map(|m| m.to_cols_array()).collect();
        // 128 threads a block: the f64 SVD needs too many registers for 1024.
        let cfg = LaunchConfig {
            grid_dim: (n.div_ceil(128) as u32, 1, 1),
            block_dim: (128, 1, 1),
            shared_mem_bytes: 0,
        };
        let n32 = n as u32;
        let (u, sigma, v): (Vec<f64>, Vec<f64>, Vec<f64>) = if f64 {
            let df = s.clone_htod(&flat).expect("upload");
            let (mut du, mut ds, mut dv) = (
                s.alloc_zeros::<f64>(9 * n).expect("alloc"),
                s.alloc_zeros::<f64>(3 * n).expect("alloc"),
                s.alloc_zeros::<f64>(9 * n).expect("alloc"),
            );
            // SAFETY: n inputs of 9 reals, outputs sized for n.
            unsafe {
                s.launch_builder(&k)
                    .arg(&df)
                    .arg(&n32)
                    .arg(&mut du)
                    .arg(&mut ds)
                    .arg(&mut dv)
                    .launch(cfg)
                    .expect("launch")
            };
            (
                s.clone_dtoh(&du).unwrap(),
                s.clone_dtoh(&ds).unwrap(),
                s.clone_dtoh(&dv).unwrap(),
            )
        } else {
            let f32s: Vec<f32> = flat.iter().map(|&x| x as f32).collect();
            let df = s.clone_htod(&f32s).expect("upload");
            let (mut du, mut ds, mut dv) = (
                s.alloc_zeros::<f32>(9 * n).expect("alloc"),
                s.alloc_zeros::<f32>(3 * n).expect("alloc"),
                s.alloc_zeros::<f32>(9 * n).expect("alloc"),
            );
            // SAFETY: as above.
            unsafe {
                s.launch_builder(&k)
                    .arg(&df)
                    .arg(&n32)
                    .arg(&mut du)
                    .arg(&mut ds)
                    .arg(&mut dv)
                    .launch(cfg)
                    .expect("launch")
            };
            let w = |v: Vec<f32>| v.into_iter().map(|x| x as f64).collect::<Vec<f64>>();
            (
                w(s.clone_dtoh(&du).unwrap()),
                w(s.clone_dtoh(&ds).unwrap()),
                w(s.clone_dtoh(&dv).unwrap()),
            )
        };
        for (i, a) in hard.iter().enumerate() {
            let a = if f64 {
                *a
            } else {
                M3::from_cols_array(&a.to_cols_array().map(|x| x as f32 as f64))
            };
            let um = M3::from_cols_array(&std::array::from_fn(|q| u[9 * i + q]));
            let vm = M3::from_cols_array(&std::array::from_fn(|q| v[9 * i + q]));
            let sg = glam::DVec3::new(sigma[3 * i], sigma[3 * i + 1], sigma[3 * i + 2]);
            let maxabs = |m: M3| m.to_cols_array().iter().fold(0f64, |x, y| x.max(y.abs()));
            let rec =
                maxabs(um * M3::from_diagonal(sg) * vm.transpose() - a) / maxabs(a).max(1e-30);
            let orth = maxabs(um.transpose() * um - M3::IDENTITY) + (vm.determinant() - 1.0).abs();
            let (_, rs, _) = rtmpm_physics_f64::svd::svd3(a);
            let sv = (sg - rs).abs().max_element() / rs.abs().max_element().max(1e-30);
            println!(
                "{} matrix {i}: reconstruction {rec:.2e} orthogonality {orth:.2e} singular values vs Rust {sv:.2e}",
                if f64 { "f64" } else { "f32" }
            );
            assert!(
                rec <= tol || maxabs(a) == 0.0,
                "matrix {i}: reconstruction {rec:e}"
            );
            assert!(orth <= 10.0 * tol, "matrix {i}: orthogonality {orth:e}");
            assert!(
                sv <= 10.0 * tol,
                "matrix {i}: singular values {sg:?} vs Rust {rs:?}"
            );
        }
    }
}
