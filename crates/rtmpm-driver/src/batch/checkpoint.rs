//! Checkpoints of a batch: a folder with the batch's table, `batch.toml` (the count, and per
//! world its label, whether it runs or is frozen and why), and one checkpoint per world,
//! `world_000.ckpt`, ... (the single run's format, `rtmpm_io::checkpoint`: the scene file's
//! text, the world's clock, rigid bodies and particles; a frozen world's the last good state it
//! keeps). [`BatchRun::resume`] puts every world back as it was: on the CPU backend a resumed
//! batch goes on bit for bit as the run that wrote the checkpoint. A batch that writes frame
//! files takes its worlds' folders up after the checkpoint's frames (as a resumed single run
//! does: later frames removed, `frames.pvd` kept up to them); `rtmpm run --checkpoint-every`
//! writes its checkpoints into `OUT/checkpoint_NNNNN/`.

use super::{BatchOptions, BatchRun, WorldStatus, world_dir_name};
use anyhow::{Context, Result, bail};
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_physics::Particles;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::Backend;
use std::path::Path;
use toml_edit::{ArrayOfTables, DocumentMut, Table, value};

/// The table of a batch checkpoint, in its folder.
pub const TABLE: &str = "batch.toml";

/// A world as the table holds it.
struct Row {
    label: String,
    status: WorldStatus,
}

impl BatchRun {
    /// Save every world into the folder `dir` (made if missing; a folder holding other files
    /// than a batch checkpoint's is refused): `text` is the batch scene file's text and
    /// `origin` where it came from, both stored with each world.
    pub fn checkpoint(&mut self, dir: &Path, text: &str, origin: &str) -> Result<()> {
        prepare_dir(dir)?;
        let mut saved = Vec::with_capacity(self.worlds.len());
        for world in self.worlds.iter_mut() {
            let sim = &mut world.sim;
            let particles = match world.status {
                WorldStatus::Running => {
                    let mut p = Particles::default();
                    sim.backend.read_particles(&mut p)?;
                    p
                }
                // A frozen world's backend holds the broken state: keep its last good one.
                WorldStatus::Frozen { .. } => world.kept.clone(),
            };
            sim.backend.flush_rigid()?;
            let bodies = sim.backend.rigid_poses();
            if bodies.len() != sim.scene.rigid_bodies.len() {
                bail!(
                    "the backend `{}` does not give the poses of the scene's {} rigid bodies, \
                     which a checkpoint needs",
                    sim.backend.name(),
                    sim.scene.rigid_bodies.len()
                );
            }
            let ckpt = Checkpoint {
                scene_toml: text.to_string(),
                scene_origin: origin.to_string(),
                time: sim.time,
                step: sim.step,
                frame: sim.frame,
                bodies,
                files: sim.scene.file_hashes(),
                particles,
            };
            saved.push(Saved {
                label: world.label.clone(),
                status: world.status.clone(),
                ckpt,
            });
        }
        write_folder(dir, &saved)
    }

    /// The batch `batch` (read from the scene file whose text is `text`) at the state saved in
    /// the folder `dir` by [`BatchRun::checkpoint`]: each world on the backend
    /// `backend(scene, w, particles)` builds from its saved particles, with its clock, rigid
    /// bodies and status; with an output folder, each world's folder is taken up after its
    /// checkpoint's frame. Refused with the reason and the fix, before any folder changes, when
    /// the checkpoint was written from another scene text, for another count or other worlds
    /// (labels), or cannot be read.
    pub fn resume(
        batch: &BatchScene,
        text: &str,
        dir: &Path,
        mut backend: impl FnMut(&Scene, usize, Particles) -> Result<Box<dyn Backend>>,
        options: &BatchOptions,
    ) -> Result<BatchRun> {
        let mut saved = read_folder(batch, text, dir)?;
        let mut particles: Vec<Option<Particles>> = saved
            .iter_mut()
            .map(|s| Some(std::mem::take(&mut s.ckpt.particles)))
            .collect();
        let states: Vec<(u64, f64)> = saved.iter().map(|s| (s.ckpt.frame, s.ckpt.time)).collect();
        let mut run = BatchRun::build(
            batch,
            text,
            |scene, w| {
                let p = particles[w].take().unwrap_or_default();
                backend(scene, w, p)
            },
            options,
            Some(&states),
        )?;
        for (w, s) in saved.into_iter().enumerate() {
            let world = &mut run.worlds[w];
            world.sim.time = s.ckpt.time;
            world.sim.step = s.ckpt.step;
            world.sim.frame = s.ckpt.frame;
            world
                .sim
                .backend
                .set_rigid_poses(&s.ckpt.bodies)
                .with_context(|| format!("world {w}: cannot restore its rigid bodies"))?;
            world.sim.backend.read_particles(&mut world.kept)?;
            world.status = s.status;
        }
        Ok(run)
    }
}

/// A world as a checkpoint folder holds it: its row of the table and its checkpoint.
pub(super) struct Saved {
    /// What sets it apart.
    pub label: String,
    /// Running or frozen.
    pub status: WorldStatus,
    /// Its clock, rigid bodies and particles (a frozen world's last good state).
    pub ckpt: Checkpoint,
}

/// Write the worlds `saved` into the folder `dir` (made ready by [`prepare_dir`]): one
/// `world_NNN.ckpt` each, then the table.
pub(super) fn write_folder(dir: &Path, saved: &[Saved]) -> Result<()> {
    let count = saved.len();
    let mut rows = ArrayOfTables::new();
    for (w, s) in saved.iter().enumerate() {
        let file = format!("{}.ckpt", world_dir_name(w, count));
        let path = dir.join(&file);
        s.ckpt
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        rows.push(row_table(&file, &s.label, &s.status));
    }
    let mut doc = DocumentMut::new();
    doc["format"] = value("rtmpm batch checkpoint 1");
    doc["count"] = value(count as i64);
    doc["world"] = toml_edit::Item::ArrayOfTables(rows);
    let path = dir.join(TABLE);
    rtmpm_io::write_atomic(&path, doc.to_string().as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// The worlds saved in the folder `dir`, checked against the batch `batch` (read from the
/// scene file whose text is `text`): refused with the reason and the fix when the checkpoint
/// was written from another scene text, for another count or other worlds (labels), or cannot
/// be read.
pub(super) fn read_folder(batch: &BatchScene, text: &str, dir: &Path) -> Result<Vec<Saved>> {
    let at = || format!("cannot resume the batch from {}", dir.display());
    let rows = read_table(dir).with_context(at)?;
    if rows.len() != batch.count() {
        bail!(
            "{}: it holds {} worlds, the batch has {} ({TABLE}: count = {})\n  fix: resume \
             it with the scene file (and batch count) it was written from",
            at(),
            rows.len(),
            batch.count(),
            rows.len()
        );
    }
    let mut saved = Vec::with_capacity(rows.len());
    let count = rows.len();
    for (w, row) in rows.into_iter().enumerate() {
        let path = dir.join(format!("{}.ckpt", world_dir_name(w, count)));
        let ckpt = match Checkpoint::load(&path) {
            Ok(c) => c,
            Err(e) => bail!(
                "{}: {}: {e}\n  fix: resume from another (earlier) checkpoint folder, or run \
                 the batch again from its start",
                at(),
                path.display()
            ),
        };
        if ckpt.scene_toml != text {
            bail!(
                "{}: {} was written from another scene text (from {})\n  fix: resume it \
                 with the scene file it was written from, unchanged",
                at(),
                path.display(),
                ckpt.scene_origin
            );
        }
        if row.label != batch.label(w) {
            bail!(
                "{}: {TABLE}: world {w} is `{}`, the batch's is `{}`\n  fix: resume it with \
                 the scene file (and batch) it was written from",
                at(),
                row.label,
                batch.label(w)
            );
        }
        batch.worlds[w]
            .check_checkpoint(&ckpt)
            .with_context(|| format!("{}: {}", at(), path.display()))?;
        saved.push(Saved {
            label: row.label,
            status: row.status,
            ckpt,
        });
    }
    Ok(saved)
}

/// The folder made ready: created, or refused when it holds files but no batch checkpoint.
pub(super) fn prepare_dir(dir: &Path) -> Result<()> {
    if dir.is_dir() && !dir.join(TABLE).is_file() {
        let mut entries =
            std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
        if entries.next().is_some() {
            bail!(
                "{} holds files but no batch checkpoint ({TABLE}): give a new or empty folder",
                dir.display()
            );
        }
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))
}

/// A world's row of the table.
fn row_table(file: &str, label: &str, status: &WorldStatus) -> Table {
    let mut t = Table::new();
    t["file"] = value(file);
    t["label"] = value(label);
    match status {
        WorldStatus::Running => {
            t["state"] = value("running");
        }
        WorldStatus::Frozen { frame, reason } => {
            t["state"] = value("frozen");
            t["frozen_frame"] = value(*frame as i64);
            t["reason"] = value(reason.as_str());
        }
    }
    t
}

/// The rows of the table in `dir`.
fn read_table(dir: &Path) -> Result<Vec<Row>> {
    let path = dir.join(TABLE);
    if dir.is_file() {
        bail!(
            "{} is not a folder: a batch checkpoint is a folder holding {TABLE} and one \
             world_NNN.ckpt per world\n  fix: give OUT/checkpoint_NNNNN (written by `rtmpm run \
             --checkpoint-every`) or the folder given to BatchSimulation.checkpoint",
            dir.display()
        );
    }
    let text = rtmpm_io::limits::read_text_bounded(
        &path,
        rtmpm_io::limits::SCENE_MAX_BYTES,
        "batch checkpoint",
    )
    .with_context(|| format!("no batch checkpoint in {}", dir.display()))?;
    let doc: DocumentMut = text
        .parse()
        .with_context(|| format!("{} is not valid TOML", path.display()))?;
    let bad = |what: &str| anyhow::anyhow!("{}: {what}", path.display());
    if doc.get("format").and_then(|f| f.as_str()) != Some("rtmpm batch checkpoint 1") {
        return Err(bad(
            "not a batch checkpoint of this rtmpm (format = \"rtmpm batch checkpoint 1\" missing)",
        ));
    }
    let count = doc.get("count").and_then(|c| c.as_integer());
    let worlds = doc
        .get("world")
        .and_then(|w| w.as_array_of_tables())
        .ok_or_else(|| bad("no [[world]] rows"))?;
    if count != Some(worlds.len() as i64) {
        return Err(bad(&format!(
            "count = {count:?} but {} [[world]] rows",
            worlds.len()
        )));
    }
    worlds
        .iter()
        .enumerate()
        .map(|(w, t)| {
            let label = t.get("label").and_then(|l| l.as_str());
            let label = label.ok_or_else(|| bad(&format!("world {w} has no label")))?;
            let status = match t.get("state").and_then(|s| s.as_str()) {
                Some("running") => WorldStatus::Running,
                Some("frozen") => WorldStatus::Frozen {
                    frame: t
                        .get("frozen_frame")
                        .and_then(|f| f.as_integer())
                        .and_then(|f| u64::try_from(f).ok())
                        .ok_or_else(|| bad(&format!("world {w}: frozen_frame missing")))?,
                    reason: t
                        .get("reason")
                        .and_then(|r| r.as_str())
                        .unwrap_or_default()
                        .to_string(),
                },
                other => {
                    return Err(bad(&format!(
                        "world {w}: state {other:?} (running or frozen)"
                    )));
                }
            };
            Ok(Row {
                label: label.to_string(),
                status,
            })
        })
        .collect()
}
