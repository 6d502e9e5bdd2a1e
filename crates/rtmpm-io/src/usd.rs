//! Pixar's Universal Scene Description, text form (`.usda`), one file per frame: the
//! particles as a `Points` prim and the fluid surface as a `Mesh` prim, Y up, metres.
//!
//! `frame_NNNNN.usda` holds `/particles` (`UsdGeomPoints`): `points`, `velocities`, `ids`,
//! `widths` (the diameter of the particle's initial volume cube) and the primvars (vertex
//! interpolation) `material` (int), `plastic`, `mass`, and when asked `J` and `stress`
//! (`matrix3d`, the Cauchy stress, Pa). `surface_NNNNN.usda` holds `/surface` (`UsdGeomMesh`):
//! `points`, `faceVertexCounts`, `faceVertexIndices` and vertex `normals`. Both open in
//! usdview, Houdini's Solaris, Blender's USD importer and Omniverse.
//!
//! A scene's rigid bodies (`[[rigid_body]]`) go into the frame file too, under `/bodies`: one
//! `Xform` per body, named after it, posed by `xformOp:translate` (its centre of mass) and
//! `xformOp:orient` (body to world), holding its shape in the body frame: a `Cube` scaled to the
//! box, a `Sphere`, a `Cylinder` (axis y) or the `Mesh` of a mesh body.

use std::io::{self, Write};
use std::path::Path;

use super::atomic::write_atomic_with;
use crate::fields::FrameFields;
use crate::frame::{FrameBytes, FrameFormat};
use glam::Vec3;
use rtmpm_geometry::shape::{UsdPrim, usd_number as num};
use rtmpm_geometry::surface::TriMesh;
use rtmpm_physics::Particles;

/// Write `name = [v0, v1, ...]` with `f(i)` giving item `i`'s text, 8 items a line.
fn array(
    w: &mut dyn Write,
    decl: &str,
    n: usize,
    f: impl Fn(usize) -> String,
    meta: &str,
) -> io::Result<()> {
    write!(w, "        {decl} = [")?;
    for i in 0..n {
        if i > 0 {
            w.write_all(if i % 8 == 0 {
                b",\n            "
            } else {
                b", "
            })?;
        }
        w.write_all(f(i).as_bytes())?;
    }
    writeln!(w, "]{meta}")
}

fn header(w: &mut dyn Write, prim: &str) -> io::Result<()> {
    writeln!(w, "#usda 1.0")?;
    writeln!(w, "(")?;
    writeln!(w, "    doc = \"{}\"", super::signature::USD_DOC)?;
    writeln!(w, "    defaultPrim = \"{prim}\"")?;
    writeln!(w, "    metersPerUnit = 1")?;
    writeln!(w, "    upAxis = \"Y\"")?;
    writeln!(w, ")")?;
    writeln!(w)
}

const VERTEX: &str = " (\n            interpolation = \"vertex\"\n        )";

/// A rigid body of a frame file (see [`FrameBody`]).
pub use crate::frame::FrameBody as UsdBody;

/// USD frames (`frame_NNNNN.usda`): the particles and the scene's rigid bodies; whole frames.
pub static FORMAT: FrameFormat = FrameFormat {
    name: "usda",
    extension: "usda",
    about: "USD text: particles and rigid bodies (usdview, Houdini Solaris, Blender, Omniverse)",
    bytes: FrameBytes {
        base: 140,
        jacobian: 14,
        stress: 140,
    },
    write: |path, f| write_usda_frame(path, f.particles, &f.fields, f.bodies),
    pvd: false,
    chunks: None,
};

/// Write the particles as `/particles` (see the module documentation), atomically.
pub fn write_usda_points(path: &Path, p: &Particles, fields: &FrameFields) -> io::Result<()> {
    write_usda_frame(path, p, fields, &[])
}

/// A USD prim name from `name`: letters, digits and `_`, not starting with a digit (others
/// become `_`); `fallback` when that leaves nothing or a name already in `used`.
fn prim_name(name: &str, fallback: String, used: &mut Vec<String>) -> String {
    let mut n: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if n.starts_with(|c: char| c.is_ascii_digit()) {
        n.insert(0, '_');
    }
    if n.is_empty() || used.contains(&n) {
        n = fallback;
    }
    used.push(n.clone());
    n
}

/// `/bodies`: an `Xform` per rigid body holding its shape (see the module documentation).
fn write_bodies(w: &mut dyn Write, bodies: &[UsdBody]) -> io::Result<()> {
    let v3 = |v: Vec3| format!("({}, {}, {})", num(v.x), num(v.y), num(v.z));
    writeln!(w, "\ndef Xform \"bodies\"\n{{")?;
    let mut used = Vec::new();
    for (i, b) in bodies.iter().enumerate() {
        let name = prim_name(b.name, format!("body_{i}"), &mut used);
        let q = b.rotation;
        writeln!(w, "    def Xform \"{name}\"\n    {{")?;
        writeln!(w, "        double3 xformOp:translate = {}", v3(b.position))?;
        writeln!(
            w,
            "        quatf xformOp:orient = ({}, {}, {}, {})",
            num(q.w),
            num(q.x),
            num(q.y),
            num(q.z)
        )?;
        writeln!(
            w,
            "        uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:orient\"]"
        )?;
        match b.shape.usd() {
            Some(UsdPrim::Schema { schema, attributes }) => {
                writeln!(w, "        def {schema} \"shape\"\n        {{")?;
                for a in attributes {
                    writeln!(w, "            {a}")?;
                }
            }
            Some(UsdPrim::Mesh(m)) => {
                writeln!(w, "        def Mesh \"shape\"\n        {{")?;
                mesh_triangles(w, &m.vertices, &m.triangles)?;
            }
            // A shape without a primitive: the body's pose alone.
            None => writeln!(w, "        def Xform \"shape\"\n        {{")?,
        }
        writeln!(w, "        }}\n    }}")?;
    }
    writeln!(w, "}}")
}

/// Write the particles as `/particles` and the rigid bodies `bodies` under `/bodies` (see the
/// module documentation), atomically.
pub fn write_usda_frame(
    path: &Path,
    p: &Particles,
    fields: &FrameFields,
    bodies: &[UsdBody],
) -> io::Result<()> {
    crate::contents::check_particles(p)?;
    let n = p.len();
    fields.check_len(n)?;
    let v3 = |v: rtmpm_physics::math::Vec3| format!("({}, {}, {})", num(v.x), num(v.y), num(v.z));
    write_atomic_with(path, |w| {
        header(w, "particles")?;
        writeln!(w, "def Points \"particles\"\n{{")?;
        array(w, "point3f[] points", n, |i| v3(p.x[i]), "")?;
        array(w, "vector3f[] velocities", n, |i| v3(p.v[i]), "")?;
        array(w, "int64[] ids", n, |i| i.to_string(), "")?;
        array(
            w,
            "float[] widths",
            n,
            |i| num(p.vol0[i].max(0.0).cbrt()),
            VERTEX,
        )?;
        array(
            w,
            "int[] primvars:material",
            n,
            |i| p.material[i].to_string(),
            VERTEX,
        )?;
        array(
            w,
            "float[] primvars:plastic",
            n,
            |i| num(p.plastic[i]),
            VERTEX,
        )?;
        array(w, "float[] primvars:mass", n, |i| num(p.mass[i]), VERTEX)?;
        if let Some(j) = fields.jacobian {
            array(w, "float[] primvars:J", n, |i| num(j[i]), VERTEX)?;
        }
        if let Some(s) = fields.stress {
            array(
                w,
                "matrix3d[] primvars:stress",
                n,
                |i| {
                    let m = super::bgeo::symmetric_to_full(s[i]).map(num);
                    format!(
                        "(({}, {}, {}), ({}, {}, {}), ({}, {}, {}))",
                        m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
                    )
                },
                VERTEX,
            )?;
        }
        writeln!(w, "}}")?;
        if !bodies.is_empty() {
            write_bodies(w, bodies)?;
        }
        Ok(())
    })
}

/// The triangles of a `Mesh` prim: its orientation, no subdivision, `points`,
/// `faceVertexCounts` and `faceVertexIndices`.
fn mesh_triangles(w: &mut dyn Write, vertices: &[Vec3], triangles: &[[u32; 3]]) -> io::Result<()> {
    let v3 = |v: Vec3| format!("({}, {}, {})", num(v.x), num(v.y), num(v.z));
    let nt = triangles.len();
    writeln!(w, "        uniform token orientation = \"rightHanded\"")?;
    writeln!(w, "        uniform token subdivisionScheme = \"none\"")?;
    array(
        w,
        "point3f[] points",
        vertices.len(),
        |i| v3(vertices[i]),
        "",
    )?;
    array(w, "int[] faceVertexCounts", nt, |_| "3".into(), "")?;
    array(
        w,
        "int[] faceVertexIndices",
        3 * nt,
        |k| triangles[k / 3][k % 3].to_string(),
        "",
    )
}

/// Write a surface mesh as `/surface` (see the module documentation), atomically.
pub fn write_usda_mesh(path: &Path, mesh: &TriMesh) -> io::Result<()> {
    mesh.check()
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, format!("bad mesh: {e}")))?;
    let v3 = |v: rtmpm_physics::math::Vec3| format!("({}, {}, {})", num(v.x), num(v.y), num(v.z));
    write_atomic_with(path, |w| {
        header(w, "surface")?;
        writeln!(w, "def Mesh \"surface\"\n{{")?;
        mesh_triangles(w, &mesh.vertices, &mesh.triangles)?;
        if !mesh.normals.is_empty() {
            array(
                w,
                "normal3f[] normals",
                mesh.normals.len(),
                |i| v3(mesh.normals[i]),
                VERTEX,
            )?;
        }
        writeln!(w, "}}")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bgeo::tests::sample;
    use crate::testing::TestDir;
    use glam::Quat;
    use rtmpm_geometry::Shape;

    #[test]
    fn points_file_holds_every_value_as_text() {
        let d = TestDir::new("usda");
        let p = sample(10);
        let s = vec![[1.0f32, 2.0, 3.0, 0.5, -0.5, 0.25]; 10];
        let j = vec![0.98f32; 10];
        let fields = FrameFields {
            stress: Some(&s),
            jacobian: Some(&j),
        };
        let path = d.path("f.usda");
        write_usda_points(&path, &p, &fields).unwrap();
        let t = std::fs::read_to_string(&path).unwrap();
        assert!(t.starts_with("#usda 1.0\n"));
        assert!(t.contains("def Points \"particles\""));
        let v3 = |v: rtmpm_physics::math::Vec3| format!("({}, {}, {})", v.x, v.y, v.z);
        assert!(t.contains(&format!(
            "point3f[] points = [{}, {}",
            v3(p.x[0]),
            v3(p.x[1])
        )));
        assert!(t.contains("int64[] ids = [0, 1, 2, 3, 4, 5, 6, 7,\n            8, 9]"));
        assert!(t.contains(
            "matrix3d[] primvars:stress = [((1, 0.5, 0.25), (0.5, 2, -0.5), (0.25, -0.5, 3))"
        ));
        assert!(t.contains("float[] primvars:J = [0.98,"));
        assert_eq!(t.matches("interpolation = \"vertex\"").count(), 6);
        // Every float parses back to the same f32.
        let v1: f32 = format!("{}", p.v[3].z).parse().unwrap();
        assert_eq!(v1, p.v[3].z);
        assert_eq!(num(f32::NAN), "nan");
        assert_eq!(num(f32::NEG_INFINITY), "-inf");
    }

    #[test]
    fn rigid_bodies_are_xforms_named_after_them_with_the_quaternion_real_first() {
        let d = TestDir::new("usda-bodies");
        let (cube, ball) = (
            Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                Vec3::ZERO,
                Vec3::new(0.5, 0.25, 0.125),
            )),
            Shape::Sphere(rtmpm_geometry::shape::Sphere {
                center: Vec3::ZERO,
                radius: 0.75,
            }),
        );
        let turn = Quat::from_rotation_y(0.5);
        let bodies = [
            UsdBody {
                name: "log 1",
                shape: &cube,
                position: Vec3::new(1.0, 2.0, 3.0),
                rotation: turn,
            },
            UsdBody {
                name: "1st",
                shape: &ball,
                position: Vec3::ZERO,
                rotation: Quat::IDENTITY,
            },
            UsdBody {
                name: "log_1",
                shape: &ball,
                position: Vec3::ZERO,
                rotation: Quat::IDENTITY,
            },
        ];
        let path = d.path("b.usda");
        write_usda_frame(&path, &sample(3), &FrameFields::default(), &bodies).unwrap();
        let t = std::fs::read_to_string(&path).unwrap();
        // Invalid characters become `_`, a leading digit gets one, a name taken falls back.
        for name in ["log_1", "_1st", "body_2"] {
            assert!(t.contains(&format!("def Xform \"{name}\"")), "{name}");
        }
        assert!(t.contains("double3 xformOp:translate = (1, 2, 3)"));
        let orient = format!(
            "quatf xformOp:orient = ({}, 0, {}, 0)",
            num(turn.w),
            num(turn.y)
        );
        assert!(t.contains(&orient), "{orient}");
        assert!(t.contains("float3 xformOp:scale = (0.5, 0.25, 0.125)"));
        assert!(t.contains("double radius = 0.75"));
        assert_eq!(t.matches("def Sphere").count(), 2);
        // Without bodies, no /bodies prim.
        write_usda_points(&path, &sample(3), &FrameFields::default()).unwrap();
        assert!(!std::fs::read_to_string(&path).unwrap().contains("bodies"));
    }

    #[test]
    fn mesh_file() {
        let d = TestDir::new("usda-mesh");
        let mut m = TriMesh {
            vertices: vec![
                rtmpm_physics::math::Vec3::ZERO,
                rtmpm_physics::math::Vec3::X,
                rtmpm_physics::math::Vec3::Y,
            ],
            normals: vec![rtmpm_physics::math::Vec3::Z; 3],
            triangles: vec![[0, 1, 2]],
        };
        let path = d.path("s.usda");
        write_usda_mesh(&path, &m).unwrap();
        let t = std::fs::read_to_string(&path).unwrap();
        assert!(t.contains("int[] faceVertexIndices = [0, 1, 2]"));
        assert!(t.contains("normal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1)]"));
        m.triangles.push([0, 1, 7]);
        assert!(write_usda_mesh(&d.path("bad.usda"), &m).is_err());
    }
}
