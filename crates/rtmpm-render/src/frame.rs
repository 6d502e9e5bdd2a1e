//! One frame on the CPU: the particles projected and splatted into the G-buffer with the
//! colliders and surfaces, the shadow map, every pixel shaded (Lambert light, shadow, depth
//! darkening, rim light, specular surfaces, a checkered floor that fades into the sky), then
//! the colour bar and the label.

use crate::camera::View;
use crate::colliders::{self, COLLIDER_COLOR, COLLIDER_ID, PosedCollider};
use crate::colorbar::draw_color_bar;
use crate::colormap;
use crate::gbuffer::GTexel;
use crate::image::Image;
use crate::input::{RenderError, RenderInput, RenderOptions, field_range};
use crate::mesh;
use crate::raster::{Splat, raster};
use crate::shadow::{LIGHT, ShadowMap};
use crate::text;
use rayon::prelude::*;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::ColorBy;

/// Render one frame.
pub fn render(input: &RenderInput, opts: &RenderOptions) -> Result<Image, RenderError> {
    let field = checked_field(input, opts)?;
    let (w, h) = (opts.width as usize, opts.height as usize);
    let view = opts.camera.view(opts.width, opts.height);
    let near = 1e-4_f32.max(opts.radius);
    let mut gbuf = splat_particles(input, &view, near, opts.radius, w, h);
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
    let (lo, hi) = match field {
        Some(f) => opts.range.unwrap_or_else(|| field_range(f)),
        None => (0.0, 1.0),
    };
    let colours = Colours {
        field,
        lo,
        inv_range: if hi > lo { 1.0 / (hi - lo) } else { 0.0 },
        palette: if opts.palette.is_empty() {
            &colormap::PALETTE
        } else {
            &opts.palette
        },
        material: input.material,
    };
    let shading = Shading::new(view, shadow.as_ref(), opts);
    let mut img = Image::new(opts.width, opts.height, [0, 0, 0]);
    shading.shade(&gbuf, &colours, &mut img);

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

/// The field coloured by (`None` for material colours), after checking the input's lengths
/// and the options' size, camera and radius.
fn checked_field<'a>(
    input: &RenderInput<'a>,
    opts: &RenderOptions,
) -> Result<Option<&'a [f32]>, RenderError> {
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
    Ok(field)
}

/// The G-buffer of the particles alone: each projected as a sphere of radius `wr` (m) and
/// splatted, the nearest surface point kept per pixel.
fn splat_particles(
    input: &RenderInput,
    view: &View,
    near: f32,
    wr: f32,
    w: usize,
    h: usize,
) -> Vec<GTexel> {
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
    gbuf
}

/// The base colour of what a G-buffer texel holds: a collider, a surface of a material, or a
/// particle by its material or its field value.
struct Colours<'a> {
    field: Option<&'a [f32]>,
    lo: f32,
    inv_range: f32,
    palette: &'a [[f32; 3]],
    material: &'a [u32],
}

impl Colours<'_> {
    fn base(&self, id: u32) -> Vec3 {
        let palette = self.palette;
        if id == COLLIDER_ID {
            return Vec3::from(COLLIDER_COLOR);
        }
        if let Some(m) = mesh::mesh_material(id) {
            return Vec3::from(palette[m as usize % palette.len()]);
        }
        let c = match self.field {
            Some(f) => colormap::viridis((f[id as usize] - self.lo) * self.inv_range),
            None => palette[self.material[id as usize] as usize % palette.len()],
        };
        Vec3::from(c)
    }
}

/// What the shading of every pixel shares: the view, the light and its shadow map, the
/// particle radius, the floor and the scene's box.
struct Shading<'a> {
    view: View,
    light: Vec3,
    shadow: Option<&'a ShadowMap>,
    wr: f32,
    floor: Option<f32>,
    bounds: (Vec3, Vec3),
    bcenter: Vec3,
    bsize: f32,
    checker: f32,
    ao_offsets: [(i64, i64); 8],
}

impl<'a> Shading<'a> {
    fn new(view: View, shadow: Option<&'a ShadowMap>, opts: &RenderOptions) -> Shading<'a> {
        let (blo, bhi) = opts.bounds;
        let bsize = (bhi - blo).max_element().max(1e-6);
        let ao_r = (opts.height as i64 / 140).max(2);
        Shading {
            view,
            light: LIGHT.normalize(),
            shadow,
            wr: opts.radius,
            floor: opts.floor,
            bounds: opts.bounds,
            bcenter: 0.5 * (blo + bhi),
            bsize,
            checker: bsize / 12.0,
            ao_offsets: [
                (ao_r, 0),
                (-ao_r, 0),
                (0, ao_r),
                (0, -ao_r),
                (ao_r * 7 / 10, ao_r * 7 / 10),
                (-ao_r * 7 / 10, ao_r * 7 / 10),
                (ao_r * 7 / 10, -ao_r * 7 / 10),
                (-ao_r * 7 / 10, -ao_r * 7 / 10),
            ],
        }
    }

    /// Every pixel of `img` from the G-buffer, rows in parallel.
    fn shade(&self, gbuf: &[GTexel], colours: &Colours, img: &mut Image) {
        let (w, h) = (img.width as usize, img.height as usize);
        img.rgb
            .par_chunks_mut(3 * w)
            .enumerate()
            .for_each(|(y, row)| {
                let sky_t = y as f32 / h as f32;
                let sky = Vec3::new(0.15, 0.17, 0.21) * (1.0 - sky_t)
                    + Vec3::new(0.36, 0.38, 0.43) * sky_t;
                for x in 0..w {
                    let view = &self.view;
                    let ray = view.ray(x as f32 + 0.5, y as f32 + 0.5);
                    let ground_t = match self.floor {
                        Some(f) if ray.y < 0.0 && view.pos.y > f => (f - view.pos.y) / ray.y,
                        _ => f32::INFINITY,
                    };
                    let g = gbuf[y * w + x];
                    let c = if g.depth < ground_t {
                        let occ = self.occlusion(gbuf, w, h, x, y, g.depth);
                        self.surface(g, ray, occ, colours.base(g.id))
                    } else if ground_t.is_finite() {
                        self.ground(view.pos + ray * ground_t, sky)
                    } else {
                        sky
                    };
                    row[3 * x] = colormap::to_u8(c.x);
                    row[3 * x + 1] = colormap::to_u8(c.y);
                    row[3 * x + 2] = colormap::to_u8(c.z);
                }
            });
    }

    /// Depth darkening: how many of eight neighbours of pixel `(x, y)` are clearly in front.
    fn occlusion(
        &self,
        gbuf: &[GTexel],
        w: usize,
        h: usize,
        x: usize,
        y: usize,
        depth: f32,
    ) -> f32 {
        let wr = self.wr;
        let mut occ = 0.0;
        for (ox, oy) in self.ao_offsets {
            let (sx, sy) = (x as i64 + ox, y as i64 + oy);
            if sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h {
                let d = depth - gbuf[sy as usize * w + sx as usize].depth;
                if d > 0.5 * wr && d < 12.0 * wr {
                    occ += 1.0;
                }
            }
        }
        occ
    }

    /// A particle, collider or surface seen along `ray`: its colour `base` lit by the light
    /// and its shadow, darkened by `occ` occluding neighbours, with a rim light on particles
    /// and a specular highlight on surfaces.
    fn surface(&self, g: GTexel, ray: Vec3, occ: f32, base: Vec3) -> Vec3 {
        let (view, light, wr) = (&self.view, self.light, self.wr);
        let nz = (1.0 - g.u * g.u - g.v * g.v).max(0.0).sqrt();
        let normal = view.right * g.u - view.up * g.v - view.fwd * nz;
        let p = view.pos + ray * g.depth;
        let lambert = normal.dot(light).max(0.0);
        let lit = self
            .shadow
            .map_or(1.0, |s| s.light(p + normal * (0.5 * wr), 2.0 * wr));
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
        base * (0.32 * ao + 0.68 * lambert * (0.5 + 0.5 * lit)) + Vec3::splat(rim * ao + spec)
    }

    /// The floor at `p`: checkers inside the scene's box, lit and shadowed, fading into `sky`
    /// far from the scene.
    fn ground(&self, p: Vec3, sky: Vec3) -> Vec3 {
        let (blo, bhi) = self.bounds;
        let inside = p.x >= blo.x && p.x <= bhi.x && p.z >= blo.z && p.z <= bhi.z;
        let albedo = if inside {
            let k = (p.x / self.checker).floor() as i64 + (p.z / self.checker).floor() as i64;
            if k & 1 == 0 { 0.80 } else { 0.70 }
        } else {
            0.55
        };
        let lit = self.shadow.map_or(1.0, |s| s.light(p, 0.5 * self.wr));
        let c = Vec3::splat(albedo * (0.35 + 0.65 * self.light.y * (0.3 + 0.7 * lit)));
        let dist = ((p - self.bcenter) * Vec3::new(1.0, 0.0, 1.0)).length() / self.bsize;
        let fade = (-(dist - 0.6).max(0.0) * 1.2).exp();
        c * fade + sky * (1.0 - fade)
    }
}
