//! Scenes from files and text: read (size-bounded), parsed and validated.

use crate::error::SceneError;
use crate::scene::Scene;
use crate::validate;
use std::path::Path;

impl Scene {
    /// Read and validate a scene file; mesh paths are relative to the file's folder. A file with
    /// `[batch]` is refused (it is many worlds, not one scene): [`crate::BatchScene::from_file`]
    /// reads its worlds.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let (scene, text) = Self::read_file(path)?;
        refuse_batch(&text, &path.display().to_string())?;
        Ok(scene)
    }

    /// [`Scene::from_file`] of a file with or without `[batch]`: the scene as written (before
    /// any sweep), as the base of [`crate::BatchScene`], and the file's text.
    pub(crate) fn read_file(path: &Path) -> Result<(Scene, String), SceneError> {
        let origin = path.display().to_string();
        let text = rtmpm_io::limits::read_text_bounded(
            path,
            rtmpm_io::limits::SCENE_MAX_BYTES,
            "scene file",
        )
        .map_err(|e| {
            let hint = match e.kind() {
                std::io::ErrorKind::NotFound => {
                    "check the path (it is relative to the current folder)"
                }
                std::io::ErrorKind::PermissionDenied => "check the file's permissions",
                _ => "give a scene file: TOML text as in scenes/ and docs/scene-format.md",
            };
            SceneError {
                origin: origin.clone(),
                line: None,
                column: None,
                field: None,
                message: format!("cannot read the scene file: {e}"),
                hint: Some(hint.into()),
            }
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut scene = validate::parse(
            &text,
            &origin,
            &base,
            path.file_stem().and_then(|s| s.to_str()),
        )?;
        scene.source = Some(path.to_path_buf());
        Ok((scene, text))
    }

    /// Parse and validate scene text; `origin` names it in error messages. Mesh paths are
    /// relative to the current directory. Text with `[batch]` is refused, as by
    /// [`Scene::from_file`] ([`crate::BatchScene::from_toml`] reads its worlds).
    pub fn from_toml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        Self::from_toml_in(text, origin, Path::new(""))
    }

    /// Like [`Scene::from_toml`], with mesh paths relative to `base_dir`.
    pub fn from_toml_in(text: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        let scene = validate::parse(text, origin, base_dir, None)?;
        refuse_batch(text, origin)?;
        Ok(scene)
    }

    /// The scene a checkpoint holds (its text, `origin` naming the checkpoint in messages, mesh
    /// paths relative to `base_dir`): as [`Scene::from_toml_in`], except that a body's mesh or
    /// particle file may be gone (its particles are in the checkpoint; the body then has no
    /// shape to sample, and its [`crate::files::SceneFile`] no hash).
    pub fn from_checkpoint_text(
        text: &str,
        origin: &str,
        base_dir: &Path,
    ) -> Result<Scene, SceneError> {
        validate::parse_resumed(text, origin, base_dir)
    }
}

/// The refusal of a scene with `[batch]` where one scene is expected, at the `[batch]` line.
fn refuse_batch(text: &str, origin: &str) -> Result<(), SceneError> {
    if !text.contains("batch") {
        return Ok(());
    }
    let Ok(doc) = toml_edit::Document::parse(text) else {
        return Ok(());
    };
    let Some((key, item)) = doc.as_table().get_key_value("batch") else {
        return Ok(());
    };
    let count = item
        .get("count")
        .and_then(|c| c.as_integer())
        .map_or("several".to_string(), |c| c.to_string());
    let pos = key
        .span()
        .or_else(|| item.span())
        .map(|s| crate::spans::line_col(text, s.start));
    Err(SceneError {
        origin: origin.into(),
        line: pos.map(|p| p.0),
        column: pos.map(|p| p.1),
        field: Some("batch".into()),
        message: format!("this scene has a [batch] of {count} worlds, where one scene is expected"),
        hint: Some(
            "run its worlds with `rtmpm run` (`rtmpm check` lists them); from Python \
             `rtmpm.Simulation(scene)` is a BatchSimulation of them; from Rust \
             rtmpm_scene::BatchScene::from_file reads them (docs/batch.md). Without [batch] the \
             file is one scene"
                .into(),
        ),
    })
}
