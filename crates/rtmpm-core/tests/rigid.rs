//! Rigid bodies coupled two ways to the material on the CPU backend (cargo feature `rigid`):
//! Archimedes (a box of half the water's density floats half submerged) and momentum exchange.
#![cfg(feature = "rigid")]

use rtmpm_core::Scene;
use rtmpm_core::cpu::CpuBackend;
use rtmpm_core::sim::{Backend, Simulation};

/// A 0.12 x 0.1 x 0.12 m box of `density` dropped onto 0.2 m of water in a 0.48 m tank;
/// returns (submerged fraction of its height, box centre height, water surface height).
fn float(density: f32, seconds: f32) -> (f32, f32, f32) {
    let text = format!(
        r#"name = "archimedes"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.6, 0.6, 0.6]
dx = 0.02
[time]
duration = {seconds}
fps = 20
cfl = 0.4
damping = 4.0
[walls]
condition = "slip"
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 2e4
[[body]]
material = "water"
shape = "box"
min = [0.06, 0.06, 0.06]
max = [0.54, 0.26, 0.54]
sampling = "regular"
[[rigid_body]]
shape = "box"
min = [0.24, 0.27, 0.24]
max = [0.36, 0.37, 0.36]
density = {density}
condition = "separate"
"#
    );
    let scene = Scene::from_toml(&text, "archimedes").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
    // The box bobs by a few mm: its height is averaged over the last half second.
    let frames = sim.scene.time.frames();
    let (mut sum, mut count) = (0.0, 0);
    for f in 0..frames {
        sim.advance_frame().expect("stable");
        if f + 10 >= frames {
            sum += sim.backend.rigid.as_ref().expect("rigid world").states()[0]
                .center
                .y;
            count += 1;
        }
    }
    let centre = sum / count as f32;
    let mut p = rtmpm_core::Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    // The free surface away from the box: the highest particles beyond 0.1 m of it, plus half
    // a particle spacing (particles sit at sub-cell centres).
    let far = |x: &glam::Vec3| (x.x - 0.3).abs().max((x.z - 0.3).abs()) > 0.16;
    let mut tops: Vec<f32> = p.x.iter().filter(|x| far(x)).map(|x| x.y).collect();
    tops.sort_by(|a, b| b.total_cmp(a));
    let surface = tops[tops.len() / 50] + 0.005;
    let bottom = centre - 0.05;
    ((surface - bottom) / 0.1, centre, surface)
}

/// Archimedes: boxes of density 250, 500 and 750 on water float with the submerged fraction of
/// their height equal to the density ratio within 5 % (issue 17). Measured at dx = 0.02 m (the
/// box is 5 cells high), its height averaged over 1.0 .. 1.5 s (it still bobs by a few mm):
/// 0.258, 0.517, 0.777 (+3.2 %, +3.4 %, +3.6 %). The CPU backend is deterministic (any thread
/// count), so the margin to the bound is not noise.
#[test]
fn boxes_float_with_the_submerged_fraction_of_archimedes() {
    for density in [250.0, 500.0, 750.0] {
        let (frac, centre, surface) = float(density, 1.5);
        let expect = density / 1000.0;
        println!(
            "density {density}: submerged fraction {frac:.3} (Archimedes {expect}), centre \
             {centre:.4} m, surface {surface:.4} m"
        );
        assert!(
            (frac / expect - 1.0).abs() < 0.05,
            "density {density}: submerged fraction {frac}, expected {expect}"
        );
    }
}

/// Zero gravity, no walls reached: a jelly ball thrown at a free box. The grid gives the box
/// exactly the momentum its rule takes from the nodes, so the material's momentum plus the
/// box's is conserved, and the box is pushed along the throw.
#[test]
fn momentum_of_material_plus_body_is_conserved() {
    let text = r#"name = "hit"
gravity = [0.0, 0.0, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 0.5, 0.5]
dx = 0.025
[time]
duration = 0.3
fps = 10
cfl = 0.4
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 2e5
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "sphere"
center = [0.3, 0.25, 0.25]
radius = 0.08
velocity = [2.0, 0.0, 0.0]
[[rigid_body]]
shape = "box"
min = [0.45, 0.17, 0.17]
max = [0.61, 0.33, 0.33]
density = 1000.0
condition = "separate"
"#;
    let scene = Scene::from_toml(text, "hit").unwrap_or_else(|e| panic!("{e}"));
    let p0 = scene.sample_particles().expect("particles");
    let momentum = |p: &rtmpm_core::Particles| {
        (0..p.len()).fold(glam::DVec3::ZERO, |a, i| {
            a + p.v[i].as_dvec3() * p.mass[i] as f64
        })
    };
    let start = momentum(&p0);
    let box_mass = 1000.0 * 0.16f64.powi(3);
    let backend = CpuBackend::new(&scene, p0, None).expect("backend");
    let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
    for _ in 0..sim.scene.time.frames() {
        sim.advance_frame().expect("stable");
    }
    let mut p = rtmpm_core::Particles::default();
    sim.backend.read_particles(&mut p).expect("read");
    let body = sim.backend.rigid.as_ref().expect("rigid world").states()[0];
    let total = momentum(&p) + body.velocity.as_dvec3() * box_mass;
    println!(
        "momentum: start {start}, material {} + box {} = {total}; box velocity {}",
        momentum(&p),
        body.velocity.as_dvec3() * box_mass,
        body.velocity
    );
    // The elastic-collision estimate 2 m1 v / (m1 + m2) is an upper bound (the ball keeps some
    // energy as vibration): measured 0.91 of it; issue 17 asks within 10 %.
    let m1 = start.x / 2.0;
    let elastic = 2.0 * m1 * 2.0 / (m1 + box_mass);
    let ratio = body.velocity.x as f64 / elastic;
    println!(
        "box speed {:.4} m/s, elastic estimate {elastic:.4} m/s ({ratio:.3})",
        body.velocity.x
    );
    assert!(
        (ratio - 1.0).abs() < 0.1,
        "box speed {ratio} of the elastic estimate"
    );
    assert!(
        (total - start).length() < 0.01 * start.length(),
        "momentum {start} -> {total}"
    );
}

/// Sinking and floating: in one tank of water, a sphere of density 2,500 reaches the floor and
/// one of 500 floats (its centre stays above the water's surface minus a radius).
#[test]
fn a_heavy_sphere_sinks_to_the_floor_and_a_light_one_floats() {
    let text = r#"name = "spheres"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.6, 0.6, 0.4]
dx = 0.02
[time]
duration = 1.2
fps = 10
cfl = 0.4
damping = 2.0
[walls]
condition = "slip"
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 2e4
[[body]]
material = "water"
shape = "box"
min = [0.06, 0.06, 0.06]
max = [0.54, 0.26, 0.34]
sampling = "regular"
[[rigid_body]]
shape = "sphere"
center = [0.18, 0.31, 0.2]
radius = 0.045
density = 2500.0
condition = "separate"
[[rigid_body]]
shape = "sphere"
center = [0.42, 0.31, 0.2]
radius = 0.045
density = 500.0
condition = "separate"
"#;
    let scene = Scene::from_toml(text, "spheres").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    let mut sim = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
    for _ in 0..sim.scene.time.frames() {
        sim.advance_frame().expect("stable");
    }
    let s = sim.backend.rigid.as_ref().expect("rigid world").states();
    let (heavy, light) = (s[0].center.y, s[1].center.y);
    println!("heavy sphere centre {heavy:.4} m, light {light:.4} m (floor 0.06, surface ~0.26)");
    // On the floor (the domain minus the walls starts at 0.06): within a cell.
    assert!(heavy - 0.045 < 0.06 + 0.02, "heavy sphere at {heavy}");
    // Floating: half submerged puts the centre at the surface (~0.26); sinking would not.
    assert!(light > 0.26 - 0.045, "light sphere at {light}");
}
