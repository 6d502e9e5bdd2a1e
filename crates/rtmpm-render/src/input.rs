//! What the renderer takes: the particles of a frame ([`RenderInput`]) and how to draw them
//! ([`RenderOptions`]), with the estimates of a good particle radius and colour range.

use crate::camera::Camera;
use rtmpm_geometry::Collider;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::ColorBy;

/// Von Mises equivalent stress of a symmetric stress `[xx, yy, zz, xy, yz, xz]`.
pub fn von_mises(s: [f32; 6]) -> f32 {
    let [xx, yy, zz, xy, yz, xz] = s;
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
        + 3.0 * (xy * xy + yz * yz + xz * xz))
        .max(0.0)
        .sqrt()
}

/// The particles of one frame, as the renderer needs them.
#[derive(Clone, Copy, Debug)]
pub struct RenderInput<'a> {
    /// Positions (m).
    pub positions: &'a [Vec3],
    /// Material index per particle (for [`ColorBy::Material`]).
    pub material: &'a [u32],
    /// The scalar field coloured by, one value per particle (required unless colouring by
    /// material).
    pub field: Option<&'a [f32]>,
    /// A surface mesh drawn with the colour of the given material (fluid surfaces; the
    /// caller leaves the particles it replaces out of `positions`).
    pub surface: Option<(&'a rtmpm_geometry::surface::TriMesh, u32)>,
}

/// How to draw a frame.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image size in pixels.
    pub width: u32,
    /// Image size in pixels.
    pub height: u32,
    /// The camera.
    pub camera: Camera,
    /// Colouring.
    pub color_by: ColorBy,
    /// Colour range of the field; `None`: the 1st to 99th percentile of this frame.
    pub range: Option<(f32, f32)>,
    /// Particle radius (m), see [`estimate_radius`].
    pub radius: f32,
    /// Height of the ground plane (m); `None` draws no ground.
    pub floor: Option<f32>,
    /// The box the scene lives in (m): bounds of the shadow map and of the ground's checkers.
    pub bounds: (Vec3, Vec3),
    /// Colour per material index (0..1 RGB); empty: [`crate::colormap::PALETTE`].
    pub palette: Vec<[f32; 3]>,
    /// Text drawn in the top-left corner (e.g. the frame number).
    pub label: Option<String>,
    /// Shadows cast by the particles and colliders (on the ground and each other).
    pub shadows: bool,
    /// Colliders to draw (grey, clipped to `bounds`); empty draws none.
    pub colliders: Vec<Collider>,
    /// Simulated time of the frame (s): the pose of moving colliders.
    pub time: f32,
}

impl RenderOptions {
    /// Default options for a scene box `[min, max]`: 1280x720, automatic camera, material
    /// colours, ground at `min.y`, shadows on.
    pub fn new(min: Vec3, max: Vec3, radius: f32) -> RenderOptions {
        RenderOptions {
            width: 1280,
            height: 720,
            camera: Camera::framing(min, max, 16.0 / 9.0, Camera::DEFAULT_FOV),
            color_by: ColorBy::Material,
            range: None,
            radius,
            floor: Some(min.y),
            bounds: (min, max),
            palette: Vec::new(),
            label: None,
            shadows: true,
            colliders: Vec::new(),
            time: 0.0,
        }
    }
}

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RenderError(pub String);

/// Particle radius from the particles' spacing: 0.6 x the median distance to the nearest
/// neighbour, estimated on up to 2000 particles with a uniform hash grid. Returns a small
/// positive fallback (1/200 of the bounding box) for fewer than two particles.
pub fn estimate_radius(positions: &[Vec3]) -> f32 {
    let n = positions.len();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in positions.iter().filter(|p| p.is_finite()) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let ext = (hi - lo).max(Vec3::splat(1e-6));
    if n < 2 || !ext.is_finite() {
        return if ext.is_finite() {
            (ext.max_element() / 200.0).max(1e-3)
        } else {
            0.01
        };
    }
    // Cell size: the spacing if the particles filled their box, at least 1/256 of its longest
    // side; particles in occupied regions are denser, so neighbours are within one cell.
    let cell = (ext.x * ext.y * ext.z / n as f32)
        .cbrt()
        .max(ext.max_element() / 256.0);
    let key = |p: Vec3| -> (i32, i32, i32) {
        let c = ((p - lo) / cell).floor();
        (c.x as i32, c.y as i32, c.z as i32)
    };
    let mut grid: rustc_hash::FxHashMap<(i32, i32, i32), Vec<u32>> = Default::default();
    for (i, p) in positions.iter().enumerate().filter(|(_, p)| p.is_finite()) {
        grid.entry(key(*p)).or_default().push(i as u32);
    }
    let stride = (n / 2000).max(1);
    let mut nn: Vec<f32> = (0..n)
        .step_by(stride)
        .filter(|&i| positions[i].is_finite())
        .filter_map(|i| {
            let p = positions[i];
            let (cx, cy, cz) = key(p);
            let mut best = f32::INFINITY;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = grid.get(&(cx + dx, cy + dy, cz + dz)) {
                            for &j in list {
                                if j as usize != i {
                                    let d = (positions[j as usize] - p).length_squared();
                                    if d > 0.0 {
                                        best = best.min(d);
                                    }
                                }
                            }
                        }
                    }
                }
            }
            best.is_finite().then(|| best.sqrt())
        })
        .collect();
    if nn.is_empty() {
        return cell * 0.5;
    }
    let mid = nn.len() / 2;
    let (_, m, _) = nn.select_nth_unstable_by(mid, f32::total_cmp);
    0.6 * *m
}

/// The 1st and 99th percentiles of the finite values (`(0, 1)` when there are none); the
/// range is widened when both ends coincide.
pub fn field_range(values: &[f32]) -> (f32, f32) {
    let stride = (values.len() / 200_000).max(1);
    let mut v: Vec<f32> = values
        .iter()
        .step_by(stride)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    let k_lo = (v.len() - 1) / 100;
    let k_hi = (v.len() - 1) - (v.len() - 1) / 100;
    let lo = *v.select_nth_unstable_by(k_lo, f32::total_cmp).1;
    let hi = *v.select_nth_unstable_by(k_hi, f32::total_cmp).1;
    if hi > lo {
        (lo, hi)
    } else {
        let pad = (lo.abs() * 0.01).max(1e-6);
        (lo - pad, hi + pad)
    }
}
