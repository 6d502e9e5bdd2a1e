//! Frame files and images of the particles in memory (`Simulation.write_frame`,
//! `Simulation.render`), with rtmpm-core's writers and renderer, and checkpoints
//! (`Simulation.checkpoint`).

use crate::errors::RtmpmError;
use crate::simulation::Inner;
use numpy::PyArray3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_core::io::checkpoint::Checkpoint;
use rtmpm_core::io::{FrameFields, cauchy_stress, ply, vtk_appended};
use rtmpm_core::math::Vec3;
use rtmpm_core::render::{Camera, ColorBy, RenderInput, RenderOptions, colormap, von_mises};
use rtmpm_core::sim::Backend;
use rtmpm_core::{Particles, Scene};
use std::path::Path;

/// Write one frame file; see `Simulation.write_frame`.
pub fn write_frame(
    py: Python<'_>,
    path: &Path,
    format: Option<&str>,
    fields: Option<Vec<String>>,
    p: &Particles,
    scene: &Scene,
) -> PyResult<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let format = format.unwrap_or(ext).to_ascii_lowercase();
    if format != "ply" && format != "vtu" {
        return Err(PyValueError::new_err(format!(
            "unknown frame format {format:?} for {}: use format=\"ply\" or \"vtu\" (or a .ply / .vtu file name)",
            path.display()
        )));
    }
    let (mut stress, mut jacobian) = (scene.output.stress, scene.output.jacobian);
    if let Some(f) = fields {
        (stress, jacobian) = (false, false);
        for name in f {
            match name.as_str() {
                "stress" => stress = true,
                "J" => jacobian = true,
                other => {
                    return Err(PyValueError::new_err(format!(
                        "unknown field {other:?}: the extra fields are \"J\" and \"stress\""
                    )));
                }
            }
        }
    }
    py.detach(|| {
        let stress = stress.then(|| cauchy_stress(p, scene));
        let jacobian = jacobian.then(|| p.f.iter().map(|f| f.determinant()).collect::<Vec<f32>>());
        let fields = FrameFields {
            stress: stress.as_deref(),
            jacobian: jacobian.as_deref(),
        };
        if format == "ply" {
            ply::write_ply(path, p, &fields)
        } else {
            // The CLI's VTU: compressed appended arrays, 3x3 stress tensors.
            vtk_appended::write_particles_vtu(path, p, &fields, scene.output.compress)
        }
    })
    .map_err(|e| RtmpmError::new_err(format!("writing {}: {e}", path.display())))
}

/// The arguments of `Simulation.render`.
pub struct View<'a> {
    pub camera: Option<[f32; 3]>,
    pub target: Option<[f32; 3]>,
    pub size: Option<(u32, u32)>,
    pub fov: Option<f32>,
    pub color_by: Option<&'a str>,
    pub range: Option<(f32, f32)>,
    pub radius: Option<f32>,
    pub shadows: bool,
    pub colliders: bool,
    pub label: Option<String>,
    pub time: f32,
}

/// Render the particles; arguments first, then the scene's `[render]` table, then the
/// defaults (as `rtmpm run --render`).
pub fn render<'py>(
    py: Python<'py>,
    p: &Particles,
    scene: &Scene,
    view: &View,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let sr = &scene.render;
    let (width, height) = match (view.size, sr.width, sr.height) {
        (Some(s), _, _) => s,
        (None, Some(w), Some(h)) => (w, h),
        (None, Some(w), None) => (w, (w * 9 / 16).max(16)),
        (None, None, Some(h)) => ((h * 16 / 9).max(16), h),
        (None, None, None) => (1280, 720),
    };
    if !(16..=8192).contains(&width) || !(16..=8192).contains(&height) {
        return Err(PyValueError::new_err(format!(
            "image size {width}x{height} out of range (16 to 8192 per side)"
        )));
    }
    let (lo, hi) = scene.interior();
    let fov = view.fov.or(sr.fov).unwrap_or(Camera::DEFAULT_FOV);
    let mut camera = Camera::framing(lo, hi, width as f32 / height as f32, fov);
    if let Some(t) = view.target.map(Vec3::from_array).or(sr.target) {
        camera.target = t;
    }
    if let Some(c) = view.camera.map(Vec3::from_array).or(sr.camera) {
        camera.position = c;
    }
    camera
        .check()
        .map_err(|e| PyValueError::new_err(format!("bad camera: {e}")))?;
    let radius = match view.radius {
        Some(r) if r.is_finite() && r > 0.0 => r,
        Some(r) => {
            return Err(PyValueError::new_err(format!(
                "radius must be a positive length, got {r}"
            )));
        }
        None => {
            let mean_vol = p.vol0.iter().map(|&v| v as f64).sum::<f64>() / p.len().max(1) as f64;
            if mean_vol > 0.0 {
                0.6 * (mean_vol as f32).cbrt()
            } else {
                rtmpm_core::render::estimate_radius(&p.x)
            }
        }
    };
    let color_by = match view.color_by {
        Some(s) => s.parse::<ColorBy>().map_err(PyValueError::new_err)?,
        None => sr.color_by.unwrap_or_default(),
    };
    if let Some((a, b)) = view.range
        && !(a.is_finite() && b.is_finite() && b > a)
    {
        return Err(PyValueError::new_err(format!(
            "range ({a}, {b}): expected finite lo < hi"
        )));
    }
    let mut opts = RenderOptions::new(lo, hi, radius);
    opts.width = width;
    opts.height = height;
    opts.camera = camera;
    opts.color_by = color_by;
    opts.range = view.range;
    opts.floor = Some(lo.y);
    opts.shadows = view.shadows;
    opts.palette = colormap::scene_palette(scene);
    if view.colliders {
        opts.colliders = scene.colliders.clone();
    }
    opts.label = view.label.clone();
    opts.time = view.time;
    let img = py
        .detach(|| {
            let field: Option<Vec<f32>> = match color_by {
                ColorBy::Material => None,
                ColorBy::Speed => Some(p.v.iter().map(|v| v.length()).collect()),
                ColorBy::J => Some(p.f.iter().map(|f| f.determinant()).collect()),
                ColorBy::Plastic => Some(p.plastic.clone()),
                ColorBy::Stress => {
                    Some(cauchy_stress(p, scene).into_iter().map(von_mises).collect())
                }
            };
            rtmpm_core::render::render(
                &RenderInput {
                    positions: &p.x,
                    material: &p.material,
                    field: field.as_deref(),
                    surface: None,
                },
                &opts,
            )
        })
        .map_err(|e| RtmpmError::new_err(format!("rendering: {e}")))?;
    let arr = numpy::ndarray::Array3::from_shape_vec(
        (img.height as usize, img.width as usize, 3),
        img.rgb,
    )
    .map_err(|e| RtmpmError::new_err(format!("rendering: {e}")))?;
    Ok(numpy::IntoPyArray::into_pyarray(arr, py))
}

/// Write a checkpoint of `inner`'s simulation to `path` (atomic): the scene, time, step,
/// frame, every particle and rigid body, the bodies first taking every impulse the grid has sent
/// them (the CUDA backend moves them a step late) so that they are at the particles' time.
pub fn checkpoint(py: Python<'_>, inner: &mut Inner, path: &Path) -> PyResult<()> {
    inner
        .sim
        .backend
        .flush_rigid()
        .map_err(|e| crate::errors::sim_error(py, &e))?;
    let particles = inner.host(py)?.clone();
    let scene = inner.scene.get();
    let ckpt = Checkpoint {
        scene_toml: scene.text.clone(),
        scene_origin: scene.origin.clone(),
        time: inner.sim.time,
        step: inner.sim.step,
        frame: inner.sim.frame,
        bodies: inner.sim.backend.rigid_poses(),
        particles,
    };
    py.detach(|| ckpt.save(path))
        .map_err(|e| RtmpmError::new_err(format!("writing checkpoint {}: {e}", path.display())))
}
