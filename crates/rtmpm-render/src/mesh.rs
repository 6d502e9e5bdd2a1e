//! Triangle meshes in the picture (fluid surfaces): triangles rasterised with a depth test into
//! the same G-buffer as the particle splats and the colliders, with perspective-correct
//! interpolation of the vertex normals, and into the light's shadow map, so surfaces hide,
//! shade and shadow exactly as everything else does. Parallel over bands of rows like
//! [`super::raster`].

use crate::camera::View;
use crate::gbuffer::GTexel;
use crate::shadow::{SHADOW_RES, ShadowMap};
use rayon::prelude::*;
use rtmpm_geometry::surface::TriMesh;
use rtmpm_physics::math::Vec3;

/// G-buffer ids of mesh texels: `MESH_ID_BASE - material` (just below the colliders' id).
pub(crate) const MESH_ID_BASE: u32 = u32::MAX - 1;
/// Ids from `MESH_ID_LIMIT` up to `MESH_ID_BASE` are mesh texels.
pub(crate) const MESH_ID_LIMIT: u32 = MESH_ID_BASE - 1023;

/// The material of a mesh texel's id, or `None` for a particle or collider id.
pub(crate) fn mesh_material(id: u32) -> Option<u32> {
    (MESH_ID_LIMIT..=MESH_ID_BASE)
        .contains(&id)
        .then(|| MESH_ID_BASE - id)
}

/// A vertex after projection: pixel x, y and the reciprocal of its depth.
#[derive(Clone, Copy)]
struct Proj {
    x: f32,
    y: f32,
    iz: f32,
}

/// Rows per band.
const BAND: usize = 8;

/// Rasterise the triangles `tris` (indices into `proj`) into `buf` (`w` x `h`). For each
/// covered pixel centre `write(texel, triangle, [b0, b1, b2])` gets the screen-space
/// barycentric coordinates.
fn raster_tris<T: Send>(
    proj: &[Proj],
    tris: &[[u32; 3]],
    w: usize,
    h: usize,
    buf: &mut [T],
    write: impl Fn(&mut T, usize, [f32; 3]) + Sync,
) {
    if w == 0 || h == 0 || tris.is_empty() {
        return;
    }
    let n_bands = h.div_ceil(BAND);
    let bbox = |t: &[u32; 3]| -> Option<(f32, f32, f32, f32)> {
        let [a, b, c] = t.map(|i| proj[i as usize]);
        if !(a.iz > 0.0 && b.iz > 0.0 && c.iz > 0.0) {
            return None; // Behind the near plane (or not projected).
        }
        let x0 = a.x.min(b.x).min(c.x).max(0.0);
        let x1 = a.x.max(b.x).max(c.x).min(w as f32 - 1.0);
        let y0 = a.y.min(b.y).min(c.y).max(0.0);
        let y1 = a.y.max(b.y).max(c.y).min(h as f32 - 1.0);
        (x0 <= x1 && y0 <= y1 && x1.is_finite() && y1.is_finite()).then_some((x0, x1, y0, y1))
    };
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n_bands];
    for (k, t) in tris.iter().enumerate() {
        if let Some((_, _, y0, y1)) = bbox(t) {
            for l in &mut lists[y0 as usize / BAND..=(y1 as usize / BAND).min(n_bands - 1)] {
                l.push(k as u32);
            }
        }
    }
    buf.par_chunks_mut(BAND * w)
        .zip(lists.par_iter())
        .enumerate()
        .for_each(|(band, (rows, list))| {
            let row0 = band * BAND;
            let n_rows = rows.len() / w;
            for &k in list {
                let t = &tris[k as usize];
                let Some((x0, x1, y0, y1)) = bbox(t) else {
                    continue;
                };
                let [a, b, c] = t.map(|i| proj[i as usize]);
                let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
                if area.abs() < 1e-12 {
                    continue;
                }
                let inv = 1.0 / area;
                let ya = (y0.floor() as usize).max(row0);
                let yb = (y1.ceil() as usize).min(row0 + n_rows - 1);
                for y in ya..=yb {
                    let py = y as f32 + 0.5;
                    for x in x0.floor() as usize..=(x1.ceil() as usize).min(w - 1) {
                        let px = x as f32 + 0.5;
                        let w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) * inv;
                        let w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) * inv;
                        let w2 = 1.0 - w0 - w1;
                        if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
                            write(&mut rows[(y - row0) * w + x], k as usize, [w0, w1, w2]);
                        }
                    }
                }
            }
        });
}

/// Draw `mesh` (material `material`) into the G-buffer `gbuf` seen through `view`.
pub(crate) fn draw(
    mesh: &TriMesh,
    material: u32,
    view: &View,
    near: f32,
    w: usize,
    h: usize,
    gbuf: &mut [GTexel],
) {
    let proj: Vec<Proj> = mesh
        .vertices
        .par_iter()
        .map(|p| {
            let (x, y, z) = view.project(*p);
            Proj {
                x,
                y,
                iz: if z > near { 1.0 / z } else { -1.0 },
            }
        })
        .collect();
    let id = MESH_ID_BASE - material.min(MESH_ID_BASE - MESH_ID_LIMIT);
    let normal_at = |k: usize, b: [f32; 3], iz: f32| -> Vec3 {
        let t = mesh.triangles[k];
        if mesh.normals.is_empty() {
            let [a, bb, c] = t.map(|i| mesh.vertices[i as usize]);
            return (bb - a).cross(c - a).normalize_or(Vec3::Y);
        }
        let mut n = Vec3::ZERO;
        for j in 0..3 {
            let v = t[j] as usize;
            n += mesh.normals[v] * (b[j] * proj[v].iz);
        }
        (n / iz).normalize_or(Vec3::Y)
    };
    raster_tris(&proj, &mesh.triangles, w, h, gbuf, |texel, k, b| {
        let t = mesh.triangles[k];
        let iz = b[0] * proj[t[0] as usize].iz
            + b[1] * proj[t[1] as usize].iz
            + b[2] * proj[t[2] as usize].iz;
        let depth = 1.0 / iz;
        if depth < texel.depth {
            let n = normal_at(k, b, iz);
            // The G-buffer stores normals as in the sphere splats: (u, v) on the screen, the
            // component towards the camera implied. A normal facing away keeps its direction
            // on the screen at the silhouette.
            let (mut u, mut v) = (n.dot(view.right), -n.dot(view.up));
            let r2 = u * u + v * v;
            if r2 > 1.0 || n.dot(view.fwd) > 0.0 {
                let s = 1.0 / r2.sqrt().max(1e-6);
                u *= s;
                v *= s;
            }
            *texel = GTexel { depth, u, v, id };
        }
    });
}

/// Add `mesh` to the light's depth map.
pub(crate) fn cast_shadows(mesh: &TriMesh, map: &mut ShadowMap) {
    let proj: Vec<Proj> = mesh
        .vertices
        .par_iter()
        .map(|p| {
            let d = *p - map.origin;
            // Orthographic: depth is linear on the map; store it directly as `iz`.
            Proj {
                x: d.dot(map.right) * map.scale,
                y: -d.dot(map.up) * map.scale,
                iz: d.dot(map.fwd).max(1e-9),
            }
        })
        .collect();
    raster_tris(
        &proj,
        &mesh.triangles,
        SHADOW_RES,
        SHADOW_RES,
        &mut map.depth,
        |t, k, b| {
            let tri = mesh.triangles[k];
            let z: f32 = (0..3).map(|j| b[j] * proj[tri[j] as usize].iz).sum();
            if z < *t {
                *t = z;
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use super::{MESH_ID_BASE, mesh_material};
    use crate::tests::support::*;
    use crate::*;
    use rtmpm_geometry::surface::TriMesh;
    use rtmpm_physics::math::Vec3;

    /// A UV sphere of radius `r` at `c`, outward triangles, exact normals.
    pub(crate) fn sphere(c: Vec3, r: f32, n: u32) -> TriMesh {
        let mut m = TriMesh::default();
        for i in 0..=n {
            let th = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..2 * n {
                let ph = std::f32::consts::PI * j as f32 / n as f32;
                let d = Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin());
                m.vertices.push(c + d * r);
                m.normals.push(d);
            }
        }
        let idx = |i: u32, j: u32| i * 2 * n + j % (2 * n);
        for i in 0..n {
            for j in 0..2 * n {
                let (a, b, c2, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
                m.triangles.push([a, d, b]);
                m.triangles.push([b, d, c2]);
            }
        }
        m
    }

    #[test]
    fn sphere_mesh_is_drawn_shaded_hidden_and_shadowing() {
        let m = sphere(Vec3::ZERO, 0.5, 24);
        assert!(m.volume() > 0.0, "outward triangles");
        let far = [Vec3::new(0.6, 0.0, -0.9)]; // Behind the sphere's right edge.
        let near = [Vec3::new(-0.15, 0.1, 0.9)]; // In front of its centre.
        let mut o = opts(160, 120);
        o.radius = 0.05;
        o.palette = vec![[0.2, 0.4, 0.9], [0.9, 0.1, 0.1]];
        o.floor = Some(-0.6);
        let render_with = |pos: &[Vec3], surface: bool| {
            render(
                &RenderInput {
                    positions: pos,
                    material: &vec![1; pos.len()],
                    field: None,
                    surface: surface.then_some((&m, 0)),
                },
                &o,
            )
            .unwrap()
        };
        let img = render_with(&far, true);
        dump(&img, "mesh_sphere");
        // The centre is the surface's blue, lit (not the sky); the sphere covers about
        // pi (0.5 * f / 3)^2 pixels.
        let c = img.pixel(80, 60);
        assert_eq!(dominant(c), Some(2), "{c:?}");
        let blue = img
            .rgb
            .chunks(3)
            .filter(|p| dominant([p[0], p[1], p[2]]) == Some(2))
            .count();
        let f = 60.0 / (20.0f32.to_radians()).tan();
        let disc = std::f32::consts::PI * (0.5 * f / 3.0).powi(2);
        assert!(
            (blue as f32 / disc - 1.0).abs() < 0.25,
            "{blue} blue pixels vs {disc}"
        );
        // The particle behind is hidden, the one in front is drawn (red) over the surface.
        assert_eq!(count_close(&img, [230, 25, 25], 60), 0);
        let img2 = render_with(&near, true);
        assert_eq!(
            dominant(img2.pixel(68, 52)),
            Some(0),
            "{:?}",
            img2.pixel(68, 52)
        );
        // Shading varies over the surface (lit side brighter) and it shadows the ground.
        let (left, right) = (img.pixel(62, 50), img.pixel(98, 70));
        assert!(left[2] as i32 - right[2] as i32 > 20, "{left:?} {right:?}");
        let no_mesh = render_with(&far, false);
        dump(&no_mesh, "mesh_sphere_none");
        let diff = img
            .rgb
            .chunks(3)
            .zip(no_mesh.rgb.chunks(3))
            .enumerate()
            .filter(|(k, (a, b))| {
                let y = k / 160;
                y > 84
                    && a.iter()
                        .zip(b.iter())
                        .map(|(x, y)| *x as i32 - *y as i32)
                        .sum::<i32>()
                        < -30
            })
            .count();
        assert!(diff > 20, "the sphere darkens {diff} ground pixels");
    }

    #[test]
    fn bad_mesh_is_an_error() {
        let mut m = sphere(Vec3::ZERO, 0.5, 4);
        m.triangles.push([0, 1, 100_000]);
        let r = render(
            &RenderInput {
                positions: &[],
                material: &[],
                field: None,
                surface: Some((&m, 0)),
            },
            &opts(32, 32),
        );
        assert!(r.is_err());
        assert_eq!(mesh_material(MESH_ID_BASE - 3), Some(3));
        assert_eq!(mesh_material(5), None);
        assert_eq!(mesh_material(u32::MAX), None);
    }
}
