//! Choosing and constructing a backend.

use anyhow::{Result, bail};
use clap::ValueEnum;
use rtmpm_core::cpu::CpuBackend;
use rtmpm_core::io::limits::human_bytes;
use rtmpm_core::scene::Precision;
use rtmpm_core::sim::Backend;
use rtmpm_core::{Particles, Scene};
use rtmpm_cuda::CudaOptions;

/// Which backend to run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendKind {
    /// CUDA when a GPU is usable, else the CPU.
    Auto,
    /// The CPU reference backend.
    Cpu,
    /// The CUDA backend (fails with the reason when no GPU is usable).
    Cuda,
}

/// The CPU backend in the scene's precision (`[solver] precision`).
fn cpu_backend(
    scene: &Scene,
    particles: Particles,
    threads: Option<usize>,
) -> Result<Box<dyn Backend>> {
    Ok(match scene.precision {
        Precision::F32 => Box::new(CpuBackend::new(scene, particles, threads)?),
        Precision::F64 => Box::new(rtmpm_f64::cpu::CpuBackend::new(scene, particles, threads)?),
    })
}

/// Construct the backend, in the scene's precision; says which one `auto` picked and why.
pub fn make_backend(
    kind: BackendKind,
    scene: &Scene,
    particles: Particles,
    threads: Option<usize>,
    cuda: &CudaOptions,
) -> Result<Box<dyn Backend>> {
    match kind {
        BackendKind::Cpu => cpu_backend(scene, particles, threads),
        BackendKind::Cuda => match cuda_backend(scene, &particles, cuda) {
            Ok(b) => Ok(b),
            Err(why) => {
                bail!("the CUDA backend is not usable here: {why}\n  hint: use --backend cpu")
            }
        },
        BackendKind::Auto => match cuda_backend(scene, &particles, cuda) {
            Ok(b) => {
                eprintln!("backend: auto -> {}", b.name());
                Ok(b)
            }
            Err(why) => {
                let b = cpu_backend(scene, particles, threads)?;
                eprintln!("backend: auto -> {} (CUDA not usable: {why})", b.name());
                Ok(b)
            }
        },
    }
}

/// The CUDA backend, or why it cannot run.
fn cuda_backend(
    scene: &Scene,
    particles: &Particles,
    options: &CudaOptions,
) -> std::result::Result<Box<dyn Backend>, String> {
    let info = rtmpm_cuda::probe().map_err(|e| e.to_string())?;
    // The budget's device estimate against the GPU's memory, before anything is allocated.
    let need = rtmpm_core::scene::Budget::estimate(scene, Some(1)).gpu_bytes;
    if need > info.memory as u64 {
        return Err(format!(
            "the scene needs about {} of GPU memory for {} particles and its grid (an \
             estimate), more than the {} of the {}; use fewer particles or a coarser dx, \
             several GPUs (--gpus N), or --backend cpu",
            human_bytes(need),
            particles.len(),
            human_bytes(info.memory as u64),
            info.name
        ));
    }
    let b = rtmpm_cuda::CudaBackend::new(scene, particles, options.clone()).map_err(|e| {
        format!(
            "{e} (the estimate for this scene was {} of the {} GPU memory)",
            human_bytes(need),
            human_bytes(info.memory as u64)
        )
    })?;
    Ok(Box::new(b))
}
