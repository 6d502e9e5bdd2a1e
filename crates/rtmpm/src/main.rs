//! `rtmpm`: run, check and benchmark Material Point Method scenes.

mod backend;
mod batch;
mod bench;
mod bench_frames;
mod budget;
mod check;
mod info;
mod mesh;
mod multi;
mod render;
mod run;
mod validate;
mod view;

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "rtmpm", version, about = "Real-time Material Point Method simulator", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write its frames.
    Run(Box<run::RunArgs>),
    /// Version, available backends and the GPU found.
    Info,
    /// Validate a scene file without running it.
    Check {
        /// Scene file (TOML).
        scene: PathBuf,
    },
    /// Run the validation cases against published results and print a table.
    Validate(validate::ValidateArgs),
    /// Render the PLY frames of a run to PNG images, movie.gif and (with ffmpeg) movie.mp4.
    Render(render::cmd::RenderArgs),
    /// Reconstruct a fluid surface mesh per PLY frame of a run (OBJ, PLY, VTU).
    Mesh(mesh::MeshArgs),
    /// Benchmark: the classic MLS-MPM fluid block, particle-steps per second.
    Bench(bench::BenchArgs),
    /// Run a scene and watch and steer it live: in a browser (--serve), or record the view.
    View(Box<view::ViewArgs>),
}

fn main() -> ExitCode {
    // NVLink multicast (NVLS) stays off in NCCL unless the user asks for it: a program using it
    // can put a shared host's GPUs out of service. Set before any thread starts.
    if std::env::var_os("NCCL_NVLS_ENABLE").is_none() {
        // SAFETY: single-threaded here (no thread has been started yet).
        unsafe { std::env::set_var("NCCL_NVLS_ENABLE", "0") };
    }
    let cli = Cli::parse();
    let result = match cli.command {
        // A scene with `[batch]`: its worlds run together.
        Command::Run(args) => match args.scene.as_deref() {
            Some(path) if batch::is_batch(path) => batch::run(&args),
            None if args.resume.as_deref().is_some_and(batch::is_checkpoint) => args
                .resume
                .as_deref()
                .map_or(Ok(()), batch::refuse_resume_without_scene),
            _ => run::run(*args),
        },
        Command::Info => info::info(),
        Command::Check { scene } => check::check(&scene),
        Command::Bench(args) => bench::bench(args),
        Command::Render(args) => render::wedge::dispatch(args),
        Command::Mesh(args) => mesh::mesh_cmd(args),
        Command::Validate(args) => validate::validate(args),
        Command::View(args) => view::view(*args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
