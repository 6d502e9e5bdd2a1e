//! Pictures of a simulation as NumPy arrays: `Simulation.render` (the CPU renderer of `rtmpm
//! render`, from the particles on the host) and `Simulation.render_gpu` (the backend's own
//! renderer, the one of a live view: on CUDA drawn from the state on the GPU, elsewhere the CPU
//! renderer of the same request). Both take the same arguments and make the same picture.

use crate::errors::RtmpmError;
use crate::state::Inner;
use numpy::PyArray3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_render::text::draw_text;
use rtmpm_render::{
    Camera, Image, RenderInput, RenderOptions, ViewRequest, colormap, particle_field,
};
use rtmpm_scene::sampling::per_axis;
use rtmpm_scene::{ColorBy, Scene};
use rtmpm_sim::Backend;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// The arguments of `Simulation.render` and `Simulation.render_gpu`.
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

/// The renderer's options for `view`: arguments first, then the scene's `[render]` table, then
/// the defaults (as `rtmpm run --render`); `radius` gives the default particle radius.
pub fn options(
    scene: &Scene,
    view: &View,
    radius: impl FnOnce() -> f32,
) -> PyResult<RenderOptions> {
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
        None => radius(),
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
    Ok(opts)
}

/// 0.6 of the cube root of the particles' mean initial volume (their spacing).
fn radius_of(p: &Particles) -> f32 {
    let mean_vol = p.vol0.iter().map(|&v| v as f64).sum::<f64>() / p.len().max(1) as f64;
    if mean_vol > 0.0 {
        0.6 * (mean_vol as f32).cbrt()
    } else {
        rtmpm_render::estimate_radius(&p.x)
    }
}

/// 0.6 of the particle spacing of the scene's first body (the same as [`radius_of`] for sampled
/// bodies, without reading the particles).
fn radius_of_scene(scene: &Scene) -> f32 {
    let ppc = scene.bodies.first().map_or(8, |b| b.particles_per_cell);
    0.6 * scene.dx / per_axis(ppc) as f32
}

fn to_array<'py>(py: Python<'py>, img: Image) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let arr = numpy::ndarray::Array3::from_shape_vec(
        (img.height as usize, img.width as usize, 3),
        img.rgb,
    )
    .map_err(|e| RtmpmError::new_err(format!("rendering: {e}")))?;
    Ok(numpy::IntoPyArray::into_pyarray(arr, py))
}

/// The CPU renderer's picture of the particles `p` with `opts`, the rigid bodies `bodies` drawn
/// with the colliders.
fn cpu_picture(
    p: &Particles,
    scene: &Scene,
    mut opts: RenderOptions,
    bodies: &[rtmpm_rigid::BodyState],
) -> Result<Image, String> {
    opts.colliders.extend(bodies.iter().map(|b| b.collider()));
    let field = particle_field(p, scene, opts.color_by);
    rtmpm_render::render(
        &RenderInput {
            positions: &p.x,
            material: &p.material,
            field: field.as_deref(),
            surface: None,
        },
        &opts,
    )
    .map_err(|e| e.to_string())
}

/// `Simulation.render`: the CPU renderer from the particles on the host.
pub fn render<'py>(
    py: Python<'py>,
    inner: &mut Inner,
    view: &View,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let scene = inner.sim.scene.clone();
    let bodies = if view.colliders {
        inner.sim.backend.rigid_bodies()
    } else {
        Vec::new()
    };
    let p = inner.host(py)?;
    let opts = options(&scene, view, || radius_of(p))?;
    let img = py
        .detach(|| cpu_picture(p, &scene, opts, &bodies))
        .map_err(|e| RtmpmError::new_err(format!("rendering: {e}")))?;
    to_array(py, img)
}

/// `Simulation.render_gpu`: the backend's own picture ([`Backend::render_view`]: on CUDA from the
/// state on the GPU), or where the backend does not draw, the CPU renderer's of the same request.
pub fn render_gpu<'py>(
    py: Python<'py>,
    inner: &mut Inner,
    view: &View,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    inner.usable()?;
    let scene = inner.sim.scene.clone();
    let opts = options(&scene, view, || radius_of_scene(&scene))?;
    let req = ViewRequest {
        camera: opts.camera,
        width: opts.width,
        height: opts.height,
        color_by: opts.color_by,
        range: opts.range,
        radius: opts.radius,
        colliders: view.colliders,
        floor: true,
        shadows: opts.shadows,
        time: opts.time,
    };
    let mut img = Image::new(1, 1, [0, 0, 0]);
    let backend = &mut inner.sim.backend;
    let r = py.detach(|| catch_unwind(AssertUnwindSafe(|| backend.render_view(&req, &mut img))));
    if inner.settle(py, r)? {
        if let Some(label) = &opts.label {
            let scale = (opts.height / 360).max(1);
            let m = 6 * scale as i32;
            draw_text(&mut img, m, m, label, scale, [235, 235, 235]);
        }
        return to_array(py, img);
    }
    let bodies = if view.colliders {
        inner.sim.backend.rigid_bodies()
    } else {
        Vec::new()
    };
    let mut cpu = req.options(&scene);
    cpu.label = opts.label.clone();
    let p = inner.host(py)?;
    let img = py
        .detach(|| cpu_picture(p, &scene, cpu, &bodies))
        .map_err(|e| RtmpmError::new_err(format!("rendering: {e}")))?;
    to_array(py, img)
}
