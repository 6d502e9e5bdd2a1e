//! Batches of worlds (`[batch]` in a scene) on the command line: loading with their budget
//! checked against this machine first, and what `rtmpm check` prints of them.

use anyhow::{Result, bail};
use rtmpm_io::limits::host_memory_available;
use rtmpm_scene::batch::{memory_refusal, scaled_budget};
use rtmpm_scene::{BatchScene, Budget};
use std::path::Path;

mod gpu;

/// True when the scene file `path` has a `[batch]` table (false when it cannot be read or
/// parsed: loading it reports why).
pub fn is_batch(path: &Path) -> bool {
    rtmpm_io::limits::read_text_bounded(path, rtmpm_io::limits::SCENE_MAX_BYTES, "scene file")
        .ok()
        .and_then(|t| toml::from_str::<toml::Table>(&t).ok())
        .is_some_and(|t| t.contains_key("batch"))
}

/// The scene file `path` as a batch of worlds. A batch whose memory (the file's scene times the
/// count) cannot fit is refused with the numbers before its worlds are made.
pub fn load(path: &Path) -> Result<BatchScene> {
    BatchScene::from_file_checked(path, |base, batch| {
        let estimate = scaled_budget(&Budget::estimate(base, None), batch.count);
        match memory_refusal(&estimate, batch.count, host_memory_available()) {
            Some(r) => Err(anyhow::anyhow!(
                "the batch of scene `{}` does not fit this machine:\n{r}",
                base.name
            )),
            None => Ok(()),
        }
    })
}

/// The budget of every world together (`frames` overriding the duration), its warnings, and
/// the refusal of a batch that cannot fit: with the worlds, their memory and how many fit.
pub fn enforce(b: &BatchScene, frames: Option<u64>, out: Option<&Path>) -> Result<Budget> {
    let budget = b.budget(frames);
    for w in budget.warnings().into_iter().chain(b.base.warnings()) {
        eprintln!("warning: {w}");
    }
    let mut refusals: Vec<String> = b
        .memory_refusal(&budget, host_memory_available())
        .into_iter()
        .collect();
    // The other refusals (disk, steps, frames) as for one scene; memory is said above.
    let disk = out.and_then(crate::budget::disk_available);
    refusals.extend(
        budget
            .refusals(None, disk, out.is_some())
            .iter()
            .map(|r| r.to_string()),
    );
    if !refusals.is_empty() {
        bail!(
            "the batch of scene `{}` does not fit this machine:\n{}{}",
            b.base.name,
            refusals.join("\n"),
            worst_world(b, frames)
        );
    }
    Ok(budget)
}

/// The first world whose own steps or frames cannot run (a swept value too fast or a step
/// too short), as a line naming it and its swept values; empty when no single world is refused.
fn worst_world(b: &BatchScene, frames: Option<u64>) -> String {
    (0..b.count())
        .find(|&w| {
            !Budget::estimate(&b.worlds[w], frames)
                .refusals(None, None, false)
                .is_empty()
        })
        .filter(|_| b.batch.is_some())
        .map(|w| {
            format!(
                "\n(world {w} of {}, {}: its own steps do not fit; the other worlds' values are \
                 in `rtmpm check`)",
                b.count(),
                b.label(w)
            )
        })
        .unwrap_or_default()
}

/// The lines `rtmpm check` prints about a batch: the count and what each world sets (the first
/// and last few of a long batch).
pub fn describe(b: &BatchScene) -> String {
    let n = b.count();
    let mut out = format!("  batch       {n} worlds");
    let shown: Vec<usize> = if n <= 8 {
        (0..n).collect()
    } else {
        (0..4).chain(n - 4..n).collect()
    };
    for (k, &w) in shown.iter().enumerate() {
        if k > 0 && w != shown[k - 1] + 1 {
            out.push_str("\n              ...");
        }
        out.push_str(&format!("\n    world {w:<5} {}", b.label(w)));
    }
    out
}

/// `--resume` and `--checkpoint-every` of a batch: refused where they cannot work (no
/// checkpoint at all, checkpoints without an output folder), before anything is made.
fn check_checkpoint_flags(args: &crate::run::RunArgs) -> Result<()> {
    if args.checkpoint_every == Some(0) {
        bail!(
            "--checkpoint-every 0 would write no checkpoint\n  fix: give --checkpoint-every N \
             (a checkpoint every N frames, N from 1), or leave it out"
        );
    }
    if args.checkpoint_every.is_some() && args.no_output {
        bail!(
            "--checkpoint-every with --no-output: a batch's checkpoints go into its output \
             folder (OUT/checkpoint_NNNNN/)\n  fix: leave out --no-output, or --checkpoint-every"
        );
    }
    Ok(())
}

/// `rtmpm run --resume DIR` without a scene file, where `DIR` is a batch checkpoint (a folder
/// with `batch.toml`): refused with the fix (a batch is resumed with its scene file, from which
/// its worlds are made again).
pub fn refuse_resume_without_scene(dir: &Path) -> Result<()> {
    bail!(
        "--resume {0}: a batch checkpoint is resumed with the batch's scene file (its worlds are \
         made again from it and checked against the checkpoint)\n  fix: rtmpm run SCENE --resume \
         {0}",
        dir.display()
    )
}

/// The batch checkpoint of the latest frame in the output folder `out`, if any.
fn last_checkpoint(out: &Path) -> Option<std::path::PathBuf> {
    let mut dirs: Vec<std::path::PathBuf> = std::fs::read_dir(out)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("checkpoint_"))
                && is_checkpoint(p)
        })
        .collect();
    dirs.sort();
    dirs.pop()
}

/// True when `dir` is a batch checkpoint's folder.
pub fn is_checkpoint(dir: &Path) -> bool {
    dir.join(rtmpm_driver::batch::checkpoint::TABLE).is_file()
}

/// Most worker threads a batch run starts (`--threads`), as for one CPU backend.
const MAX_THREADS: usize = 1024;

/// The flags of `rtmpm run` that a batch does not take, refused each with its fix.
fn check_flags(args: &crate::run::RunArgs) -> Result<()> {
    if !matches!(args.multi.mode()?, crate::multi::Mode::Single) {
        bail!(
            "a batch runs on one GPU or on the CPU backend: several GPUs or processes do not \
             apply\n  fix: leave out --gpus/--ranks (on one GPU every world runs in the same \
             kernels)"
        );
    }
    if args.render || args.preview.is_some() {
        bail!(
            "a batch run draws no pictures while it runs\n  fix: run it, then `rtmpm render \
             OUT` pictures every frame of its worlds side by side"
        );
    }
    if let Some(n) = args.steps {
        bail!(
            "--steps {n}: a batch run advances its worlds by whole frames, each world at its own \
             time step, so a count of steps means a different time in each world\n  fix: give \
             --frames N (or, from Python, BatchSimulation.step(n) steps every world n times)"
        );
    }
    check_checkpoint_flags(args)?;
    if let Some(p) = args.precision {
        bail!(
            "--precision {p}: a batch run takes its precision from the scene\n  fix: set \
             `precision = \"{p}\"` in the scene's [solver] table (every world runs at it)",
            p = p.name()
        );
    }
    Ok(())
}

/// The backend of a batch run (`rtmpm_backends::batch::choose_for`): `--backend auto` picks
/// the GPU when one is usable and the batch uses only what the GPU batch supports, else the
/// CPU with a one-line note of why; `--backend cuda` where the GPU batch cannot run is refused
/// with the reason.
fn choose_backend(
    args: &crate::run::RunArgs,
    b: &BatchScene,
) -> Result<crate::backend::BackendKind> {
    use crate::backend::BackendKind;
    let choice =
        rtmpm_backends::batch::choose_for(args.backend.into(), &b.worlds, &args.cuda_options)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    if args.backend == BackendKind::Auto {
        eprintln!("backend: {}", choice.reason);
    }
    Ok(match choice.kind {
        rtmpm_backends::BackendKind::Cuda => BackendKind::Cuda,
        _ => BackendKind::Cpu,
    })
}

/// `rtmpm run` of a scene with `[batch]`: every world on the CPU backend, frame by frame, or
/// every world in the same kernels on one GPU (`--backend cuda`, or `auto` with a GPU that
/// runs the batch), each world's frames in its folder (`docs/batch.md`), a line per frame and
/// a summary at the end.
pub fn run(args: &crate::run::RunArgs) -> Result<()> {
    use crate::backend::{BackendKind, make_backend};
    let Some(path) = args.scene.as_deref() else {
        bail!("no scene given: rtmpm run SCENE");
    };
    let b = &load(path)?;
    use rtmpm_driver::batch::{BatchOptions, BatchRun, WorldStatus};
    check_flags(args)?;
    if let Some(n) = args.threads {
        if n == 0 || n > MAX_THREADS {
            bail!("--threads must be from 1 to {MAX_THREADS}, got {n}");
        }
        // One pool for every world (a pool per world would start count x n threads).
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} worker threads: {e}"))?;
    }
    let out = (!args.no_output).then(|| args.out.clone().unwrap_or(b.base.output.dir.clone()));
    enforce(b, args.frames, out.as_deref())?;
    let text =
        rtmpm_io::limits::read_text_bounded(path, rtmpm_io::limits::SCENE_MAX_BYTES, "scene file")?;
    let options = BatchOptions {
        frames: args.frames,
        out_dir: out.clone(),
        overwrite: args.overwrite,
    };
    let start = std::time::Instant::now();
    let origin = path.display().to_string();
    let every = args
        .checkpoint_every
        .map(|k| (k, text.as_str(), origin.as_str()));
    if choose_backend(args, b)? == BackendKind::Cuda {
        let ckpt = gpu::Checkpoints {
            resume: args.resume.as_deref(),
            every,
        };
        return gpu::run(b, &text, &options, &args.cuda_options, (start, ckpt));
    }
    eprintln!("batch: {} worlds on the CPU backend", b.count());
    let cuda = rtmpm_cuda::CudaOptions::default();
    let mut run = match &args.resume {
        Some(dir) => {
            eprintln!("resuming the batch from {}", dir.display());
            BatchRun::resume(
                b,
                &text,
                dir,
                |scene, _, p| make_backend(BackendKind::Cpu, scene, p, None, &cuda),
                &options,
            )?
        }
        None => BatchRun::new(
            b,
            &text,
            |scene, _| {
                let (p, _) = rtmpm_driver::setup::sample(scene)?;
                make_backend(BackendKind::Cpu, scene, p, None, &cuda)
            },
            &options,
        )
        .map_err(|e| match out.as_deref().and_then(last_checkpoint) {
            Some(ckpt) if !args.overwrite => e.context(format!(
                "the folder holds checkpoints of a batch: continue it with `rtmpm run {} \
                 --resume {}`",
                path.display(),
                ckpt.display()
            )),
            _ => e,
        })?,
    };
    let total = run.frames;
    run.on_world_done(world_progress(start));
    run.execute_checkpointed(every, |r, frozen| {
        for &w in frozen {
            if let WorldStatus::Frozen { reason, .. } = &r.worlds[w].status {
                eprintln!("world {w} ({}) frozen: {reason}", r.worlds[w].label);
            }
        }
        eprintln!(
            "frame {}/{total}: {} of {} worlds running, {:.1} s",
            r.frame(),
            r.running(),
            r.worlds.len(),
            start.elapsed().as_secs_f64()
        );
    })?;
    let frozen = run.worlds.len() - run.running();
    println!(
        "batch of {} worlds: {} frames in {:.1} s, {frozen} frozen{}",
        run.worlds.len(),
        total,
        start.elapsed().as_secs_f64(),
        match &out {
            Some(d) => format!(
                "; frames in {}/world_*/ (batch.csv lists them)",
                d.display()
            ),
            None => String::new(),
        }
    );
    Ok(())
}

/// Progress inside a frame of many worlds: a line at most every 2 s while its worlds advance
/// (the frame's own line follows when it is done).
fn world_progress(start: std::time::Instant) -> impl FnMut(usize, usize) + Send + 'static {
    let mut last = std::time::Instant::now();
    move |done, of| {
        if done < of && last.elapsed().as_secs_f64() >= 2.0 {
            last = std::time::Instant::now();
            eprintln!(
                "  {done} of {of} worlds advanced this frame, {:.1} s",
                start.elapsed().as_secs_f64()
            );
        }
    }
}
