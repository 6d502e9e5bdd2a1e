//! What a shape file provides ([`ShapeKind`]) and what it uses: the uses of a shape, the
//! validator's view of a table ([`ShapeFields`]), the device parameters and USD primitive, and
//! the distance formulas more than one shape shares.

use crate::mesh::TriMesh;
use crate::points::PointSet;
use glam::{Mat3, Quat, Vec3};
use std::path::PathBuf;

/// What a scene uses a shape for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Use {
    /// `[[collider]]`: an obstacle of the material.
    Collider,
    /// `[[body]]`: material that fills the shape at the start.
    Body,
    /// `[[emitter]]`: material that appears in the shape while the run goes on.
    Emitter,
    /// `[[rigid_body]]`: a body the material pushes and is pushed by.
    RigidBody,
}

impl Use {
    /// Every use, in the order of the scene format's tables.
    pub const ALL: [Use; 4] = [Use::Body, Use::Collider, Use::Emitter, Use::RigidBody];

    /// The use with its article, as messages name it: "an emitter".
    pub fn noun(self) -> &'static str {
        match self {
            Use::Collider => "a collider",
            Use::Body => "a body",
            Use::Emitter => "an emitter",
            Use::RigidBody => "a rigid body",
        }
    }

    /// Its table in scene files: `emitter` for `[[emitter]]`.
    pub fn table(self) -> &'static str {
        match self {
            Use::Collider => "collider",
            Use::Body => "body",
            Use::Emitter => "emitter",
            Use::RigidBody => "rigid_body",
        }
    }
}

/// What the registry knows of a shape without an instance (the scene's checks, the CUDA
/// contract, the docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeInfo {
    /// [`ShapeKind::NAME`].
    pub name: &'static str,
    /// [`ShapeKind::NOUN`].
    pub noun: &'static str,
    /// [`ShapeKind::FIELDS`].
    pub fields: &'static [&'static str],
    /// [`ShapeKind::USES`].
    pub uses: &'static [Use],
    /// [`ShapeKind::REFUSAL`].
    pub refusal: &'static str,
    /// [`ShapeKind::DEVICE`].
    pub device: bool,
}

impl ShapeInfo {
    /// True when a scene may use the shape for `u`.
    pub fn allows(&self, u: Use) -> bool {
        self.uses.contains(&u)
    }

    /// Why `u` may not use it, as a message: "an emitter cannot be a mesh"; `None` when it
    /// may.
    pub fn refused(&self, u: Use) -> Option<String> {
        if self.allows(u) {
            return None;
        }
        let why = if self.refusal.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.refusal)
        };
        Some(format!("{} cannot be {}{why}", u.noun(), self.noun))
    }

    /// The shape as the fix of a message lists it: `"box" (min, max)`.
    pub fn with_fields(&self) -> String {
        format!("\"{}\" ({})", self.name, self.fields.join(", "))
    }
}

/// The fields of a shape's scene table, as a shape file reads them. The scene's validator
/// implements it: its errors name the field (relative to the table: `radius`), its line and
/// column, and a fix.
pub trait ShapeFields {
    /// The validator's error.
    type Error;

    /// A vector field as written, `None` when absent.
    fn vector(&self, name: &str) -> Option<[f32; 3]>;
    /// A number field as written, `None` when absent.
    fn number(&self, name: &str) -> Option<f32>;
    /// The error of a field the shape needs and the table lacks.
    fn missing(&self, name: &str) -> Self::Error;
    /// The error of field `name`: what is wrong and how to fix it.
    fn error(&self, name: &str, message: String, hint: String) -> Self::Error;
    /// `v` checked finite.
    fn finite3(&self, name: &str, v: [f32; 3]) -> Result<Vec3, Self::Error>;
    /// `x` checked finite and > 0; `what` names it in the message.
    fn positive(&self, name: &str, x: f32, what: &str) -> Result<f32, Self::Error>;
    /// `v` checked finite and nonzero, normalised; `what` names it in the message.
    fn unit(&self, name: &str, v: [f32; 3], what: &str) -> Result<Vec3, Self::Error>;
    /// The scene's grid spacing (m).
    fn dx(&self) -> f32;
    /// The triangles of the table's mesh file (`file`, placed by `scale` and `translate`) and
    /// the file's path.
    fn mesh_file(&self) -> Result<(TriMesh, PathBuf), Self::Error>;
    /// The points of the table's particle file (`file`, placed by `scale` and `translate`).
    fn points_file(&self) -> Result<PointSet, Self::Error>;
    /// A rigid body's `convex` (its engine collides a mesh as its convex hull).
    fn convex(&self) -> bool;

    /// A vector field the shape needs, checked finite.
    fn point(&self, name: &str) -> Result<Vec3, Self::Error> {
        let v = self.vector(name).ok_or_else(|| self.missing(name))?;
        self.finite3(name, v)
    }

    /// A length the shape needs, checked finite and > 0.
    fn length(&self, name: &str) -> Result<f32, Self::Error> {
        let x = self.number(name).ok_or_else(|| self.missing(name))?;
        self.positive(name, x, name)
    }
}

/// A shape's parameters as its device twin reads them (`kernels/geometry/<name>.cuh`): eight
/// floats, and a mesh's distance grid (dimensions and values).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuParams<'a> {
    pub p: [f32; 8],
    pub dims: [u32; 3],
    /// The grid's values (x fastest), empty for the analytic shapes.
    pub values: &'a [f32],
}

impl GpuParams<'_> {
    /// Parameters `p` (at most eight) without a grid.
    pub fn of(p: &[f32]) -> GpuParams<'static> {
        let mut g = GpuParams::default();
        g.p[..p.len()].copy_from_slice(p);
        g
    }
}

/// A shape as a USD geometry primitive in its body frame (`rtmpm_io::usd`, rigid bodies).
#[derive(Clone, Debug, PartialEq)]
pub enum UsdPrim<'a> {
    /// A prim of this schema (`Cube`, `Sphere`, ...) with these attribute lines
    /// (`double radius = 0.5`).
    Schema {
        schema: &'static str,
        attributes: Vec<String>,
    },
    /// A `Mesh` prim of these triangles.
    Mesh(&'a TriMesh),
}

/// A float as USD's text format reads it (`inf`, `-inf`, `nan` for the non-finite).
pub fn usd_number(x: f32) -> String {
    if x.is_finite() {
        format!("{x}")
    } else if x.is_nan() {
        "nan".into()
    } else if x > 0.0 {
        "inf".into()
    } else {
        "-inf".into()
    }
}

/// What a shape file provides; see the module documentation.
pub trait ShapeKind: Sized {
    /// The name in scene files (`shape = "..."`); also the name of its kernel file
    /// (`kernels/geometry/<NAME>.cuh`) and of its device functions (`<NAME>_distance`, ...).
    const NAME: &'static str;
    /// The shape in messages, with its article: "a half-space".
    const NOUN: &'static str;
    /// Its fields in a scene table (besides `shape`); a table may give no other.
    const FIELDS: &'static [&'static str];
    /// What a scene may use it for.
    const USES: &'static [Use];
    /// Why the other uses may not have it, where there is a reason to say ("it is infinite").
    const REFUSAL: &'static str = "";
    /// True when it has a device twin: `kernels/geometry/<NAME>.cuh` with `<NAME>_distance`,
    /// `<NAME>_normal` and `<NAME>_contains`.
    const DEVICE: bool = true;

    /// Read and check its fields for use `u`.
    fn read<F: ShapeFields>(f: &F, u: Use) -> Result<Self, F::Error>;
    /// Read it as a rigid body: the shape about its centre of mass in its rest orientation
    /// (the body frame), the centre in the world and the rest orientation.
    fn read_body<F: ShapeFields>(f: &F) -> Result<(Self, Vec3, Quat), F::Error> {
        Self::read(f, Use::RigidBody).map(Self::body_frame)
    }
    /// The shape about its centre in its rest orientation, the centre and that orientation
    /// (for a rigid body).
    fn body_frame(self) -> (Self, Vec3, Quat);

    /// Signed distance (negative inside).
    fn distance(&self, x: Vec3) -> f32;
    /// Outward unit normal (the gradient of the distance; a fixed unit vector where it is
    /// undefined).
    fn normal(&self, x: Vec3) -> Vec3;
    /// True when the sampler keeps a particle at `x` (a body's or an emitter's inside).
    fn contains(&self, x: Vec3) -> bool;
    /// Axis-aligned bounds of the solid `(min, max)`; infinite for an unbounded shape.
    fn bounds(&self) -> (Vec3, Vec3);
    /// Bounds of the shape as its signed distance describes it (a collider in pictures): a
    /// mesh's distance grid; by default [`ShapeKind::bounds`].
    fn distance_bounds(&self) -> (Vec3, Vec3) {
        self.bounds()
    }
    /// A natural centre (a collider's default pivot).
    fn center(&self) -> Vec3;
    /// Volume (m^3).
    fn volume(&self) -> f32;
    /// Surface area (m^2).
    fn area(&self) -> f32;
    /// Half-extents of the axis-aligned box about [`ShapeKind::center`] that holds the shape
    /// turned by `r` about that centre.
    fn half_extents(&self, r: Mat3) -> Vec3;
    /// Radius of a sphere about [`ShapeKind::center`] that holds the shape.
    fn bounding_radius(&self) -> f32 {
        self.half_extents(Mat3::IDENTITY).length()
    }
    /// Its parameters on the device.
    fn gpu(&self) -> GpuParams<'_>;
    /// Its USD primitive in the body frame, `None` where it has none.
    fn usd(&self) -> Option<UsdPrim<'_>>;
}

/// A vector as scene files write it: `[x, y, z]`.
pub fn fmt3(v: Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// Signed distance to an axis-aligned box (exact, negative inside).
#[inline]
pub fn box_distance(x: Vec3, center: Vec3, half_extents: Vec3) -> f32 {
    let q = (x - center).abs() - half_extents;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// Any unit vector perpendicular to unit `a`.
#[inline]
pub(crate) fn any_perpendicular(a: Vec3) -> Vec3 {
    let t = if a.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    a.cross(t).normalize()
}

/// Signed distance to a capped cylinder (exact, negative inside); `axis` must be a unit vector.
#[inline]
pub fn cylinder_distance(x: Vec3, center: Vec3, axis: Vec3, radius: f32, half_height: f32) -> f32 {
    let p = x - center;
    let h = p.dot(axis);
    let r = (p - h * axis).length();
    let dr = r - radius;
    let dh = h.abs() - half_height;
    let ox = dr.max(0.0);
    let oy = dh.max(0.0);
    (ox * ox + oy * oy).sqrt() + dr.max(dh).min(0.0)
}
