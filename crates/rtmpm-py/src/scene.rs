//! `rtmpm.Scene`: a validated scene, from a file, TOML text or a dict (the same schema and
//! validation as `rtmpm run`, see docs/scene-format.md).

use crate::errors::scene_error;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rtmpm_scene::{BatchScene, Scene, StepMode};
use std::path::{Path, PathBuf};

/// A validated scene.
///
/// Build one with :meth:`Scene.load` (a TOML file), :meth:`Scene.from_toml` (TOML text) or
/// :meth:`Scene.from_dict` (the same structure as a dict). Invalid scenes raise
/// :class:`rtmpm.SceneError` with the file, line, field and fix.
#[pyclass(name = "Scene", module = "rtmpm", frozen)]
pub struct PyScene {
    pub scene: Scene,
    /// The scene's TOML text (written into checkpoints).
    pub text: String,
    /// Where it came from: a path, "<string>" or "<dict>".
    pub origin: String,
    /// The worlds of the scene's `[batch]` (`None` without one): a `Simulation` of it is a
    /// batch (`crate::batch`).
    pub batch: Option<BatchScene>,
}

impl PyScene {
    /// Parse `text` as the scene that `origin` names, with mesh paths relative to `base`.
    pub fn parse(
        py: Python<'_>,
        text: String,
        origin: String,
        base: &Path,
        from_dict: bool,
    ) -> PyResult<PyScene> {
        let b = BatchScene::from_toml_in(&text, &origin, base)
            .map_err(|e| scene_error(py, &e, from_dict))?;
        Ok(PyScene::of(b, text, origin))
    }

    /// The scene of `b` (its file's scene, and its worlds when it has a `[batch]`).
    fn of(b: BatchScene, text: String, origin: String) -> PyScene {
        PyScene {
            scene: b.base.clone(),
            batch: b.batch.is_some().then_some(b),
            text,
            origin,
        }
    }
}

/// Issue the scene's warnings (what `rtmpm run` prints as "warning:") as `UserWarning`s.
pub fn warn(py: Python<'_>, scene: &Scene) -> PyResult<()> {
    for w in scene.warnings() {
        let text = std::ffi::CString::new(w).unwrap_or_default();
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        PyErr::warn(py, &category, &text, 1)?;
    }
    Ok(())
}

#[pymethods]
impl PyScene {
    /// Read and validate a scene file (mesh paths are relative to the file's folder).
    ///
    /// Raises :class:`rtmpm.SceneError` when the file cannot be read or is invalid.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyScene> {
        let b = BatchScene::from_file(&path).map_err(|e| scene_error(py, &e, false))?;
        // from_file succeeded, so the file was readable a moment ago.
        let text = std::fs::read_to_string(&path).map_err(|e| {
            crate::errors::SceneError::new_err(format!("{}: cannot read: {e}", path.display()))
        })?;
        Ok(PyScene::of(b, text, path.display().to_string()))
    }

    /// Parse and validate scene text (TOML). Mesh paths are relative to ``base_dir`` (default:
    /// the current directory).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(py: Python<'_>, text: String, base_dir: Option<PathBuf>) -> PyResult<PyScene> {
        let base = base_dir.unwrap_or_default();
        PyScene::parse(py, text, "<string>".into(), &base, false)
    }

    /// Validate a scene given as a dict with the structure of a scene file, e.g.
    /// ``{"domain": {"min": [0, 0, 0], "max": [1, 1, 1], "dx": 0.05}, "time": {...},
    /// "material": [{...}], "body": [{...}]}``. Lists, tuples and NumPy arrays are arrays;
    /// ``None`` values are left out. Mesh paths are relative to ``base_dir``.
    ///
    /// Errors are the same as for files, without line numbers (``file == "<dict>"``).
    #[staticmethod]
    #[pyo3(signature = (d, base_dir = None))]
    fn from_dict(
        py: Python<'_>,
        d: &Bound<'_, PyDict>,
        base_dir: Option<PathBuf>,
    ) -> PyResult<PyScene> {
        let text = crate::dict_toml::dict_to_toml(d)?;
        let base = base_dir.unwrap_or_default();
        PyScene::parse(py, text, "<dict>".into(), &base, true)
    }

    /// The scene's TOML text (for a dict scene, the TOML generated from it).
    fn to_toml(&self) -> String {
        self.text.clone()
    }

    /// Scene name (the default output folder's name).
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// Where the scene came from: its path, ``"<string>"`` or ``"<dict>"``.
    #[getter]
    fn source(&self) -> String {
        self.origin.clone()
    }

    /// What the scene allows but probably gets wrong, one string each, as ``rtmpm check``
    /// prints them (today: rigid bodies that can hang in a fluid they are denser than, see
    /// docs/scene-format.md, "Resolution of rigid bodies"). A :class:`Simulation` of the scene
    /// issues them as ``UserWarning``.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scene.warnings()
    }

    /// The number of worlds of the scene's ``[batch]``, or ``None`` without one. A
    /// :class:`Simulation` of a scene with ``[batch]`` is a :class:`BatchSimulation` of its
    /// worlds (docs/batch.md); the other properties are those of the scene as written.
    #[getter]
    fn batch(&self) -> Option<usize> {
        self.batch.as_ref().map(BatchScene::count)
    }

    /// What sets each world of ``[batch]`` apart (``"material[0].yield_stress = 150"``); empty
    /// without ``[batch]``.
    #[getter]
    fn batch_labels(&self) -> Vec<String> {
        match &self.batch {
            Some(b) => (0..b.count()).map(|w| b.label(w)).collect(),
            None => Vec::new(),
        }
    }

    /// Grid spacing (m).
    #[getter]
    fn dx(&self) -> f32 {
        self.scene.dx
    }

    /// The simulation box as ``((xmin, ymin, zmin), (xmax, ymax, zmax))`` (m).
    #[getter]
    fn domain(&self) -> ([f32; 3], [f32; 3]) {
        (
            self.scene.domain_min.to_array(),
            self.scene.domain_max.to_array(),
        )
    }

    /// Gravity (m/s^2).
    #[getter]
    fn gravity(&self) -> [f32; 3] {
        self.scene.gravity.to_array()
    }

    /// Output frames per simulated second.
    #[getter]
    fn fps(&self) -> f32 {
        self.scene.time.fps
    }

    /// Simulated duration (s).
    #[getter]
    fn duration(&self) -> f32 {
        self.scene.time.duration
    }

    /// Number of frames of the duration.
    #[getter]
    fn frames(&self) -> u64 {
        self.scene.time.frames()
    }

    /// The fixed time step (s), or None with the CFL rule.
    #[getter]
    fn fixed_dt(&self) -> Option<f32> {
        match self.scene.time.step {
            StepMode::Fixed { dt } => Some(dt),
            StepMode::Cfl { .. } => None,
        }
    }

    /// ``"f32"`` or ``"f64"`` (``[solver] precision``).
    #[getter]
    fn precision(&self) -> &'static str {
        self.scene.precision.name()
    }

    /// Material names, in the order of the particles' ``material`` index.
    #[getter]
    fn materials(&self) -> Vec<String> {
        self.scene
            .materials
            .iter()
            .map(|m| m.name.clone())
            .collect()
    }

    /// Number of particles the bodies are filled with (samples them).
    fn count_particles(&self, py: Python<'_>) -> PyResult<usize> {
        let p = self
            .scene
            .sample_particles()
            .map_err(|e| scene_error(py, &e, self.origin == "<dict>"))?;
        Ok(p.len())
    }

    fn __repr__(&self) -> String {
        let (lo, hi) = (self.scene.domain_min, self.scene.domain_max);
        format!(
            "Scene(name={:?}, source={:?}, domain=({:?}, {:?}), dx={}, materials={:?})",
            self.scene.name,
            self.origin,
            lo.to_array(),
            hi.to_array(),
            self.scene.dx,
            self.materials()
        )
    }
}

/// Accept a Scene, a path (str or os.PathLike) or a dict where a scene is expected.
pub fn scene_arg(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<Py<PyScene>> {
    if let Ok(s) = obj.cast::<PyScene>() {
        return Ok(s.clone().unbind());
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        return Py::new(py, PyScene::from_dict(py, d, None)?);
    }
    if let Ok(p) = obj.extract::<PathBuf>() {
        return Py::new(py, PyScene::load(py, p)?);
    }
    Err(pyo3::exceptions::PyTypeError::new_err(
        "scene must be an rtmpm.Scene, a path to a scene file or a dict",
    ))
}
