//! `rtmpm run --backend cuda` of a batch: every world in the same kernels on one GPU
//! (`rtmpm_cuda::batch::CudaBatch`), stepped together at one time step by
//! `rtmpm_driver::batch::lockstep::LockstepRun`, each world's frames in its own folder, with
//! checkpoints (`--checkpoint-every`) and resumes (`--resume`) in the CPU batch's layout.

use anyhow::{Context, Result, anyhow};
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_driver::batch::BatchOptions;
use rtmpm_driver::batch::WorldStatus;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_physics::Particles;
use rtmpm_scene::BatchScene;
use std::path::Path;
use std::time::Instant;

/// How a GPU batch run starts and saves itself: a checkpoint folder to resume from, and a
/// checkpoint every `every.0` frames (`every.1` the scene file's text, `every.2` its path).
pub struct Checkpoints<'a> {
    pub resume: Option<&'a Path>,
    pub every: Option<(u64, &'a str, &'a str)>,
}

/// Run the batch `b` (scene file text `text`) on GPU 0 with `cuda` options, fresh or resumed.
pub fn run(
    b: &BatchScene,
    text: &str,
    options: &BatchOptions,
    cuda: &rtmpm_cuda::CudaOptions,
    (start, ckpt): (Instant, Checkpoints<'_>),
) -> Result<()> {
    let info = rtmpm_cuda::probe().map_err(|e| {
        anyhow!("the CUDA backend cannot run here: {e}\n  fix: --backend cpu runs the batch")
    })?;
    let make = |particles: &[Particles]| {
        let batch =
            CudaBatch::new(&b.worlds, particles, cuda.clone()).map_err(|e| anyhow!("{e}"))?;
        Ok((batch.scene().clone(), Box::new(batch)))
    };
    let mut run = match ckpt.resume {
        Some(dir) => {
            eprintln!("resuming the batch from {}", dir.display());
            LockstepRun::resume(b, text, dir, make, options)?
        }
        None => {
            let mut particles = Vec::with_capacity(b.count());
            for (w, scene) in b.worlds.iter().enumerate() {
                let (p, _) = rtmpm_driver::setup::sample(scene)
                    .with_context(|| format!("world {w} ({})", b.label(w)))?;
                particles.push(p);
            }
            let (scene, batch) = make(&particles)?;
            drop(particles);
            LockstepRun::new(b, text, scene, batch, options)?
        }
    };
    eprintln!(
        "batch: {} worlds in the same kernels on the {} (one time step for every world)",
        b.count(),
        info.name
    );
    let total = run.frames;
    run.execute_checkpointed(ckpt.every, |r, frozen| {
        for &w in frozen {
            if let WorldStatus::Frozen { reason, .. } = &r.worlds[w].status {
                eprintln!("world {w} ({}) frozen: {reason}", r.worlds[w].label);
            }
        }
        eprintln!(
            "frame {}/{total}: {} of {} worlds running, {} steps, {:.1} s",
            r.sim.frame,
            r.running(),
            r.worlds.len(),
            r.sim.step,
            start.elapsed().as_secs_f64()
        );
    })?;
    let frozen = run.worlds.len() - run.running();
    println!(
        "batch of {} worlds on the GPU: {} frames, {} steps in {:.1} s, {frozen} frozen{}",
        run.worlds.len(),
        run.sim.frame,
        run.sim.step,
        start.elapsed().as_secs_f64(),
        match &options.out_dir {
            Some(d) => format!(
                "; frames in {}/world_*/ (batch.csv lists them)",
                d.display()
            ),
            None => String::new(),
        }
    );
    Ok(())
}
