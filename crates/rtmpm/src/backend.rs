//! Choosing and constructing a backend: the command-line face of the `rtmpm-backends` crate
//! (shared with the Python package).

use anyhow::{Result, anyhow};
use clap::ValueEnum;
use rtmpm_backends::BackendRequest;
use rtmpm_cuda::CudaOptions;
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::SampledBody;
use rtmpm_sim::Backend;

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

impl From<BackendKind> for rtmpm_backends::BackendKind {
    fn from(k: BackendKind) -> Self {
        match k {
            BackendKind::Auto => rtmpm_backends::BackendKind::Auto,
            BackendKind::Cpu => rtmpm_backends::BackendKind::Cpu,
            BackendKind::Cuda => rtmpm_backends::BackendKind::Cuda,
        }
    }
}

/// Construct the backend, in the scene's precision; says which one `auto` picked and why.
pub fn make_backend(
    kind: BackendKind,
    scene: &Scene,
    particles: Particles,
    threads: Option<usize>,
    cuda: &CudaOptions,
) -> Result<Box<dyn Backend>> {
    let request = BackendRequest {
        kind: kind.into(),
        threads,
        gpus: 1,
        cuda: cuda.clone(),
    };
    let created = rtmpm_backends::create(&request, scene, particles).map_err(|e| anyhow!("{e}"))?;
    if kind == BackendKind::Auto {
        eprintln!("backend: {}", created.reason);
    }
    Ok(Box::new(created.backend))
}

/// [`make_backend`] from sampled bodies: one GPU packs them straight from their positions (see
/// `rtmpm_backends::create_from_bodies`).
pub fn make_backend_from_bodies(
    kind: BackendKind,
    scene: &Scene,
    bodies: Vec<SampledBody>,
    threads: Option<usize>,
    cuda: &CudaOptions,
) -> Result<Box<dyn Backend>> {
    let request = BackendRequest {
        kind: kind.into(),
        threads,
        gpus: 1,
        cuda: cuda.clone(),
    };
    let created =
        rtmpm_backends::create_from_bodies(&request, scene, bodies).map_err(|e| anyhow!("{e}"))?;
    if kind == BackendKind::Auto {
        eprintln!("backend: {}", created.reason);
    }
    Ok(Box::new(created.backend))
}
