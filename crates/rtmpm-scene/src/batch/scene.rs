//! [`BatchScene`]: a scene file read as the worlds of its `[batch]`, each validated, with the
//! errors of a swept value placed at its sweep.

use super::path;
use super::sweep::{Batch, BatchIssue, MAX_BATCH_TEXT_BYTES};
use crate::budget::Budget;
use crate::error::SceneError;
use crate::scene::Scene;
use crate::spans::line_col;
use crate::validate;
use rtmpm_io::limits::human_bytes;
use std::path::Path;

/// A scene file as a batch of worlds: the file's scene, its `[batch]` and one validated scene
/// per world (the file's scene alone when it has no `[batch]`).
#[derive(Clone, Debug)]
pub struct BatchScene {
    /// The scene as written (world 0 before its sweeps).
    pub base: Scene,
    /// The `[batch]` table, when the file has one.
    pub batch: Option<Batch>,
    /// One scene per world, in order.
    pub worlds: Vec<Scene>,
}

impl BatchScene {
    /// Read a scene file and its worlds; mesh paths are relative to the file's folder.
    pub fn from_file(path: &Path) -> Result<BatchScene, SceneError> {
        Self::from_file_checked(path, |_, _| Ok(()))
    }

    /// [`BatchScene::from_file`], with `check` called on the file's scene and its `[batch]`
    /// before the worlds are made (the place to refuse a batch that cannot fit, from the file's
    /// scene times the count, before thousands of worlds are validated).
    pub fn from_file_checked<E: From<SceneError>>(
        path: &Path,
        check: impl FnOnce(&Scene, &Batch) -> Result<(), E>,
    ) -> Result<BatchScene, E> {
        let (base, text) = Scene::read_file(path)?;
        let origin = path.display().to_string();
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let stem = path.file_stem().and_then(|s| s.to_str());
        let Some((batch, table)) = read_batch(&text, &origin)? else {
            return Ok(BatchScene::single(base));
        };
        check(&base, &batch)?;
        let mut worlds = make_worlds(&batch, &table, &text, &origin, &dir, stem)?;
        for w in &mut worlds {
            w.source = Some(path.to_path_buf());
        }
        Ok(BatchScene {
            base,
            batch: Some(batch),
            worlds,
        })
    }

    /// Parse scene text and its worlds; mesh paths are relative to `base_dir`.
    pub fn from_toml_in(
        text: &str,
        origin: &str,
        base_dir: &Path,
    ) -> Result<BatchScene, SceneError> {
        let base = validate::parse(text, origin, base_dir, None)?;
        let Some((batch, table)) = read_batch(text, origin)? else {
            return Ok(BatchScene::single(base));
        };
        let worlds = make_worlds(&batch, &table, text, origin, base_dir, None)?;
        Ok(BatchScene {
            base,
            batch: Some(batch),
            worlds,
        })
    }

    /// Parse scene text and its worlds; mesh paths are relative to the current folder.
    pub fn from_toml(text: &str, origin: &str) -> Result<BatchScene, SceneError> {
        Self::from_toml_in(text, origin, Path::new(""))
    }

    /// A scene without `[batch]`: one world.
    pub fn single(scene: Scene) -> BatchScene {
        BatchScene {
            worlds: vec![scene.clone()],
            base: scene,
            batch: None,
        }
    }

    /// Worlds in the batch (1 without `[batch]`).
    pub fn count(&self) -> usize {
        self.worlds.len()
    }

    /// What sets world `w` apart (`material[0].yield_stress = 150`).
    pub fn label(&self, w: usize) -> String {
        match &self.batch {
            Some(b) => b.label(w),
            None => format!("world {w}"),
        }
    }

    /// The budget of all the worlds together: particles, memory and output summed, the most
    /// steps and frames of any world (see [`Budget::estimate`]).
    pub fn budget(&self, frames: Option<u64>) -> Budget {
        let each: Vec<Budget> = self
            .worlds
            .iter()
            .map(|s| Budget::estimate(s, frames))
            .collect();
        with_world_overhead(sum_budgets(&each), self.count())
    }

    /// The refusal of the batch when its memory (`budget`, of every world) is more than
    /// `host_available`: the worlds, their memory, and how many fit ([`memory_refusal`]).
    pub fn memory_refusal(&self, budget: &Budget, host_available: Option<u64>) -> Option<String> {
        memory_refusal(budget, self.count(), host_available)
    }
}

/// The refusal of `count` worlds whose memory together is `budget`'s, when more than
/// `host_available`: the worlds, their memory, and how many fit.
pub fn memory_refusal(
    budget: &Budget,
    count: usize,
    host_available: Option<u64>,
) -> Option<String> {
    let avail = host_available?;
    if budget.host_bytes <= avail {
        return None;
    }
    let n = count.max(1) as u64;
    let per_world = budget.host_bytes / n;
    Some(format!(
        "{} worlds of about {} particles need about {} of memory ({} a world), more than \
             the {} available: about {} worlds fit\n  fix: lower [batch] count, or use fewer \
             particles a world (a larger dx, a lower particles_per_cell)",
        count,
        budget.particles / n,
        human_bytes(budget.host_bytes),
        human_bytes(per_world),
        human_bytes(avail),
        avail / per_world.max(1)
    ))
}

/// The `[batch]` of `text` (checked, its sweeps in the file's order) and the file's table;
/// `None` without `[batch]`.
fn read_batch(text: &str, origin: &str) -> Result<Option<(Batch, toml::Table)>, SceneError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| SceneError {
        origin: origin.into(),
        line: None,
        column: None,
        field: None,
        message: format!("the scene does not parse as a table: {}", e.message()),
        hint: None,
    })?;
    let Some(raw) = table.get("batch") else {
        return Ok(None);
    };
    let at = |issue: BatchIssue| positioned(issue, text, origin);
    let mut batch = Batch::parse(raw).map_err(at)?;
    // The sweeps in the file's order (the table sorts its keys).
    batch
        .sweeps
        .sort_by_key(|s| batch_span(text, Some(&s.path), None));
    let bytes = text.len().saturating_mul(batch.count);
    if bytes > MAX_BATCH_TEXT_BYTES {
        return Err(at(BatchIssue::of_key(
            "count",
            format!(
                "{} worlds of this {} scene would hold {} of scene text, more than the {} \
                 allowed",
                batch.count,
                human_bytes(text.len() as u64),
                human_bytes(bytes as u64),
                human_bytes(MAX_BATCH_TEXT_BYTES as u64)
            ),
            "use fewer worlds, or a smaller scene file",
        )));
    }
    Ok(Some((batch, table)))
}

/// Every world's scene, validated; a world refused is reported at the sweep that made it.
fn make_worlds(
    batch: &Batch,
    table: &toml::Table,
    text: &str,
    origin: &str,
    dir: &Path,
    stem: Option<&str>,
) -> Result<Vec<Scene>, SceneError> {
    let tables = batch
        .expand(table)
        .map_err(|issue| positioned(issue, text, origin))?;
    tables
        .iter()
        .enumerate()
        .map(|(w, t)| {
            let world_text = toml::to_string(t).map_err(|e| SceneError {
                origin: origin.into(),
                line: None,
                column: None,
                field: Some("batch".into()),
                message: format!("world {w}'s scene cannot be written: {e}"),
                hint: None,
            })?;
            validate::parse(&world_text, origin, dir, stem)
                .map_err(|e| world_error(batch, w, &e, table, text, origin))
        })
        .collect()
}

/// The budget of `count` worlds like the one of `one` (the estimate before the worlds are
/// made: memory, particles and output times the count, with each world's fixed host memory,
/// [`HOST_BYTES_PER_WORLD`]).
pub fn scaled_budget(one: &Budget, count: usize) -> Budget {
    let n = count as u64;
    let all = Budget {
        body_particles: one
            .body_particles
            .iter()
            .map(|b| b.saturating_mul(n))
            .collect(),
        particles: one.particles.saturating_mul(n),
        output_bytes: one.output_bytes.saturating_mul(n),
        host_bytes: one.host_bytes.saturating_mul(n),
        gpu_bytes: one.gpu_bytes.saturating_mul(n),
        ..one.clone()
    };
    with_world_overhead(all, count)
}

/// Host memory of each world of a batch beyond its particles and grid nodes (its scene, its
/// simulation and backend, its output and the particles it keeps): the batches of tiny worlds
/// (7 particles, 512 to 8,192 worlds, domains of 16^3 and 32^3 cells, CPU backend) peaked at
/// 44.7 KiB more resident memory a world, of which the particles and grid counted 7.8 KiB.
pub const HOST_BYTES_PER_WORLD: u64 = 40 * 1024;

/// `budget` of `count` worlds with each world's fixed host memory ([`HOST_BYTES_PER_WORLD`]).
fn with_world_overhead(mut budget: Budget, count: usize) -> Budget {
    budget.host_bytes = budget
        .host_bytes
        .saturating_add(HOST_BYTES_PER_WORLD.saturating_mul(count as u64));
    budget
}

/// The budgets of several worlds as one run's.
fn sum_budgets(each: &[Budget]) -> Budget {
    let mut total = each.first().cloned().unwrap_or_else(|| Budget {
        body_particles: Vec::new(),
        particles: 0,
        frames: 0,
        steps: 0,
        dt: 0.0,
        dt_reason: String::new(),
        dt_fix: String::new(),
        min_dt: None,
        emitter_particles: Vec::new(),
        resumed_particles: 0,
        output_bytes: 0,
        host_bytes: 0,
        gpu_bytes: 0,
        host_bytes_per_particle: 0,
    });
    for b in each.iter().skip(1) {
        for (t, n) in total.body_particles.iter_mut().zip(&b.body_particles) {
            *t = t.saturating_add(*n);
        }
        total.particles = total.particles.saturating_add(b.particles);
        total.output_bytes = total.output_bytes.saturating_add(b.output_bytes);
        total.host_bytes = total.host_bytes.saturating_add(b.host_bytes);
        total.gpu_bytes = total.gpu_bytes.saturating_add(b.gpu_bytes);
        total.frames = total.frames.max(b.frames);
        if b.steps > total.steps {
            total.steps = b.steps;
            total.dt = b.dt;
            total.dt_reason = b.dt_reason.clone();
            total.dt_fix = b.dt_fix.clone();
            total.min_dt = b.min_dt;
        }
    }
    total
}

/// A [`BatchIssue`] at its place in the file: the sweep's key, or the `[batch]` key.
fn positioned(issue: BatchIssue, text: &str, origin: &str) -> SceneError {
    let pos = batch_span(text, issue.sweep.as_deref(), issue.key).map(|o| line_col(text, o));
    SceneError {
        origin: origin.into(),
        line: pos.map(|p| p.0),
        column: pos.map(|p| p.1),
        field: Some(issue.field()),
        message: issue.message,
        hint: Some(issue.hint),
    }
}

/// Byte offset of a sweep's key (or of `[batch]`'s `key`, or of `[batch]`).
fn batch_span(text: &str, sweep: Option<&str>, key: Option<&str>) -> Option<usize> {
    let doc = toml_edit::Document::parse(text).ok()?;
    let (bkey, batch) = doc.as_table().get_key_value("batch")?;
    let fallback = bkey.span().or_else(|| batch.span()).map(|s| s.start);
    let batch = batch.as_table_like()?;
    let found = match (sweep, key) {
        (Some(p), _) => batch
            .get("sweep")
            .and_then(|s| s.as_table_like())
            .and_then(|s| s.get_key_value(p))
            .and_then(|(k, _)| k.span()),
        (None, Some(k)) => batch.get_key_value(k).and_then(|(k, _)| k.span()),
        _ => None,
    };
    found.map(|s| s.start).or(fallback)
}

/// A world's scene refused: at the sweep whose value it is (the one the error's field names,
/// else the first), naming the world and its values.
fn world_error(
    batch: &Batch,
    w: usize,
    e: &SceneError,
    file: &toml::Table,
    text: &str,
    origin: &str,
) -> SceneError {
    let blamed = batch
        .sweeps
        .iter()
        .find(|s| e.field.as_deref().is_some_and(|f| f.starts_with(&s.path)))
        .or(batch.sweeps.first());
    let inner = match &e.field {
        Some(f) => format!("field `{f}`: {}", e.message),
        None => e.message.clone(),
    };
    // A field the file leaves out, refused as soon as it is written as an unknown name: a
    // misspelt one. (A field the scene knows, refused for its type or a rule, is the world's.)
    let unknown = blamed.is_some_and(|s| {
        e.field.as_deref() == Some(s.path.as_str())
            && path::lookup(file, &s.segs) == path::Target::Absent
            && (e.message.contains("unknown field") || e.message.contains("is not a parameter"))
    });
    let message = if unknown {
        format!("no such field in the scene: {inner}")
    } else {
        format!("world {w} ({}) is refused: {inner}", batch.label(w))
    };
    positioned(
        BatchIssue {
            sweep: blamed.map(|s| s.path.clone()),
            key: None,
            message,
            hint: e
                .hint
                .clone()
                .unwrap_or_else(|| "give every world a value the scene accepts".into()),
        },
        text,
        origin,
    )
}
