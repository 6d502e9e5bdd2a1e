//! `--resume CKPT`: the checkpoint's scene and state, checked before the run goes on: the
//! scene it holds (its errors are the checkpoint's, not the scene file's on disk), its values
//! against that scene, and the files the scene reads against the hashes the checkpoint stored.
//! The rows of `bodies.csv` up to the checkpoint's frame are checked by
//! [`crate::bodies_csv::KeptRows::read`].

use crate::bodies_csv::KeptRows;
use anyhow::{Context, Result, bail};
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_physics::Particles;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::Scene;
use rtmpm_scene::files::check_resumed;
use std::path::Path;

/// Where a resumed run stands: the checkpoint's time, step, frame and rigid bodies.
#[derive(Clone, Debug)]
pub struct ResumeState {
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// Frames completed.
    pub frame: u64,
    /// The rigid bodies' poses and velocities.
    pub bodies: Vec<BodyPose>,
    /// The rows of the output folder's `bodies.csv` the resumed run keeps, when read (and
    /// checked) before the folder was prepared; else [`crate::run::Run::new`] reads them.
    pub bodies_csv: Option<KeptRows>,
}

/// A checkpoint as read: its scene, the scene's text, the particles and the state.
pub struct Loaded {
    /// The scene it holds.
    pub scene: Scene,
    /// The scene's text, as the checkpoint holds it.
    pub scene_text: String,
    /// The particles.
    pub particles: Particles,
    /// Where the run stands.
    pub state: ResumeState,
}

/// Read the checkpoint at `path`, its scene (mesh paths relative to the folder of the scene file
/// it was written from) and particles, and check them: the values against the scene, the files
/// the scene needs against the hashes stored (notes printed for a body's file gone or changed).
pub fn load(path: &Path) -> Result<Loaded> {
    let at = || format!("cannot resume from {}", path.display());
    let ckpt = Checkpoint::load(path).with_context(at)?;
    let base = Path::new(&ckpt.scene_origin)
        .parent()
        .unwrap_or(Path::new(""));
    // Errors in the stored scene are the checkpoint's, not the scene file's on disk (which may
    // have changed since).
    let origin = format!("{} [the scene stored in it]", path.display());
    let scene =
        Scene::from_checkpoint_text(&ckpt.scene_toml, &origin, base).with_context(|| {
            format!(
                "{}: the scene it holds (written from {}) is not valid in this rtmpm",
                at(),
                ckpt.scene_origin
            )
        })?;
    scene.check_checkpoint(&ckpt).with_context(at)?;
    match check_resumed(&ckpt.files, &scene.files) {
        Ok(notes) => notes.iter().for_each(|n| eprintln!("note: {n}")),
        Err(e) => bail!("{}: {e}", at()),
    }
    if ckpt.files.is_empty() {
        let unchecked: Vec<String> = scene
            .files
            .iter()
            .filter(|f| f.needed_on_resume())
            .map(|f| f.path.display().to_string())
            .collect();
        if !unchecked.is_empty() {
            eprintln!(
                "warning: {} holds no hashes of its scene's files (written by an older rtmpm): \
                 {} cannot be checked against the run's",
                path.display(),
                unchecked.join(", ")
            );
        }
    }
    Ok(Loaded {
        scene,
        scene_text: ckpt.scene_toml,
        particles: ckpt.particles,
        state: ResumeState {
            time: ckpt.time,
            step: ckpt.step,
            frame: ckpt.frame,
            bodies: ckpt.bodies,
            bodies_csv: None,
        },
    })
}
