//! Validation of the geometry of bodies and colliders: shapes, meshes and their placement,
//! sampling settings.

use super::core::{MESH_MARGIN, R, V, fmt3};
use crate::scene::Body;
use crate::schema::*;
use crate::settings::Sampling;
use rtmpm_geometry::mesh::MeshSdf;
use rtmpm_geometry::sdf::Shape;
use rtmpm_geometry::{BodyShape, Collider};
use rtmpm_io::obj::read_obj;
use rtmpm_physics::boundary::BoundaryRule;
use rtmpm_physics::material::Material;
use rtmpm_physics::math::Vec3;
use std::path::Path;
use std::sync::Arc;

impl V<'_> {
    pub(super) fn mesh(
        &self,
        prefix: &str,
        g: &RawGeometry,
        base: &Path,
        dx: f32,
    ) -> R<Arc<MeshSdf>> {
        let (path, scale, translate) = self.mesh_placement(prefix, g, base)?;
        let sdf = read_obj(&path, scale, translate)
            .map(|mesh| MeshSdf::build(&mesh, 0.5 * dx, MESH_MARGIN))
            .map_err(|e| self.err(format!("{prefix}.file"), e.to_string(), "give a readable, closed OBJ mesh with triangles (paths are relative to the scene file)"))?;
        Ok(Arc::new(sdf))
    }

    /// A mesh's `file` (joined to the scene's folder), `scale` and `translate`.
    pub(super) fn mesh_placement(
        &self,
        prefix: &str,
        g: &RawGeometry,
        base: &Path,
    ) -> R<(std::path::PathBuf, Vec3, Vec3)> {
        let file = g.file.as_ref().ok_or_else(|| {
            self.err(
                format!("{prefix}.file"),
                "a mesh needs a file",
                "add file = \"meshes/x.obj\" (relative to the scene file)",
            )
        })?;
        let scale = match g.scale {
            None => Vec3::ONE,
            Some(RawScale::Uniform(s)) => Vec3::splat(s),
            Some(RawScale::PerAxis(s)) => Vec3::from_array(s),
        };
        if !scale.is_finite() || scale.min_element() <= 0.0 {
            return Err(self.err(
                format!("{prefix}.scale"),
                format!("scale {} must be positive", fmt3(scale)),
                "use positive scale factors",
            ));
        }
        let translate = match g.translate {
            Some(t) => self.vec3(&format!("{prefix}.translate"), t)?,
            None => Vec3::ZERO,
        };
        Ok((base.join(file), scale, translate))
    }

    /// Check that only the parameters of `shape` are given.
    pub(super) fn shape_fields(&self, prefix: &str, shape: RawShape, g: &RawGeometry) -> R<()> {
        let allowed: &[&str] = match shape {
            RawShape::HalfSpace => &["point", "normal"],
            RawShape::Box => &["min", "max"],
            RawShape::Sphere => &["center", "radius"],
            RawShape::Cylinder => &["center", "axis", "radius", "height"],
            RawShape::Mesh | RawShape::Particles => &["file", "scale", "translate"],
        };
        let given = [
            ("min", g.min.is_some()),
            ("max", g.max.is_some()),
            ("center", g.center.is_some()),
            ("radius", g.radius.is_some()),
            ("axis", g.axis.is_some()),
            ("height", g.height.is_some()),
            ("file", g.file.is_some()),
            ("scale", g.scale.is_some()),
            ("translate", g.translate.is_some()),
            ("point", g.point.is_some()),
            ("normal", g.normal.is_some()),
        ];
        for (f, is) in given {
            if is && !allowed.contains(&f) {
                return Err(self.err(
                    format!("{prefix}.{f}"),
                    format!("`{f}` is not a parameter of shape \"{}\"", shape.name()),
                    format!("remove it; this shape takes: {}", allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn need<T: Copy>(
        &self,
        prefix: &str,
        f: &str,
        x: Option<T>,
        shape: RawShape,
    ) -> R<T> {
        x.ok_or_else(|| {
            self.err(
                format!("{prefix}.{f}"),
                format!("shape \"{}\" needs `{f}`", shape.name()),
                format!("add {f}"),
            )
        })
    }

    /// Analytic body shapes, or a mesh.
    pub(super) fn body_shape(
        &self,
        prefix: &str,
        shape: RawShape,
        g: &RawGeometry,
        base: &Path,
        dx: f32,
    ) -> R<BodyShape> {
        self.shape_fields(prefix, shape, g)?;
        let f = |n: &str| format!("{prefix}.{n}");
        Ok(match shape {
            RawShape::Box => {
                let min = self.vec3(&f("min"), self.need(prefix, "min", g.min, shape)?)?;
                let max = self.vec3(&f("max"), self.need(prefix, "max", g.max, shape)?)?;
                if !max.cmpgt(min).all() {
                    return Err(self.err(
                        f("max"),
                        format!(
                            "box max {} is not above min {} on every axis",
                            fmt3(max),
                            fmt3(min)
                        ),
                        "make every component of max larger than min",
                    ));
                }
                BodyShape::Box { min, max }
            }
            RawShape::Sphere => {
                let center =
                    self.vec3(&f("center"), self.need(prefix, "center", g.center, shape)?)?;
                let radius = self.positive(
                    &f("radius"),
                    self.need(prefix, "radius", g.radius, shape)?,
                    "radius",
                )?;
                BodyShape::Sphere { center, radius }
            }
            RawShape::Cylinder => {
                let center =
                    self.vec3(&f("center"), self.need(prefix, "center", g.center, shape)?)?;
                let axis = self.unit(&f("axis"), g.axis.unwrap_or([0.0, 1.0, 0.0]), "axis")?;
                let radius = self.positive(
                    &f("radius"),
                    self.need(prefix, "radius", g.radius, shape)?,
                    "radius",
                )?;
                let height = self.positive(
                    &f("height"),
                    self.need(prefix, "height", g.height, shape)?,
                    "height",
                )?;
                BodyShape::Cylinder {
                    center,
                    axis,
                    radius,
                    half_height: 0.5 * height,
                }
            }
            RawShape::Mesh => BodyShape::Mesh(self.mesh(prefix, g, base, dx)?),
            RawShape::Particles => {
                return Err(self.err(
                    f("shape"),
                    "only a body can be made of particles",
                    "use box, sphere, cylinder, mesh or half_space for a collider",
                ));
            }
            RawShape::HalfSpace => {
                return Err(self.err(
                    f("shape"),
                    "a body cannot be a half-space (it is infinite)",
                    "use box, sphere, cylinder or mesh",
                ));
            }
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
        let material = materials
            .iter()
            .position(|m| m.name == b.material)
            .ok_or_else(|| {
                let known: Vec<String> =
                    materials.iter().map(|m| format!("{:?}", m.name)).collect();
                self.err(
                    f("material"),
                    format!("unknown material {:?}", b.material),
                    if known.is_empty() {
                        "define it in a [[material]] table".to_string()
                    } else {
                        format!("use one of: {}", known.join(", "))
                    },
                )
            })? as u32;
        let shape = match b.shape {
            RawShape::Particles => self.particles_shape(&prefix, b, base)?,
            s => self.body_shape(&prefix, s, &b.geometry(), base, dx)?,
        };
        let (lo, hi) = shape.bounds();
        let (imin, imax) = interior;
        let tol = 1e-5 * (imax - imin).max_element();
        if lo.cmplt(imin - tol).any() || hi.cmpgt(imax + tol).any() {
            return Err(self.err(
                f("shape"),
                format!(
                    "the body spans {} .. {}, outside the domain or inside the walls",
                    fmt3(lo),
                    fmt3(hi)
                ),
                format!(
                    "keep bodies inside the box {} .. {} (the domain minus the walls)",
                    fmt3(imin),
                    fmt3(imax)
                ),
            ));
        }
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
        })
    }

    pub(super) fn collider(&self, i: usize, c: &RawCollider, base: &Path, dx: f32) -> R<Collider> {
        let prefix = format!("collider[{i}]");
        let f = |n: &str| format!("{prefix}.{n}");
        let g = c.geometry();
        let shape = match c.shape {
            RawShape::HalfSpace => {
                self.shape_fields(&prefix, c.shape, &g)?;
                let point =
                    self.vec3(&f("point"), self.need(&prefix, "point", g.point, c.shape)?)?;
                let normal = self.unit(
                    &f("normal"),
                    self.need(&prefix, "normal", g.normal, c.shape)?,
                    "normal",
                )?;
                Shape::HalfSpace { point, normal }
            }
            s => match self.body_shape(&prefix, s, &g, base, dx)? {
                BodyShape::Box { min, max } => Shape::Box {
                    center: 0.5 * (min + max),
                    half_extents: 0.5 * (max - min),
                },
                BodyShape::Sphere { center, radius } => Shape::Sphere { center, radius },
                BodyShape::Cylinder {
                    center,
                    axis,
                    radius,
                    half_height,
                } => Shape::Cylinder {
                    center,
                    axis,
                    radius,
                    half_height,
                },
                BodyShape::Mesh(m) => Shape::Mesh(m),
                BodyShape::Particles { .. } => {
                    return Err(self.err(
                        f("shape"),
                        "only a body can be made of particles",
                        "use box, sphere, cylinder, mesh or half_space",
                    ));
                }
            },
        };
        let condition = Self::condition(c.condition.unwrap_or(RawCondition::Slip));
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
