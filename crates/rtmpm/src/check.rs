//! `rtmpm check SCENE`: validate without running.

use anyhow::Result;
use rtmpm_core::Scene;
use std::path::Path;

pub fn check(path: &Path) -> Result<()> {
    let scene = Scene::from_file(path)?;
    let particles = scene.sample_particles()?;
    let [nx, ny, nz] = scene.n_cells();
    println!("{}: ok", path.display());
    println!("  name        {}", scene.name);
    println!(
        "  domain      [{}, {}, {}] - [{}, {}, {}] m, dx = {} m ({nx} x {ny} x {nz} cells)",
        scene.domain_min.x,
        scene.domain_min.y,
        scene.domain_min.z,
        scene.domain_max.x,
        scene.domain_max.y,
        scene.domain_max.z,
        scene.dx
    );
    println!(
        "  time        {} s at {} fps ({} frames), step {:?}",
        scene.time.duration,
        scene.time.fps,
        scene.time.frames(),
        scene.time.step
    );
    for (i, m) in scene.materials.iter().enumerate() {
        let n = particles
            .material
            .iter()
            .filter(|&&id| id as usize == i)
            .count();
        println!(
            "  material    {} ({}, density {} kg/m^3): {n} particles",
            m.name,
            m.model.kind(),
            m.density
        );
    }
    println!("  solver      {}", scene.solver.describe());
    println!("  colliders   {}", scene.colliders.len());
    println!("  particles   {}", particles.len());
    println!("  precision   {}", scene.precision.name());
    Ok(())
}
