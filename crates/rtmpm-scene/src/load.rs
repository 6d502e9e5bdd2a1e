//! Scenes from files and text: read (size-bounded), parsed and validated.

use crate::error::SceneError;
use crate::scene::Scene;
use crate::validate;
use std::path::Path;

impl Scene {
    /// Read and validate a scene file; mesh paths are relative to the file's folder.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
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
        Ok(scene)
    }

    /// Parse and validate scene text; `origin` names it in error messages. Mesh paths are
    /// relative to the current directory.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        validate::parse(text, origin, Path::new(""), None)
    }

    /// Like [`Scene::from_toml`], with mesh paths relative to `base_dir`.
    pub fn from_toml_in(text: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        validate::parse(text, origin, base_dir, None)
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
