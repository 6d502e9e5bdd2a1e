//! A small CPU renderer for particle frames: shaded spheres with a depth buffer, a ground plane
//! with a shadow map, depth-based ambient occlusion, colour by material or by a scalar field
//! (viridis, with a colour bar and its range as text), PNG and animated GIF output.
//!
//! * [`camera`]: pinhole camera and automatic framing of the domain.
//! * [`raster`]: sphere splatting, parallel over bands of rows (rayon).
//! * `mesh`: triangle meshes (fluid surfaces) rasterised into the same depth buffers, shaded
//!   with a specular highlight.
//! * `colliders`: colliders drawn by sphere tracing their signed distances, clipped to the
//!   scene box, into the same depth buffers (they hide, and cast and receive shadows).
//! * [`colormap`]: viridis and the material palette.
//! * [`text`]: a built-in 5x7 bitmap font for labels.
//! * [`image`]: RGB images, PNG encoding/decoding, resizing, GIF movies.
//! * [`view`]: what a live view asks a backend to draw ([`ViewRequest`]), as options of this
//!   renderer.
//!
//! [`render`] draws one frame from particle arrays in memory; callers that read PLY frames
//! build the same [`RenderInput`] from the file's columns.

pub mod camera;
mod colliders;
pub mod colormap;
pub mod image;
mod mesh;
pub mod plot;
pub(crate) mod raster;
mod shadow;
#[cfg(test)]
mod tests;
#[cfg(test)]
pub(crate) use tests::support as tests_support;
pub mod text;
pub mod view;

pub use camera::{Camera, View};
pub use colliders::COLLIDER_COLOR;
pub use image::{GifMovie, Image};
pub use shadow::{LIGHT, SHADOW_RES, ShadowFrame};
pub use view::{ViewRequest, particle_field};

use colliders::{COLLIDER_ID, PosedCollider};
use raster::{Splat, raster};
use rayon::prelude::*;
use rtmpm_geometry::Collider;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::ColorBy;
use shadow::ShadowMap;

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
    /// Colour per material index (0..1 RGB); empty: [`colormap::PALETTE`].
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

/// Format a colour-bar value compactly (`0.125`, `12.5`, `1.25E5`).
pub fn format_value(v: f32) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-2..1e4).contains(&a) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.2e}").to_uppercase()
    }
}

/// One texel of the G-buffer: depth along the view axis, the splat coordinates (giving the
/// sphere normal) and the particle index.
#[derive(Clone, Copy)]
struct GTexel {
    depth: f32,
    u: f32,
    v: f32,
    id: u32,
}

/// Render one frame.
pub fn render(input: &RenderInput, opts: &RenderOptions) -> Result<Image, RenderError> {
    let n = input.positions.len();
    if input.material.len() != n {
        return Err(RenderError(format!(
            "{} material indices for {n} particles",
            input.material.len()
        )));
    }
    let field = match (opts.color_by, input.field) {
        (ColorBy::Material, _) => None,
        (c, None) => {
            return Err(RenderError(format!(
                "colouring by {c} needs the field, which the frame does not have"
            )));
        }
        (_, Some(f)) if f.len() != n => {
            return Err(RenderError(format!(
                "{} field values for {n} particles",
                f.len()
            )));
        }
        (_, Some(f)) => Some(f),
    };
    if opts.width == 0 || opts.height == 0 || opts.width > 16384 || opts.height > 16384 {
        return Err(RenderError(format!(
            "image size {}x{} is out of range (1 to 16384 per side)",
            opts.width, opts.height
        )));
    }
    opts.camera.check().map_err(RenderError)?;
    if !(opts.radius.is_finite() && opts.radius > 0.0) {
        return Err(RenderError(format!(
            "particle radius must be positive, got {}",
            opts.radius
        )));
    }
    let (w, h) = (opts.width as usize, opts.height as usize);
    let view = opts.camera.view(opts.width, opts.height);
    let wr = opts.radius;
    let near = 1e-4_f32.max(wr);

    // Project.
    let splats: Vec<Splat> = input
        .positions
        .par_iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let (x, y, z) = view.project(*p);
            (z > near && x.is_finite() && y.is_finite()).then(|| Splat {
                x,
                y,
                r: (wr * view.focal / z).max(0.6),
                z,
                wr,
                id: i as u32,
            })
        })
        .collect();
    let mut gbuf = vec![
        GTexel {
            depth: f32::INFINITY,
            u: 0.0,
            v: 0.0,
            id: 0,
        };
        w * h
    ];
    raster(&splats, w, h, &mut gbuf, |t, s, u, v| {
        let d = s.z - (1.0 - u * u - v * v).max(0.0).sqrt() * s.wr;
        if d < t.depth {
            *t = GTexel {
                depth: d,
                u,
                v,
                id: s.id,
            };
        }
    });
    drop(splats);
    let posed: Vec<PosedCollider> = opts
        .colliders
        .iter()
        .filter_map(|c| PosedCollider::new(c, opts.time, opts.bounds))
        .collect();
    colliders::draw(&posed, &view, near, w, h, &mut gbuf);
    if let Some((m, material)) = input.surface {
        m.check()
            .map_err(|e| RenderError(format!("bad surface mesh: {e}")))?;
        mesh::draw(m, material, &view, near, w, h, &mut gbuf);
    }
    let shadow = opts.shadows.then(|| {
        let mut map = ShadowMap::build(input, opts);
        colliders::cast_shadows(&posed, &mut map);
        if let Some((m, _)) = input.surface {
            mesh::cast_shadows(m, &mut map);
        }
        map
    });

    // Colours.
    let (lo, hi) = match field {
        Some(f) => opts.range.unwrap_or_else(|| field_range(f)),
        None => (0.0, 1.0),
    };
    let inv_range = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
    let palette: &[[f32; 3]] = if opts.palette.is_empty() {
        &colormap::PALETTE
    } else {
        &opts.palette
    };
    let base = |id: u32| -> Vec3 {
        if id == COLLIDER_ID {
            return Vec3::from(COLLIDER_COLOR);
        }
        if let Some(m) = mesh::mesh_material(id) {
            return Vec3::from(palette[m as usize % palette.len()]);
        }
        let c = match field {
            Some(f) => colormap::viridis((f[id as usize] - lo) * inv_range),
            None => palette[input.material[id as usize] as usize % palette.len()],
        };
        Vec3::from(c)
    };

    // Shade.
    let light = LIGHT.normalize();
    let (blo, bhi) = opts.bounds;
    let bcenter = 0.5 * (blo + bhi);
    let bsize = (bhi - blo).max_element().max(1e-6);
    let checker = bsize / 12.0;
    let ao_r = (h as i64 / 140).max(2);
    let ao_offsets: [(i64, i64); 8] = [
        (ao_r, 0),
        (-ao_r, 0),
        (0, ao_r),
        (0, -ao_r),
        (ao_r * 7 / 10, ao_r * 7 / 10),
        (-ao_r * 7 / 10, ao_r * 7 / 10),
        (ao_r * 7 / 10, -ao_r * 7 / 10),
        (-ao_r * 7 / 10, -ao_r * 7 / 10),
    ];
    let mut img = Image::new(opts.width, opts.height, [0, 0, 0]);
    img.rgb
        .par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(y, row)| {
            let sky_t = y as f32 / h as f32;
            let sky =
                Vec3::new(0.15, 0.17, 0.21) * (1.0 - sky_t) + Vec3::new(0.36, 0.38, 0.43) * sky_t;
            for x in 0..w {
                let ray = view.ray(x as f32 + 0.5, y as f32 + 0.5);
                let ground_t = match opts.floor {
                    Some(f) if ray.y < 0.0 && view.pos.y > f => (f - view.pos.y) / ray.y,
                    _ => f32::INFINITY,
                };
                let g = gbuf[y * w + x];
                let c = if g.depth < ground_t {
                    let nz = (1.0 - g.u * g.u - g.v * g.v).max(0.0).sqrt();
                    let normal = view.right * g.u - view.up * g.v - view.fwd * nz;
                    let p = view.pos + ray * g.depth;
                    let lambert = normal.dot(light).max(0.0);
                    let lit = shadow
                        .as_ref()
                        .map_or(1.0, |s| s.light(p + normal * (0.5 * wr), 2.0 * wr));
                    // Depth darkening: neighbours clearly in front occlude.
                    let mut occ = 0.0;
                    for (ox, oy) in ao_offsets {
                        let (sx, sy) = (x as i64 + ox, y as i64 + oy);
                        if sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h {
                            let d = g.depth - gbuf[sy as usize * w + sx as usize].depth;
                            if d > 0.5 * wr && d < 12.0 * wr {
                                occ += 1.0;
                            }
                        }
                    }
                    let ao = 1.0 - 0.55 * occ / 8.0;
                    // Rim light on the particles' edges (colliders' surfaces are not spheres).
                    let rim = if g.id == COLLIDER_ID {
                        0.0
                    } else {
                        0.12 * (1.0 - nz).powi(2)
                    };
                    // Surfaces (water) get a specular highlight (Blinn-Phong).
                    let spec = if mesh::mesh_material(g.id).is_some() {
                        let half = (light - ray.normalize()).normalize_or(light);
                        0.45 * normal.dot(half).max(0.0).powi(60) * lit
                    } else {
                        0.0
                    };
                    base(g.id) * (0.32 * ao + 0.68 * lambert * (0.5 + 0.5 * lit))
                        + Vec3::splat(rim * ao + spec)
                } else if ground_t.is_finite() {
                    let p = view.pos + ray * ground_t;
                    let inside = p.x >= blo.x && p.x <= bhi.x && p.z >= blo.z && p.z <= bhi.z;
                    let albedo = if inside {
                        let k = (p.x / checker).floor() as i64 + (p.z / checker).floor() as i64;
                        if k & 1 == 0 { 0.80 } else { 0.70 }
                    } else {
                        0.55
                    };
                    let lit = shadow.as_ref().map_or(1.0, |s| s.light(p, 0.5 * wr));
                    let c = Vec3::splat(albedo * (0.35 + 0.65 * light.y * (0.3 + 0.7 * lit)));
                    // Fade into the background far from the scene.
                    let dist = ((p - bcenter) * Vec3::new(1.0, 0.0, 1.0)).length() / bsize;
                    let fade = (-(dist - 0.6).max(0.0) * 1.2).exp();
                    c * fade + sky * (1.0 - fade)
                } else {
                    sky
                };
                row[3 * x] = colormap::to_u8(c.x);
                row[3 * x + 1] = colormap::to_u8(c.y);
                row[3 * x + 2] = colormap::to_u8(c.z);
            }
        });

    // Overlays.
    let scale = (opts.height / 360).max(1);
    if field.is_some() {
        draw_color_bar(&mut img, opts.color_by.label(), lo, hi, scale);
    }
    if let Some(label) = &opts.label {
        let m = 6 * scale as i32;
        text::draw_text(&mut img, m, m, label, scale, [235, 235, 235]);
    }
    Ok(img)
}

/// Vertical viridis bar at the right edge, title above, max/mid/min labels to its left (what
/// [`render`] draws when colouring by a field; the GPU renderers draw it with this too).
pub fn draw_color_bar(img: &mut Image, title: &str, lo: f32, hi: f32, scale: u32) {
    let (w, h) = (img.width as i32, img.height as i32);
    let s = scale as i32;
    let margin = 10 * s;
    let bar_w = 10 * s;
    let bar_h = (h / 2).max(8);
    let x1 = w - margin;
    let x0 = x1 - bar_w;
    let y0 = (h - bar_h) / 2;
    let y1 = y0 + bar_h;
    img.fill_rect(x0 - 1, y0 - 1, bar_w + 2, bar_h + 2, [235, 235, 235]);
    for y in y0..y1 {
        let t = (y1 - 1 - y) as f32 / (bar_h - 1).max(1) as f32;
        let c = colormap::viridis(t);
        img.fill_rect(x0, y, bar_w, 1, c.map(colormap::to_u8));
    }
    let white = [235, 235, 235];
    let th = text::text_height(scale) as i32;
    let tw = text::text_width(title, scale) as i32;
    text::draw_text(img, (x1 - tw).max(0), y0 - th - 4 * s, title, scale, white);
    for (v, y) in [
        (hi, y0),
        (0.5 * (lo + hi), (y0 + y1) / 2 - th / 2),
        (lo, y1 - th),
    ] {
        let t = format_value(v);
        let tw = text::text_width(&t, scale) as i32;
        text::draw_text(img, (x0 - 4 * s - tw).max(0), y, &t, scale, white);
    }
}
