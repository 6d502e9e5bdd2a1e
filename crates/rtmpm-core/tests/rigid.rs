//! Rigid bodies coupled two ways to the material on the CPU backend (cargo feature `rigid`):
//! the checks of issue 17 at the quick resolution of `rtmpm validate`, on the same scenes
//! (`validation/*.toml`) and measurements (`rtmpm_core::checks`).
#![cfg(feature = "rigid")]

use rtmpm_core::Scene;
use rtmpm_core::checks;
use rtmpm_core::cpu::CpuBackend;
use rtmpm_core::sim::Simulation;

const ARCHIMEDES: &str = include_str!("../../../validation/archimedes.toml");
const SINKING: &str = include_str!("../../../validation/sinking.toml");
const MOMENTUM: &str = include_str!("../../../validation/rigid_momentum.toml");

fn simulation(text: &str) -> Simulation<CpuBackend> {
    let scene = Scene::from_toml(text, "test").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    Simulation::<CpuBackend>::with_backend(scene, Box::new(backend))
}

/// Archimedes: boxes of density 250, 500 and 750 on water float with the submerged fraction of
/// their height equal to the density ratio within 5 % (issue 17). Measured at dx = 0.02 m (the
/// box is 5 cells high), its height averaged over 1.0 .. 1.5 s (it still bobs by a few mm):
/// 0.258, 0.517, 0.777 (+3.2 %, +3.4 %, +3.6 %). The CPU backend is deterministic (any thread
/// count), so the margin to the bound is not noise.
#[test]
fn boxes_float_with_the_submerged_fraction_of_archimedes() {
    for density in [250.0, 500.0, 750.0] {
        let text =
            checks::edit_toml(ARCHIMEDES, &[("rigid_body.0.density", density.into())]).unwrap();
        let f = checks::float(&mut simulation(&text), |_, _| {}).expect("stable");
        let expect = density / 1000.0;
        println!(
            "density {density}: submerged fraction {:.3} (Archimedes {expect}), centre {:.4} m, \
             surface {:.4} m",
            f.fraction, f.centre, f.surface
        );
        assert!(
            (f.fraction / expect - 1.0).abs() < 0.05,
            "density {density}: submerged fraction {}, expected {expect}",
            f.fraction
        );
    }
}

/// Zero gravity, no walls reached: a jelly ball thrown at a free box. The grid gives the box
/// exactly the momentum its rule takes from the nodes, so the material's momentum plus the
/// box's is conserved, and the box is pushed along the throw.
#[test]
fn momentum_of_material_plus_body_is_conserved() {
    let c = checks::collide(&mut simulation(MOMENTUM)).expect("stable");
    println!(
        "momentum: start {}, material {} + box {}; box speed {:.4} m/s, elastic estimate {:.4} \
         m/s ({:.3})",
        c.start,
        c.material,
        c.body,
        c.body_speed,
        c.elastic,
        c.body_speed / c.elastic
    );
    // The elastic-collision estimate 2 m1 v / (m1 + m2) is an upper bound (the ball keeps some
    // energy as vibration): measured 0.91 of it; issue 17 asks within 10 %.
    let ratio = c.body_speed / c.elastic;
    assert!(
        (ratio - 1.0).abs() < 0.1,
        "box speed {ratio} of the elastic estimate"
    );
    assert!(c.momentum_error() < 0.01, "momentum error {c:?}");
}

/// Sinking and floating: in one tank of water, a sphere of density 2,500 reaches the floor and
/// one of 500 floats (its centre stays above the water's surface minus a radius).
#[test]
fn a_heavy_sphere_sinks_to_the_floor_and_a_light_one_floats() {
    let s = checks::settle(&mut simulation(SINKING)).expect("stable");
    let (heavy, light) = (s[0].center.y, s[1].center.y);
    println!("heavy sphere centre {heavy:.4} m, light {light:.4} m (floor 0.06, surface ~0.26)");
    // On the floor (the domain minus the walls starts at 0.06): within a cell.
    assert!(heavy - 0.045 < 0.06 + 0.02, "heavy sphere at {heavy}");
    // Floating: half submerged puts the centre at the surface (~0.26); sinking would not.
    assert!(light > 0.26 - 0.045, "light sphere at {light}");
}

/// `checks::refine` halves dx and doubles the walls' cells: the interior stays where it was.
#[test]
fn refined_validation_scenes_keep_their_walls_in_metres() {
    for text in [ARCHIMEDES, SINKING, MOMENTUM] {
        let a = Scene::from_toml(text, "a").unwrap();
        let b = Scene::from_toml(&checks::refine(text, 2).unwrap(), "b").unwrap();
        assert_eq!(b.dx, a.dx / 2.0);
        let (ia, ib) = (a.interior(), b.interior());
        assert!((ia.0 - ib.0).length() < 1e-6 && (ia.1 - ib.1).length() < 1e-6);
        assert_eq!(a.rigid_bodies, b.rigid_bodies);
    }
}

/// A cylinder of density 500 (radius 0.05 m, 0.16 m long) lying along x on the water of the
/// Archimedes scene floats half submerged: by the symmetry of its circular section about the
/// axis, a lying cylinder of half the water's density floats with the axis at the surface, so
/// the submerged fraction of its height (its diameter) is 0.5 as for a box, within 5 %. Lying
/// rather than standing: the water then pushes on the curved side (the cylinder's own distance
/// and normals, not a box-like cap), the `axis` field turns the body (local y onto x), and a
/// lying cylinder is stable however long it is, where a standing one tips over unless its
/// radius exceeds sqrt(s (1 - s) / 2) of its height (s the density ratio).
#[test]
fn a_lying_cylinder_of_half_the_waters_density_floats_half_submerged() {
    let block = "shape = \"box\"\nmin = [0.24, 0.27, 0.24]\nmax = [0.36, 0.37, 0.36]";
    assert!(ARCHIMEDES.contains(block));
    let text = ARCHIMEDES.replacen(
        block,
        "shape = \"cylinder\"\ncenter = [0.3, 0.32, 0.3]\nradius = 0.05\nheight = 0.16\n\
         axis = [1.0, 0.0, 0.0]",
        1,
    );
    let mut sim = simulation(&text);
    let spec = &sim.scene.rigid_bodies[0];
    let volume = std::f32::consts::PI * 0.05f32.powi(2) * 0.16;
    assert!((spec.mass - 500.0 * volume).abs() < 1e-6 * spec.mass);
    let f = checks::float(&mut sim, |_, _| {}).expect("stable");
    let b = sim.backend.rigid.as_ref().expect("rigid world").states()[0];
    println!(
        "cylinder: submerged fraction {:.3} (Archimedes 0.5), centre {:.4} m, surface {:.4} m, \
         axis {}",
        f.fraction, f.centre, f.surface, b.rotation.y_axis
    );
    // Still lying along x.
    assert!(b.rotation.y_axis.x.abs() > 0.99, "{}", b.rotation.y_axis);
    assert!(
        (f.fraction / 0.5 - 1.0).abs() < 0.05,
        "submerged fraction {}",
        f.fraction
    );
}
