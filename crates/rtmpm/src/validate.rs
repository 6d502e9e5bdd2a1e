//! `rtmpm validate`: run the published validation cases (the `rtmpm-validate` crate), print
//! the table, write the plots.

use crate::backend::BackendKind;
use anyhow::{Result, bail};
use clap::Args;
use std::path::PathBuf;

/// `rtmpm validate`.
#[derive(Args)]
pub struct ValidateArgs {
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// Run only these cases, comma separated (free_fall, hydrostatic_column,
    /// hydrostatic_column_gimp, vibrating_bar, vibrating_bar_gimp, dam_break, colliding_disks,
    /// granular_column, slump, cohesive_column, archimedes, sinking, rigid_momentum,
    /// emitter_mass; the rigid-body ones need the cargo feature `rigid`). Only when named: the
    /// experimental CK-MPM cases hydrostatic_column_ck, vibrating_bar_ck, dam_break_ck,
    /// granular_column_ck (the CPU backend, or CUDA on one GPU).
    #[arg(long, value_delimiter = ',')]
    pub case: Vec<String>,
    /// Coarse resolutions that finish in a few minutes on 2 CPU cores (what CI runs).
    #[arg(long)]
    pub quick: bool,
    /// Also run the convergence studies (three resolutions, observed order).
    #[arg(long)]
    pub convergence: bool,
    /// Folder of the validation scenes.
    #[arg(long, default_value = "validation")]
    pub scenes: PathBuf,
    /// Where the plots go.
    #[arg(long, default_value = "out/validation")]
    pub out: PathBuf,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Floating-point precision of the whole step: f32 or f64 (default: the scene's
    /// `[solver] precision`, else f32).
    #[arg(long, value_name = "f32|f64")]
    pub precision: Option<rtmpm_scene::Precision>,
    /// The CUDA backend's particle state: f32 or compact (default: the scene's
    /// `[solver] particle_state`, else f32; the CPU backend ignores it).
    #[arg(long, value_name = "f32|compact")]
    pub particle_state: Option<rtmpm_scene::ParticleState>,
    /// CUDA backend switches for every case, as `rtmpm run --cuda-options` (e.g. `ck_p2g=warp` to
    /// validate CK-MPM's unfused kernels); refused with the CPU backend.
    #[arg(long, value_name = "LIST", default_value = "")]
    pub cuda_options: rtmpm_cuda::CudaOptions,
}

/// Run the cases, print the table, the plots' paths and the cases that could not run; an
/// error when a check failed or a case could not run.
pub fn validate(args: ValidateArgs) -> Result<()> {
    if args.backend == BackendKind::Cpu && args.cuda_options != rtmpm_cuda::CudaOptions::default() {
        bail!(
            "--cuda-options are switches of the CUDA backend and this validation runs on the CPU \
             backend: drop --cuda-options or use --backend cuda"
        );
    }
    let options = rtmpm_validate::Options {
        backend: args.backend.into(),
        quick: args.quick,
        convergence: args.convergence,
        scenes: args.scenes,
        threads: args.threads,
        precision: args.precision,
        particle_state: args.particle_state,
        cuda: args.cuda_options,
    };
    let report = rtmpm_validate::run(&args.case, &options)?;
    print!("{}", report.table());
    for path in report.write_plots(&args.out)? {
        println!("plot: {}", path.display());
    }
    for (name, e) in &report.broken {
        println!("case {name} could not run: {e}");
    }
    let failed = report.failed().count();
    if failed > 0 || !report.broken.is_empty() {
        bail!(
            "{failed} of {} validation checks failed; {} cases could not run",
            report.rows.len(),
            report.broken.len()
        );
    }
    println!("{} passed, 0 failed", report.rows.len());
    Ok(())
}
