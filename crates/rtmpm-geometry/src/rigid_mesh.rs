//! Rigid bodies whose shape is a closed triangle mesh (`[[rigid_body]] shape = "mesh"`).
//!
//! The mesh is checked to be closed (every edge shared by exactly two faces, wound opposite
//! ways: a watertight, consistently oriented 2-manifold) and wound outward (positive enclosed
//! volume); its volume, centre of mass and inertia tensor are integrated exactly over the
//! enclosed solid (the signed tetrahedra from the origin to each face: Blow & Binstock, "How to
//! find the inertia tensor (or other mass properties) of a 3D solid body represented by a
//! triangle mesh", 2004; Tonon, "Explicit exact formulas for the 3-D tetrahedron inertia tensor
//! in terms of its vertex coordinates", J. Math. Stat. 2005). The body frame has its origin at
//! the centre of mass and the axes of the file (after `scale`); the coupling evaluates the
//! mesh's signed distance grid in that frame with the mesh colliders' own code
//! ([`MeshSdf`], `kernels/grid_update.cu: mesh_distance` on the GPU).

use crate::mesh::{MeshSdf, TriMesh};
use glam::{DMat3, DVec3, Mat3, Vec3};
use std::collections::HashMap;
use std::sync::Arc;

/// Most triangles a mesh body may have: the signed distance grid, the convex hull or the
/// triangle-mesh collider of rapier and the checks below all grow with the triangle count.
pub const MAX_BODY_TRIANGLES: usize = 200_000;

/// Why a mesh cannot be a rigid body; the message names the problem, [`MeshBodyError::fix`]
/// says how to repair the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshBodyError {
    #[error("the mesh has {count} triangles, more than the {max} a rigid body may have")]
    TooLarge { count: usize, max: usize },
    #[error(
        "the mesh is not closed: {open} edge(s) belong to one face only, e.g. the edge {a} .. {b}"
    )]
    Open { open: usize, a: String, b: String },
    #[error(
        "the mesh is not a manifold: the edge {a} .. {b} is shared by {faces} faces (or twice in \
         the same direction)"
    )]
    NonManifold { a: String, b: String, faces: usize },
    #[error(
        "the mesh encloses no volume: {volume:.3e} m^3, against {bounds:.3e} m^3 for its \
         bounding box (flat, degenerate, or a stray far vertex)"
    )]
    ZeroVolume { volume: f64, bounds: f64 },
    #[error(
        "the mesh's faces are wound inward (inverted normals): its enclosed volume is negative \
         ({volume:.3e} m^3)"
    )]
    Inverted { volume: f64 },
    #[error(
        "convex = true, but the mesh is not convex: at the edge {a} .. {b} the faces fold \
         inward by {depth:.3e} m"
    )]
    NotConvex { a: String, b: String, depth: f32 },
    #[error("convex = true, but the mesh is {parts} separate closed parts, not one convex solid")]
    Disconnected { parts: usize },
}

impl MeshBodyError {
    /// How to repair the mesh or the table.
    pub fn fix(&self) -> String {
        match self {
            MeshBodyError::TooLarge { max, .. } => format!(
                "decimate the mesh to at most {max} triangles (e.g. Blender's Decimate modifier); \
                 a body's coupling resolves details of half a cell only"
            ),
            MeshBodyError::Open { .. } | MeshBodyError::NonManifold { .. } => {
                "give a closed (watertight) mesh whose every edge joins exactly two faces, e.g. \
                 fill the holes and merge duplicate vertices (Blender: Mesh > Clean Up > Fill \
                 Holes, Merge by Distance); an open surface can be a collider, not a body"
                    .into()
            }
            MeshBodyError::ZeroVolume { .. } => {
                "give a mesh that encloses a solid (not a flat or degenerate surface, no vertex far \
                 from the others), or check `scale`"
                    .into()
            }
            MeshBodyError::Inverted { .. } => {
                "flip the faces' winding so that they are counter-clockwise seen from outside \
                 (Blender: Mesh > Normals > Recalculate Outside)"
                    .into()
            }
            MeshBodyError::NotConvex { .. } | MeshBodyError::Disconnected { .. } => {
                "remove convex = true: a closed non-convex mesh gets a triangle-mesh collider in \
                 the rigid-body engine (the coupling with the material uses the mesh itself \
                 either way)"
                    .into()
            }
        }
    }
}

/// A closed mesh as a rigid body's shape, in the body frame (origin at the centre of mass).
#[derive(Clone, Debug)]
pub struct RigidMesh {
    /// The mesh in the body frame, duplicate vertices merged.
    pub mesh: TriMesh,
    /// Its signed distance grid in the body frame (what the coupling evaluates).
    pub sdf: Arc<MeshSdf>,
    /// Enclosed volume (m^3).
    pub volume: f32,
    /// Inertia tensor about the centre of mass for a density of 1 kg/m^3 (body frame).
    pub unit_inertia: Mat3,
    /// The rigid-body engine collides the body as the mesh's convex hull (`convex = true`)
    /// instead of the triangle mesh.
    pub convex: bool,
    /// Half-extents of the box about the centre that holds the mesh (body frame), and the
    /// radius of the sphere about it.
    pub half_extents: Vec3,
    pub radius: f32,
}

impl PartialEq for RigidMesh {
    fn eq(&self, o: &RigidMesh) -> bool {
        self.mesh == o.mesh
            && self.volume == o.volume
            && self.convex == o.convex
            && self.sdf.spacing == o.sdf.spacing
            && self.sdf.dims == o.sdf.dims
    }
}

/// Volume, centre of mass and inertia tensor about the centre of mass (density 1) of the solid
/// a closed, outward-wound mesh encloses, in f64 (see the module docs).
pub fn mass_properties(mesh: &TriMesh) -> (f64, DVec3, DMat3) {
    let mut volume = 0.0;
    let mut first = DVec3::ZERO;
    // Second moments sum x x^T over the solid.
    let mut c = DMat3::ZERO;
    // About a point near the mesh (the first vertex) to limit cancellation far from the origin.
    let o = mesh
        .vertices
        .first()
        .copied()
        .unwrap_or(Vec3::ZERO)
        .as_dvec3();
    for t in &mesh.triangles {
        let [a, b, d] = t.map(|i| mesh.vertices[i as usize].as_dvec3() - o);
        let v = a.dot(b.cross(d)) / 6.0;
        volume += v;
        let s = a + b + d;
        first += v * s / 4.0;
        let outer = |x: DVec3| DMat3::from_cols(x * x.x, x * x.y, x * x.z);
        c += (outer(a) + outer(b) + outer(d) + outer(s)) * (v / 20.0);
    }
    if volume == 0.0 {
        return (0.0, o, DMat3::ZERO);
    }
    let com = first / volume;
    let shift = DMat3::from_cols(com * com.x, com * com.y, com * com.z) * volume;
    let c = c - shift;
    let trace = c.x_axis.x + c.y_axis.y + c.z_axis.z;
    (
        volume,
        com + o,
        DMat3::from_diagonal(DVec3::splat(trace)) - c,
    )
}

fn fmt_v(v: Vec3) -> String {
    format!("({:.4}, {:.4}, {:.4})", v.x, v.y, v.z)
}

/// `mesh` with vertices of identical coordinates merged (exporters often split vertices along
/// seams of normals or texture coordinates; the closedness check works on positions).
fn weld(mesh: &TriMesh) -> TriMesh {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut out = TriMesh::default();
    let mut map = Vec::with_capacity(mesh.vertices.len());
    for v in &mesh.vertices {
        let key = v.to_array().map(|x| (x + 0.0).to_bits());
        let id = *index.entry(key).or_insert_with(|| {
            out.vertices.push(*v);
            (out.vertices.len() - 1) as u32
        });
        map.push(id);
    }
    out.triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| map[i as usize]))
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    out
}

/// Every directed edge must appear once, and its reverse once.
fn check_closed(mesh: &TriMesh) -> Result<HashMap<(u32, u32), u32>, MeshBodyError> {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * mesh.triangles.len());
    let v = |i: u32| fmt_v(mesh.vertices[i as usize]);
    for (f, t) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let e = (t[k], t[(k + 1) % 3]);
            if edges.insert(e, f as u32).is_some() {
                let faces = mesh
                    .triangles
                    .iter()
                    .filter(|t| {
                        (0..3).any(|k| {
                            let d = (t[k], t[(k + 1) % 3]);
                            d == e || d == (e.1, e.0)
                        })
                    })
                    .count();
                return Err(MeshBodyError::NonManifold {
                    a: v(e.0),
                    b: v(e.1),
                    faces,
                });
            }
        }
    }
    let open: Vec<&(u32, u32)> = edges
        .keys()
        .filter(|(a, b)| !edges.contains_key(&(*b, *a)))
        .collect();
    if let Some(&&(a, b)) = open.iter().min() {
        return Err(MeshBodyError::Open {
            open: open.len(),
            a: v(a),
            b: v(b),
        });
    }
    Ok(edges)
}

/// Number of connected parts of the mesh (faces joined by shared vertices).
fn parts(mesh: &TriMesh) -> usize {
    let mut parent: Vec<u32> = (0..mesh.vertices.len() as u32).collect();
    fn root(p: &mut [u32], mut i: u32) -> u32 {
        while p[i as usize] != i {
            p[i as usize] = p[p[i as usize] as usize];
            i = p[i as usize];
        }
        i
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            parent[a as usize] = b;
        }
    }
    let mut used = vec![false; mesh.vertices.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    (0..mesh.vertices.len() as u32)
        .filter(|&i| used[i as usize] && root(&mut parent, i) == i)
        .count()
}

/// For `convex = true`: every edge must be convex (the far vertex of each face lies on or
/// behind the plane of its neighbour across the edge), within `1e-5` of the mesh's size. A
/// closed, connected surface that is convex at every edge bounds a convex solid.
fn check_convex(mesh: &TriMesh, edges: &HashMap<(u32, u32), u32>) -> Result<(), MeshBodyError> {
    let (lo, hi) = mesh.bounds();
    let tol = 1e-5 * (hi - lo).length();
    let p = |i: u32| mesh.vertices[i as usize];
    let mut worst: Option<((u32, u32), f32)> = None;
    for (&(a, b), &f) in edges {
        let Some(&g) = edges.get(&(b, a)) else {
            continue;
        };
        let t = mesh.triangles[f as usize];
        let n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
        let Some(n) = n.try_normalize() else {
            continue;
        };
        let far = mesh.triangles[g as usize]
            .into_iter()
            .find(|&i| i != a && i != b)
            .unwrap_or(a);
        let depth = (p(far) - p(a)).dot(n);
        if depth > tol && worst.is_none_or(|(_, d)| depth > d) {
            worst = Some(((a, b), depth));
        }
    }
    match worst {
        Some(((a, b), depth)) => Err(MeshBodyError::NotConvex {
            a: fmt_v(p(a)),
            b: fmt_v(p(b)),
            depth,
        }),
        None => Ok(()),
    }
}

impl RigidMesh {
    /// A body of the closed mesh `world` (as placed in the world at t = 0); its distance grid
    /// has `spacing` (m) and `margin` cells around the mesh. Returns the body and its centre of
    /// mass in the world.
    pub fn new(
        world: &TriMesh,
        convex: bool,
        spacing: f32,
        margin: u32,
    ) -> Result<(RigidMesh, Vec3), MeshBodyError> {
        if world.triangles.len() > MAX_BODY_TRIANGLES {
            return Err(MeshBodyError::TooLarge {
                count: world.triangles.len(),
                max: MAX_BODY_TRIANGLES,
            });
        }
        let mut mesh = weld(world);
        let edges = check_closed(&mesh)?;
        let (volume, com, inertia) = mass_properties(&mesh);
        let (lo, hi) = mesh.bounds();
        let extent = (hi - lo).as_dvec3();
        // Zero (flat, degenerate) against the bounding box, within rounding.
        let bounds = extent.x * extent.y * extent.z;
        if volume.abs() <= 1e-6 * bounds || !volume.is_finite() {
            return Err(MeshBodyError::ZeroVolume { volume, bounds });
        }
        if volume < 0.0 {
            return Err(MeshBodyError::Inverted { volume });
        }
        if convex {
            let parts = parts(&mesh);
            if parts > 1 {
                return Err(MeshBodyError::Disconnected { parts });
            }
            check_convex(&mesh, &edges)?;
        }
        let com = com.as_vec3();
        for v in &mut mesh.vertices {
            *v -= com;
        }
        let sdf = MeshSdf::build(&mesh, spacing, margin);
        let (lo, hi) = mesh.bounds();
        let half_extents = lo.abs().max(hi.abs());
        let radius = mesh
            .vertices
            .iter()
            .map(|v| v.length())
            .fold(0.0f32, f32::max);
        Ok((
            RigidMesh {
                mesh,
                sdf: Arc::new(sdf),
                volume: volume as f32,
                unit_inertia: inertia.as_mat3(),
                convex,
                half_extents,
                radius,
            },
            com,
        ))
    }

    /// Half-extents of the axis-aligned box about the centre that holds the mesh turned by `r`
    /// (exact: the extreme vertices).
    pub fn world_half_extents(&self, r: Mat3) -> Vec3 {
        self.mesh
            .vertices
            .iter()
            .fold(Vec3::ZERO, |h, v| h.max((r * *v).abs()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box `[0, a] x [0, b] x [0, c]` as 12 outward triangles.
    pub(crate) fn box_mesh(size: Vec3, at: Vec3) -> TriMesh {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
        TriMesh::parse_obj(text.as_bytes(), "box", size, at).expect("box")
    }

    #[test]
    fn a_box_mesh_has_the_box_s_volume_centre_and_inertia() {
        let size = Vec3::new(0.12, 0.1, 0.3);
        let at = Vec3::new(1.0, 2.0, -3.0);
        let (v, com, i) = mass_properties(&box_mesh(size, at));
        // f32 vertices 1 to 3 m from the origin hold the 0.1 m sizes to a few 1e-7 m each:
        // 1e-5 relative.
        let s = size.as_dvec3();
        assert!((v / (s.x * s.y * s.z) - 1.0).abs() < 1e-5, "{v}");
        assert!(
            (com - (at + 0.5 * size).as_dvec3()).length() < 1e-6,
            "{com}"
        );
        // Solid box, density 1: I_xx = V (b^2 + c^2) / 12.
        let expect = DVec3::new(
            s.y * s.y + s.z * s.z,
            s.x * s.x + s.z * s.z,
            s.x * s.x + s.y * s.y,
        ) * (v / 12.0);
        for (a, e) in [
            (i.x_axis.x, expect.x),
            (i.y_axis.y, expect.y),
            (i.z_axis.z, expect.z),
        ] {
            assert!((a / e - 1.0).abs() < 1e-5, "{a} vs {e}");
        }
        let off = i.x_axis.y.abs().max(i.x_axis.z.abs()).max(i.y_axis.z.abs());
        assert!(off < 1e-5 * expect.x, "off-diagonal {off}");
    }

    /// The corner tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1), density 1: volume 1/6, centre
    /// of mass (1/4, 1/4, 1/4), and about it I_xx = 1/30 - (1/6)(1/16 + 1/16) = 1/80 and
    /// I_xy = -(1/120 - (1/6)(1/16)) = 1/480 (integrals of x^2 and x y over it: 1/60, 1/120).
    #[test]
    fn a_tetrahedron_has_its_analytic_centre_and_inertia_with_products() {
        let t = TriMesh {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        };
        let (v, com, i) = mass_properties(&t);
        assert!((v - 1.0 / 6.0).abs() < 1e-12, "{v}");
        assert!((com - DVec3::splat(0.25)).length() < 1e-12, "{com}");
        for k in 0..3 {
            assert!((i.col(k)[k] - 1.0 / 80.0).abs() < 1e-12, "{i}");
            assert!((i.col(k)[(k + 1) % 3] - 1.0 / 480.0).abs() < 1e-12, "{i}");
        }
        let (b, c) = RigidMesh::new(&t, true, 0.05, 3).expect("a convex body");
        assert!((c - Vec3::splat(0.25)).length() < 1e-6);
        assert!((b.radius - Vec3::new(0.75, -0.25, -0.25).length()).abs() < 1e-6);
    }

    #[test]
    fn a_box_body_is_centred_and_convex() {
        let (b, com) = RigidMesh::new(
            &box_mesh(Vec3::new(0.2, 0.1, 0.4), Vec3::ONE),
            true,
            0.01,
            3,
        )
        .expect("body");
        assert!((com - Vec3::new(1.1, 1.05, 1.2)).length() < 1e-5);
        assert!((b.half_extents - Vec3::new(0.1, 0.05, 0.2)).length() < 1e-5);
        assert!(b.sdf.distance(Vec3::ZERO) < -0.049);
        assert!(b.sdf.distance(Vec3::new(0.0, 0.06, 0.0)) > 0.0);
        let turned = b.world_half_extents(Mat3::from_rotation_z(std::f32::consts::FRAC_PI_2));
        assert!(
            (turned - Vec3::new(0.05, 0.1, 0.2)).length() < 1e-5,
            "{turned}"
        );
    }

    #[test]
    fn open_inverted_flat_nonconvex_and_huge_meshes_are_refused() {
        let good = box_mesh(Vec3::ONE, Vec3::ZERO);
        // Open: one face removed.
        let mut open = good.clone();
        open.triangles.truncate(10);
        assert!(matches!(
            RigidMesh::new(&open, false, 0.1, 3),
            Err(MeshBodyError::Open { .. })
        ));
        // Inverted: every face flipped.
        let mut inv = good.clone();
        for t in &mut inv.triangles {
            t.swap(1, 2);
        }
        let e = RigidMesh::new(&inv, false, 0.1, 3).unwrap_err();
        assert!(matches!(e, MeshBodyError::Inverted { .. }), "{e}");
        // One face flipped: the edges it shares run the same way twice.
        let mut one = good.clone();
        one.triangles[0].swap(1, 2);
        let e = RigidMesh::new(&one, false, 0.1, 3).unwrap_err();
        assert!(matches!(e, MeshBodyError::NonManifold { .. }), "{e}");
        // Flat: one triangle, both sides (closed, no volume).
        let flat = TriMesh {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2], [0, 2, 1]],
        };
        let e = RigidMesh::new(&flat, false, 0.1, 3).unwrap_err();
        assert!(matches!(e, MeshBodyError::ZeroVolume { .. }), "{e}");
        // Not convex: the top face's centre pushed down (a dented top, 4 triangles).
        let mut dent = good.clone();
        dent.vertices.push(Vec3::new(0.5, 0.6, 0.5));
        let top: Vec<usize> = (0..dent.triangles.len())
            .filter(|&f| {
                dent.triangles[f]
                    .iter()
                    .all(|&i| dent.vertices[i as usize].y == 1.0)
            })
            .collect();
        assert_eq!(top.len(), 2);
        // (0,1,0) (1,1,0) (1,1,1) (0,1,1): clockwise seen from +y, so the fan below is outward.
        let ring = [
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ]
        .map(|p| {
            dent.vertices
                .iter()
                .position(|v| *v == Vec3::from_array(p))
                .expect("a corner") as u32
        });
        let mut tris: Vec<[u32; 3]> = dent
            .triangles
            .iter()
            .enumerate()
            .filter(|(f, _)| !top.contains(f))
            .map(|(_, t)| *t)
            .collect();
        for k in 0..4 {
            tris.push([ring[k], 8, ring[(k + 1) % 4]]);
        }
        dent.triangles = tris;
        eprintln!("{:?}", dent.triangles);
        // Closed and outward either way; only convex = true refuses it.
        let (ok, _) = RigidMesh::new(&dent, false, 0.1, 3).expect("closed non-convex mesh");
        assert!(ok.volume < 1.0 && ok.volume > 0.8, "{}", ok.volume);
        let e = RigidMesh::new(&dent, true, 0.1, 3).unwrap_err();
        assert!(matches!(e, MeshBodyError::NotConvex { .. }), "{e}");
        // Two separate cubes: closed, but not one convex solid.
        let mut two = good.clone();
        let n = two.vertices.len() as u32;
        two.vertices
            .extend(good.vertices.iter().map(|v| *v + Vec3::new(3.0, 0.0, 0.0)));
        two.triangles
            .extend(good.triangles.iter().map(|t| t.map(|i| i + n)));
        let (pair, _) = RigidMesh::new(&two, false, 0.1, 3).expect("two cubes, not convex");
        assert!((pair.volume - 2.0).abs() < 1e-5, "{}", pair.volume);
        let e = RigidMesh::new(&two, true, 0.1, 3).unwrap_err();
        assert_eq!(e, MeshBodyError::Disconnected { parts: 2 });
        // Too many triangles.
        let mut big = good.clone();
        big.triangles = vec![[0, 1, 2]; MAX_BODY_TRIANGLES + 1];
        let e = RigidMesh::new(&big, false, 0.1, 3).unwrap_err();
        assert!(matches!(e, MeshBodyError::TooLarge { .. }), "{e}");
    }
}
