//! Whole-pipeline physics checks through the public API: scene text -> particles -> CPU steps.

mod common;

use common::cpu::CpuBackend;
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;

/// An elastic column (E = 1 MPa, nu = 0, as cb-geo's hydrostatic column) in a slab with slip walls
/// settles under gravity (settling damping: resting on the floor's wall plane, nothing else damps
/// its elastic oscillation); its vertical stress must grow with depth as rho g d.
#[test]
fn settled_column_pressure_grows_with_depth() {
    let text = r#"
name = "column"
gravity = [0.0, -9.81, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [0.16, 0.2, 0.1]
dx = 0.01
[time]
duration = 0.6
fps = 10
cfl = 0.4
max_dt = 1e-3
damping = 40.0
[walls]
thickness = 3
condition = "slip"
[[material]]
name = "soil"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.0
[[body]]
material = "soil"
shape = "box"
min = [0.03, 0.03, 0.03]
max = [0.13, 0.13, 0.07]
particles_per_cell = 8
sampling = "regular"
"#;
    let scene = Scene::from_toml(text, "column").expect("valid scene");
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    let mut sim = Simulation::new(scene, Box::new(backend));
    for _ in 0..sim.scene.time.frames() {
        sim.advance_frame().expect("stable");
    }
    let mut p = rtmpm_sim::Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    let model = &sim.scene.materials[0].model;
    let top = p.x.iter().map(|x| x.y).fold(f32::MIN, f32::max);
    // Layers of one cell: mean vertical stress -sigma_yy against rho g depth.
    let layers = 10;
    let mut sum = vec![0.0f64; layers];
    let mut count = vec![0usize; layers];
    for i in 0..p.len() {
        let j = p.f[i].determinant();
        let sigma = model.kirchhoff(p.f[i], p.plastic[i], p.c[i]) * (1.0 / j);
        let pressure = -sigma.y_axis.y;
        let layer = (((top - p.x[i].y) / 0.01) as usize).min(layers - 1);
        sum[layer] += pressure as f64;
        count[layer] += 1;
    }
    let mean: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, &c)| s / c.max(1) as f64)
        .collect();
    // Layer l holds the particle rows at depths l dx and (l + 1/2) dx below the top row, which
    // lies a quarter cell below the free surface: its mean depth is (l + 1/2) dx.
    let rho_g = 1000.0 * 9.81;
    let depth_of = |l: usize| (l as f64 + 0.5) * 0.01;
    // Away from the floor's wall band (whose nodes are constrained, an MPM boundary artefact
    // studied by the validation suite), the vertical stress must grow with depth ...
    for l in 1..=5 {
        assert!(
            mean[l] > mean[l - 1],
            "stress must grow with depth: {mean:?}"
        );
    }
    // ... at the hydrostatic rate rho g (first layer to fifth) ...
    let slope = (mean[5] - mean[1]) / (depth_of(5) - depth_of(1));
    assert!(
        (slope - rho_g).abs() < 0.05 * rho_g,
        "d sigma / d depth = {slope:.0} Pa/m, rho g = {rho_g:.0} ({mean:?})"
    );
    // ... and match rho g d to within one cell of head (the first-order error of MPM at a free
    // surface; cb-geo reports the same order of error at this resolution).
    for (l, &m) in mean.iter().enumerate().take(6) {
        let exact = rho_g * depth_of(l);
        assert!(
            (m - exact).abs() < rho_g * 0.01,
            "layer {l}: {m:.1} Pa vs rho g d = {exact:.1} Pa ({mean:?})"
        );
    }
    // Settled: nothing moves fast any more.
    let vmax = p.v.iter().map(|v| v.length()).fold(0.0, f32::max);
    assert!(vmax < 0.05, "column still moving at {vmax} m/s");
}

/// Angular momentum `sum m (x - c) x v` of the particles about their centre of mass.
fn angular_momentum(p: &rtmpm_sim::Particles) -> [f64; 3] {
    let c = p.center_of_mass();
    let mut l = [0.0f64; 3];
    for i in 0..p.len() {
        let (m, x, v) = (p.mass[i] as f64, p.x[i], p.v[i]);
        let r = [x.x as f64 - c[0], x.y as f64 - c[1], x.z as f64 - c[2]];
        let v = [v.x as f64, v.y as f64, v.z as f64];
        l[0] += m * (r[1] * v[2] - r[2] * v[1]);
        l[1] += m * (r[2] * v[0] - r[0] * v[2]);
        l[2] += m * (r[0] * v[1] - r[1] * v[0]);
    }
    l
}

/// A body with `angular_velocity` starts with APIC's C equal to the gradient of its velocity
/// field (the cross-product matrix of w), so the first steps keep its angular momentum; with
/// C = 0, as before, P2G averages the rotation away and about 1 % is lost in the first step.
#[test]
fn spinning_body_keeps_its_angular_momentum_from_step_0() {
    let text = r#"
gravity = [0.0, 0.0, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.05
[time]
duration = 0.1
fps = 10
dt = 1e-3
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 1.0e4
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.2
velocity = [0.3, 0.0, 0.0]
angular_velocity = [1.0, 2.0, -3.0]
sampling = "regular"
"#;
    let scene = Scene::from_toml(text, "spin").expect("valid scene");
    let p0 = scene.sample_particles().expect("particles");
    // C = [w]x: C r = w x r for every r.
    let r = glam::Vec3::new(0.3, -0.7, 1.1);
    let w = glam::Vec3::new(1.0, 2.0, -3.0);
    assert!((p0.c[0] * r - w.cross(r)).length() < 1e-6);
    let relative_loss = |p_start: rtmpm_sim::Particles, steps: usize| -> f64 {
        let l0 = angular_momentum(&p_start);
        let mut b = CpuBackend::new(&scene, p_start, Some(1)).expect("backend");
        use rtmpm_sim::Backend;
        for s in 0..steps {
            b.step(1e-3, s as f32 * 1e-3).expect("step");
        }
        let mut p = rtmpm_sim::Particles::default();
        b.read_particles(&mut p).expect("read");
        let l1 = angular_momentum(&p);
        let d =
            ((l1[0] - l0[0]).powi(2) + (l1[1] - l0[1]).powi(2) + (l1[2] - l0[2]).powi(2)).sqrt();
        d / (l0[0].powi(2) + l0[1].powi(2) + l0[2].powi(2)).sqrt()
    };
    let with_c = relative_loss(p0.clone(), 1);
    let mut zero_c = p0.clone();
    zero_c.c.iter_mut().for_each(|c| *c = glam::Mat3::ZERO);
    let without_c = relative_loss(zero_c, 1);
    eprintln!(
        "relative change of L in one step: {with_c:e} with C = [w]x, {without_c:e} with C = 0"
    );
    assert!(
        with_c < 1e-4,
        "angular momentum changed by {with_c:e} in one step"
    );
    assert!(
        without_c > 1e-3,
        "C = 0 lost only {without_c:e}: the test is not sensitive"
    );
    assert!(relative_loss(p0, 10) < 1e-3);
}

/// A CFL step that collapses (an initial speed of 1e6 m/s) stops at once with the fastest
/// particle named, instead of crawling on at 1e-8 s a step.
#[test]
fn collapsing_cfl_step_stops_and_names_the_fastest_particle() {
    let text = r#"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.05
[time]
duration = 1.0
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e5
[[body]]
material = "water"
shape = "box"
min = [0.3, 0.3, 0.3]
max = [0.5, 0.5, 0.5]
velocity = [1e6, 0.0, 0.0]
"#;
    let scene = Scene::from_toml(text, "fast").expect("valid scene");
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, Some(1)).expect("backend");
    let mut sim = Simulation::new(scene, Box::new(backend));
    let t = std::time::Instant::now();
    let err = sim.advance_frame().expect_err("must stop");
    assert!(t.elapsed().as_secs_f64() < 5.0);
    let rtmpm_sim::SimError::Stall(b) = &err else {
        panic!("{err}")
    };
    assert!((b.velocity.x - 1e6).abs() < 1.0, "{err}");
    let msg = err.to_string();
    assert!(msg.contains("min_dt") && msg.contains("`water`"), "{msg}");
    // With a lower min_dt the same scene is allowed to step.
    let slow = Scene::from_toml(
        &text.replace("duration = 1.0", "duration = 1.0\nmin_dt = 1e-9"),
        "f",
    )
    .expect("valid");
    let p = slow.sample_particles().expect("particles");
    let backend = CpuBackend::new(&slow, p, Some(1)).expect("backend");
    let mut sim = Simulation::new(slow, Box::new(backend));
    // One step: the particles leave the domain at that speed; only the stall matters here.
    let r = sim.advance(1);
    assert!(!matches!(r, Err(rtmpm_sim::SimError::Stall(_))), "{r:?}");
    assert_eq!(sim.step, 1);
}
