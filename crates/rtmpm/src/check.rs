//! `rtmpm check SCENE`: validate without running, and print the run's budget.

use anyhow::Result;
use rtmpm_scene::{StepMode, sampling};
use std::path::Path;

pub fn check(path: &Path) -> Result<()> {
    let batch = crate::batch::load(path)?;
    let scene = &batch.base;
    // The budget first: a scene that cannot fit is refused before anything is sampled.
    let budget = match batch.batch {
        Some(_) => crate::batch::enforce(&batch, None, Some(&scene.output.dir))?,
        None => crate::budget::enforce(scene, None, Some(&scene.output.dir))?,
    };
    // Particles are counted, not stored, so `check` needs no memory for them.
    let mut per_material = vec![0u64; scene.materials.len()];
    for (i, b) in scene.bodies.iter().enumerate() {
        per_material[b.material as usize] += sampling::count_body(scene, i)?;
    }
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
        "  time        {} s at {} fps ({} frames), {}",
        scene.time.duration,
        scene.time.fps,
        scene.time.frames(),
        step(&scene.time.step)
    );
    for (m, n) in scene.materials.iter().zip(&per_material) {
        println!(
            "  material    {} ({}, density {} kg/m^3): {n} particles",
            m.name,
            m.model.kind(),
            m.density
        );
    }
    println!("  solver      {}", scene.solver.describe());
    println!("  colliders   {}", scene.colliders.len());
    for e in &scene.emitters {
        println!(
            "  emitter     {} ({}): {} particles of {:.3e} kg from {} s to {} s ({:.1} per second)",
            e.name,
            scene.materials[e.material as usize].name,
            e.total(),
            e.particle_mass,
            e.start as f32,
            e.stop as f32,
            e.rate
        );
    }
    if batch.batch.is_some() {
        println!("{}", crate::batch::describe(&batch));
        println!(
            "  particles   {} a world (the file's scene, before the sweeps)",
            per_material.iter().sum::<u64>()
        );
    } else {
        println!("  particles   {}", per_material.iter().sum::<u64>());
    }
    println!("  precision   {}", scene.precision.name());
    println!("{}", budget.describe());
    Ok(())
}

/// The time step as the scene file writes it.
fn step(s: &StepMode) -> String {
    match *s {
        StepMode::Fixed { dt } => format!("fixed step dt = {dt} s"),
        StepMode::Cfl {
            cfl,
            max_dt,
            min_dt,
        } => format!("CFL step, cfl = {cfl}, max_dt = {max_dt} s, min_dt = {min_dt:.3e} s"),
    }
}
