//! Validation of the shapes of bodies, colliders, emitters and rigid bodies: where a shape may
//! be used, which fields it takes, its fields read by the shape itself
//! (`rtmpm_geometry::shape`, through [`Fields`]), meshes and particle files; and the bodies and
//! colliders themselves.

use super::core::{R, V, fmt3};
use crate::error::SceneError;
use crate::scene::Body;
use crate::schema::*;
use crate::settings::Sampling;
use rtmpm_geometry::mesh::TriMesh;
use rtmpm_geometry::shape::{Mesh, Points, ShapeFields, ShapeKind, allowed_for};
use rtmpm_geometry::{Collider, PointSet, Shape, Use};
use rtmpm_io::obj::read_obj;
use rtmpm_io::points::read_points;
use rtmpm_physics::boundary::BoundaryRule;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use std::path::{Path, PathBuf};

/// The geometry fields of table `prefix` (`body[2]`) as a shape reads them.
pub(super) struct Fields<'a, 'v> {
    pub v: &'a V<'v>,
    pub prefix: &'a str,
    pub g: &'a RawGeometry,
    pub use_: Use,
    /// The scene file's folder (files are relative to it).
    pub base: &'a Path,
    pub dx: f32,
    /// A rigid body's `convex`.
    pub convex: bool,
}

impl Fields<'_, '_> {
    fn path(&self, name: &str) -> String {
        format!("{}.{name}", self.prefix)
    }

    /// `scale` (one factor or three, positive) and `translate`.
    fn placement(&self, scale_message: impl Fn(Vec3) -> String) -> R<(Vec3, Vec3)> {
        let scale = match self.g.scale {
            None => Vec3::ONE,
            Some(RawScale::Uniform(s)) => Vec3::splat(s),
            Some(RawScale::PerAxis(s)) => Vec3::from_array(s),
        };
        if !scale.is_finite() || scale.min_element() <= 0.0 {
            return Err(self.v.err(
                self.path("scale"),
                scale_message(scale),
                "use positive scale factors",
            ));
        }
        let translate = match self.g.translate {
            Some(t) => self.v.vec3(&self.path("translate"), t)?,
            None => Vec3::ZERO,
        };
        Ok((scale, translate))
    }
}

impl ShapeFields for Fields<'_, '_> {
    type Error = SceneError;

    fn vector(&self, name: &str) -> Option<[f32; 3]> {
        match name {
            "min" => self.g.min,
            "max" => self.g.max,
            "center" => self.g.center,
            "axis" => self.g.axis,
            "translate" => self.g.translate,
            "point" => self.g.point,
            "normal" => self.g.normal,
            _ => None,
        }
    }

    fn number(&self, name: &str) -> Option<f32> {
        match name {
            "radius" => self.g.radius,
            "height" => self.g.height,
            _ => None,
        }
    }

    fn missing(&self, name: &str) -> SceneError {
        self.v.err(
            self.path(name),
            format!("shape \"{}\" needs `{name}`", self.g.shape.name()),
            format!("add {name}"),
        )
    }

    fn error(&self, name: &str, message: String, hint: String) -> SceneError {
        self.v.err(self.path(name), message, hint)
    }

    fn finite3(&self, name: &str, v: [f32; 3]) -> R<Vec3> {
        self.v.vec3(&self.path(name), v)
    }

    fn positive(&self, name: &str, x: f32, what: &str) -> R<f32> {
        self.v.positive(&self.path(name), x, what)
    }

    fn unit(&self, name: &str, v: [f32; 3], what: &str) -> R<Vec3> {
        self.v.unit(&self.path(name), v, what)
    }

    fn dx(&self) -> f32 {
        self.dx
    }

    fn convex(&self) -> bool {
        self.convex
    }

    /// `file` (joined to the scene's folder), placed by `scale` and `translate`.
    fn mesh_file(&self) -> R<(TriMesh, PathBuf)> {
        let file = self.g.file.as_ref().ok_or_else(|| {
            self.v.err(
                self.path("file"),
                "a mesh needs a file",
                "add file = \"meshes/x.obj\" (relative to the scene file)",
            )
        })?;
        let (scale, translate) =
            self.placement(|s| format!("scale {} must be positive", fmt3(s)))?;
        let path = self.base.join(file);
        let hint = match self.use_ {
            Use::RigidBody => format!(
                "give a readable OBJ file with triangles; the path is relative to the scene \
                 file's folder ({})",
                self.base.display()
            ),
            _ => {
                "give a readable, closed OBJ mesh with triangles (paths are relative to the scene \
                  file)"
                    .to_string()
            }
        };
        let mesh = read_obj(&path, scale, translate)
            .map_err(|e| self.v.err(self.path("file"), e.to_string(), hint))?;
        self.v.read_file(&self.path("file"), &path);
        Ok((mesh, path))
    }

    /// `file`'s points (not empty), placed by `scale` and `translate` (volumes scaled, masses
    /// kept).
    fn points_file(&self) -> R<PointSet> {
        let file = self.g.file.as_ref().ok_or_else(|| {
            self.v.err(
                self.path("file"),
                "a particles body needs a file",
                "add file = \"x.ply\" (or .vtu, .bgeo, .bgeo.gz), relative to the scene file",
            )
        })?;
        let mut points = read_points(&self.base.join(file)).map_err(|e| {
            self.v.err(
                self.path("file"),
                e.to_string(),
                "give a readable PLY, VTU or BGEO file of points (e.g. a frame of an earlier run)",
            )
        })?;
        self.v.read_file(&self.path("file"), &self.base.join(file));
        if points.positions.is_empty() {
            return Err(self.v.err(
                self.path("file"),
                format!("{} holds no points", points.source.display()),
                "use a file with at least one point",
            ));
        }
        let (scale, translate) = self.placement(|_| "scale factors must be positive".into())?;
        if scale != Vec3::ONE || translate != Vec3::ZERO {
            for p in &mut points.positions {
                *p = *p * scale + translate;
            }
            // Volumes scale with the product of the factors; masses stay.
            if let Some(v) = &mut points.volumes {
                let k = scale.element_product();
                v.iter_mut().for_each(|x| *x *= k);
            }
        }
        Ok(points)
    }
}

impl V<'_> {
    /// The shape of table `prefix` may be used for `u`: a clear refusal naming the shapes
    /// that may.
    pub(super) fn shape_use(&self, prefix: &str, shape: RawShape, u: Use) -> R<()> {
        match shape.info().refused(u) {
            None => Ok(()),
            Some(message) => Err(self.err(
                format!("{prefix}.shape"),
                message,
                format!("use shape = {}", allowed_for(u)),
            )),
        }
    }

    /// Only the fields of the table's shape are given.
    pub(super) fn shape_fields(&self, prefix: &str, g: &RawGeometry) -> R<()> {
        let info = g.shape.info();
        match g.given().into_iter().find(|f| !info.fields.contains(f)) {
            None => Ok(()),
            Some(f) => Err(self.err(
                format!("{prefix}.{f}"),
                format!("`{f}` is not a parameter of shape \"{}\"", info.name),
                format!("remove it; this shape takes: {}", info.fields.join(", ")),
            )),
        }
    }

    /// The shape of table `prefix` of use `u`, checked and read (`base`: the scene's folder;
    /// `dx`: the grid spacing).
    pub(super) fn shape(
        &self,
        prefix: &str,
        g: &RawGeometry,
        u: Use,
        base: &Path,
        dx: f32,
    ) -> R<Shape> {
        self.shape_use(prefix, g.shape, u)?;
        self.shape_fields(prefix, g)?;
        self.read_shape(prefix, g, u, base, dx)
    }

    /// The shape of table `prefix`, read (its use and fields checked).
    fn read_shape(&self, prefix: &str, g: &RawGeometry, u: Use, base: &Path, dx: f32) -> R<Shape> {
        let fields = Fields {
            v: self,
            prefix,
            g,
            use_: u,
            base,
            dx,
            convex: false,
        };
        Shape::read(g.shape.0, &fields, u)
    }

    /// The bounds `lo .. hi` of `what` (`the body`) of table `prefix` lie inside the domain
    /// minus the walls, `interior` (within 1e-5 of its size).
    pub(super) fn inside_interior(
        &self,
        prefix: &str,
        what: &str,
        (lo, hi): (Vec3, Vec3),
        (imin, imax): (Vec3, Vec3),
    ) -> R<()> {
        let tol = 1e-5 * (imax - imin).max_element();
        if lo.cmplt(imin - tol).any() || hi.cmpgt(imax + tol).any() {
            return Err(self.err(
                format!("{prefix}.shape"),
                format!(
                    "the {what} spans {} .. {}, outside the domain or inside the walls",
                    fmt3(lo),
                    fmt3(hi)
                ),
                format!(
                    "keep each {what} inside the box {} .. {} (the domain minus the walls)",
                    fmt3(imin),
                    fmt3(imax)
                ),
            ));
        }
        Ok(())
    }

    /// The material named `name` of table `prefix`, as its index.
    pub(super) fn material_index(
        &self,
        prefix: &str,
        name: &str,
        materials: &[Material],
    ) -> R<usize> {
        materials
            .iter()
            .position(|m| m.name == name)
            .ok_or_else(|| {
                let known: Vec<String> =
                    materials.iter().map(|m| format!("{:?}", m.name)).collect();
                self.err(
                    format!("{prefix}.material"),
                    format!("unknown material {name:?}"),
                    if known.is_empty() {
                        "define it in a [[material]] table".to_string()
                    } else {
                        format!("use one of: {}", known.join(", "))
                    },
                )
            })
    }

    pub(super) fn body(
        &self,
        i: usize,
        b: &RawBody,
        materials: &[Material],
        base: &Path,
        dx: f32,
        interior: (Vec3, Vec3),
    ) -> R<Body> {
        let prefix = format!("body[{i}]");
        let f = |n: &str| format!("{prefix}.{n}");
        let material = self.material_index(&prefix, &b.material, materials)? as u32;
        let g = b.geometry();
        self.shape_use(&prefix, b.shape, Use::Body)?;
        self.shape_fields(&prefix, &g)?;
        if b.shape.name() == Points::NAME {
            self.not_for_points(&prefix, b)?;
        }
        // A checkpoint's scene whose body file is gone: the body's particles are the
        // checkpoint's, and it has no shape to sample.
        let gone = [Points::NAME, Mesh::NAME].contains(&b.shape.name())
            && g.file
                .as_ref()
                .is_some_and(|file| self.resumed_without(&f("file"), &base.join(file)));
        let shape = if gone {
            Shape::Particles(Points {
                points: Default::default(),
            })
        } else {
            self.read_shape(&prefix, &g, Use::Body, base, dx)?
        };
        self.inside_interior(&prefix, "body", shape.bounds(), interior)?;
        let ppc = b.particles_per_cell.unwrap_or(8);
        if ppc == 0 {
            return Err(self.err(
                f("particles_per_cell"),
                "particles_per_cell must be at least 1",
                "use 8 (2 per axis) or 27 (3 per axis)",
            ));
        }
        let sampling = match b.sampling.unwrap_or(RawSampling::Jittered) {
            RawSampling::Regular => Sampling::Regular,
            RawSampling::Jittered => Sampling::Jittered,
            RawSampling::Random => Sampling::Random,
        };
        if let Some(c) = b.count {
            if sampling != Sampling::Random {
                return Err(self.err(
                    f("count"),
                    "count only applies to sampling = \"random\"",
                    "remove count, or set sampling = \"random\"",
                ));
            }
            if c == 0 {
                return Err(self.err(
                    f("count"),
                    "count must be at least 1",
                    "give a positive particle count",
                ));
            }
        }
        let velocity = match b.velocity {
            Some(v) => self.vec3(&f("velocity"), v)?,
            None => Vec3::ZERO,
        };
        let angular_velocity = match b.angular_velocity {
            Some(v) => self.vec3(&f("angular_velocity"), v)?,
            None => Vec3::ZERO,
        };
        Ok(Body {
            name: b.name.clone().unwrap_or_else(|| format!("body{i}")),
            material,
            shape,
            particles_per_cell: ppc,
            jitter: sampling == Sampling::Jittered,
            sampling,
            count: b.count,
            velocity,
            angular_velocity,
            file_velocity: b.velocity.is_none() && b.angular_velocity.is_none(),
        })
    }

    /// A body made of a file's particles is not sampled: `sampling` and `count` do not apply.
    fn not_for_points(&self, prefix: &str, b: &RawBody) -> R<()> {
        for (field, given) in [
            ("sampling", b.sampling.is_some()),
            ("count", b.count.is_some()),
        ] {
            if given {
                return Err(self.err(
                    format!("{prefix}.{field}"),
                    format!("`{field}` does not apply to a body made of a file's particles"),
                    "remove it: the particles are the file's points",
                ));
            }
        }
        Ok(())
    }

    pub(super) fn collider(&self, i: usize, c: &RawCollider, base: &Path, dx: f32) -> R<Collider> {
        let prefix = format!("collider[{i}]");
        let f = |n: &str| format!("{prefix}.{n}");
        let shape = self.shape(&prefix, &c.geometry(), Use::Collider, base, dx)?;
        let condition = Self::condition(c.condition.unwrap_or(Self::DEFAULT_CONDITION));
        let friction = self.non_negative(&f("friction"), c.friction.unwrap_or(0.0), "friction")?;
        let velocity = match c.velocity {
            Some(v) => self.vec3(&f("velocity"), v)?,
            None => Vec3::ZERO,
        };
        let angular_velocity = match c.angular_velocity {
            Some(v) => self.vec3(&f("angular_velocity"), v)?,
            None => Vec3::ZERO,
        };
        let pivot = match c.pivot {
            Some(p) => self.vec3(&f("pivot"), p)?,
            None => shape.center(),
        };
        let keyframes = match &c.keyframes {
            Some(k) => Some(self.keyframes(&prefix, c, k, pivot)?),
            None => None,
        };
        Ok(Collider {
            shape,
            rule: BoundaryRule {
                condition,
                friction,
            },
            velocity,
            angular_velocity,
            pivot,
            keyframes,
        })
    }
}
