//! Raw serde structs of the scene file, exactly as written (before validation).
//!
//! Every struct denies unknown fields so that typos are reported with their position.
//! Optional fields are `Option` so that the validator can tell "absent" (use the default)
//! from "given" (check it, and reject it where it does not apply).

use rtmpm_geometry::{Shape, ShapeInfo};
use serde::{Deserialize, Deserializer, de};

/// A 3-vector written as `[x, y, z]`.
pub type V3 = [f32; 3];

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawScene {
    pub name: Option<String>,
    pub seed: Option<u64>,
    pub domain: RawDomain,
    pub gravity: Option<V3>,
    pub time: RawTime,
    pub walls: Option<RawWalls>,
    #[serde(default)]
    pub material: Vec<RawMaterial>,
    #[serde(default)]
    pub body: Vec<RawBody>,
    #[serde(default)]
    pub collider: Vec<RawCollider>,
    #[serde(default)]
    pub emitter: Vec<RawEmitter>,
    #[serde(default)]
    pub rigid_body: Vec<RawRigidBody>,
    #[serde(default)]
    pub joint: Vec<RawJoint>,
    pub output: Option<RawOutput>,
    pub render: Option<RawRender>,
    pub solver: Option<RawSolver>,
    pub surface: Option<RawSurface>,
    /// `[batch]`: many worlds from this scene, read by `crate::batch` (each world's scene is
    /// this one with the sweeps' values).
    pub batch: Option<toml::Value>,
}

/// `[surface]`: how fluid surfaces are reconstructed (`[output] surface`, `rtmpm mesh`,
/// rendering).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSurface {
    pub materials: Option<Vec<String>>,
    pub smoothing_length: Option<f32>,
    pub cube_size: Option<f32>,
    pub threshold: Option<f32>,
    pub smoothing_iters: Option<u32>,
    pub normal_smoothing_iters: Option<u32>,
}

/// `[solver]`: how the step is computed: the particle-grid transfer (see
/// `rtmpm_physics::transfer`) and the floating-point precision.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSolver {
    pub transfer: Option<RawTransfer>,
    pub update: Option<RawUpdate>,
    pub flip: Option<f32>,
    pub precision: Option<crate::settings::Precision>,
    pub particle_state: Option<crate::settings::ParticleState>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum RawTransfer {
    #[serde(rename = "mls")]
    Mls,
    #[serde(rename = "gimp")]
    Gimp,
    #[serde(rename = "mpm-linear")]
    MpmLinear,
    #[serde(rename = "ck-mpm")]
    CkMpm,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawUpdate {
    Usl,
    Musl,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDomain {
    pub min: V3,
    pub max: V3,
    pub dx: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTime {
    pub duration: f32,
    pub fps: Option<f32>,
    pub dt: Option<f32>,
    pub cfl: Option<f32>,
    pub max_dt: Option<f32>,
    pub min_dt: Option<f32>,
    pub damping: Option<f32>,
    pub damping_until: Option<f32>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawCondition {
    Sticky,
    Slip,
    Separate,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawFace {
    pub condition: Option<RawCondition>,
    pub friction: Option<f32>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawFaces {
    pub x_min: Option<RawFace>,
    pub x_max: Option<RawFace>,
    pub y_min: Option<RawFace>,
    pub y_max: Option<RawFace>,
    pub z_min: Option<RawFace>,
    pub z_max: Option<RawFace>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawWalls {
    pub thickness: Option<u32>,
    pub condition: Option<RawCondition>,
    pub friction: Option<f32>,
    pub faces: Option<RawFaces>,
}

/// A `[[material]]` table: its name, type and density; the model's own fields are read by the
/// model (`rtmpm_physics::material`, each model's `Params`), which rejects unknown ones.
#[derive(Debug, Deserialize)]
pub struct RawMaterial {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: String,
    pub density: f32,
    #[serde(flatten)]
    pub fields: toml::Table,
}

/// A table's `shape = "..."`: a shape of the registry ([`Shape::ALL`], its index there), read
/// from its name (an unknown name is serde's "unknown variant" error, listing the names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawShape(pub usize);

impl RawShape {
    /// The shape named `name`.
    pub fn named(name: &str) -> Option<RawShape> {
        Shape::code_of(name).map(|k| RawShape(k as usize))
    }

    /// What the registry knows of it.
    pub fn info(self) -> &'static ShapeInfo {
        &Shape::ALL[self.0]
    }

    /// Its name in scene files.
    pub fn name(self) -> &'static str {
        self.info().name
    }
}

impl<'de> Deserialize<'de> for RawShape {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<RawShape, D::Error> {
        struct Name;
        impl de::Visitor<'_> for Name {
            type Value = RawShape;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a shape name")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<RawShape, E> {
                RawShape::named(v).ok_or_else(|| E::unknown_variant(v, Shape::NAMES))
            }
        }
        d.deserialize_str(Name)
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawSampling {
    Regular,
    Jittered,
    Random,
}

/// A mesh scale: one number (uniform) or `[sx, sy, sz]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum RawScale {
    Uniform(f32),
    PerAxis(V3),
}

/// The geometry fields of every shape, listed once: `$then!` receives them as
/// `[name: type, ...]` (each optional in a table), followed by `$rest`.
macro_rules! with_geometry_fields {
    ($then:ident! { $($rest:tt)* }) => {
        $then! {
            [
                min: V3,
                max: V3,
                center: V3,
                radius: f32,
                axis: V3,
                height: f32,
                file: String,
                scale: RawScale,
                translate: V3,
                point: V3,
                normal: V3
            ]
            $($rest)*
        }
    };
}

/// [`RawGeometry`] from the geometry fields.
macro_rules! geometry_struct {
    ([$($g:ident: $gt:ty),*]) => {
        /// A table's shape and geometry fields as written: the fields of every shape, of which a
        /// table may give only its shape's (`rtmpm_geometry::shape::ShapeKind::FIELDS`; the
        /// validator says which field does not belong).
        #[derive(Clone, Debug)]
        pub struct RawGeometry {
            pub shape: RawShape,
            $(pub $g: Option<$gt>,)*
        }

        impl RawGeometry {
            /// The geometry fields given, in the order of their list.
            pub fn given(&self) -> Vec<&'static str> {
                let mut v = Vec::new();
                $(if self.$g.is_some() {
                    v.push(stringify!($g));
                })*
                v
            }
        }
    };
}

with_geometry_fields!(geometry_struct! {});

/// A table with a shape: `shape` and every geometry field ([`RawGeometry`]), then its own
/// fields.
macro_rules! shaped_table {
    (
        [$($g:ident: $gt:ty),*]
        $(#[$m:meta])*
        pub struct $name:ident { $($(#[$fm:meta])* pub $f:ident: $ft:ty,)* }
    ) => {
        $(#[$m])*
        #[derive(Debug, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            /// The shape.
            pub shape: RawShape,
            $(#[doc = "A geometry field ([`RawGeometry`])."] pub $g: Option<$gt>,)*
            $($(#[$fm])* pub $f: $ft,)*
        }

        impl $name {
            /// The table's shape and geometry fields.
            pub fn geometry(&self) -> RawGeometry {
                RawGeometry {
                    shape: self.shape,
                    $($g: self.$g.clone(),)*
                }
            }
        }
    };
}

with_geometry_fields!(shaped_table! {
    /// A `[[body]]` table: material that fills its shape at the start.
    pub struct RawBody {
        pub name: Option<String>,
        pub material: String,
        pub particles_per_cell: Option<u32>,
        pub sampling: Option<RawSampling>,
        pub count: Option<u64>,
        pub velocity: Option<V3>,
        pub angular_velocity: Option<V3>,
    }
});

with_geometry_fields!(shaped_table! {
    /// A `[[collider]]` table: an obstacle, its boundary rule and its motion.
    pub struct RawCollider {
        pub condition: Option<RawCondition>,
        pub friction: Option<f32>,
        pub velocity: Option<V3>,
        pub angular_velocity: Option<V3>,
        pub pivot: Option<V3>,
        pub keyframes: Option<Vec<RawKeyframe>>,
    }
});

/// One key of `collider.keyframes`: `{ t, position, rotation }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawKeyframe {
    /// Time (s).
    pub t: f32,
    /// World position of the collider's pivot (default: the pivot of the rest pose).
    pub position: Option<V3>,
    /// Rotation vector: axis times angle in radians (default: none).
    pub rotation: Option<V3>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawMeshFormat {
    Obj,
    Ply,
    Vtu,
    Usda,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum RawField {
    #[serde(rename = "stress")]
    Stress,
    #[serde(rename = "J")]
    J,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawOutput {
    pub dir: Option<String>,
    /// Names of frame formats ([`rtmpm_io::FRAME_FORMATS`]).
    pub formats: Option<Vec<String>>,
    pub fields: Option<Vec<RawField>>,
    pub surface: Option<Vec<RawMeshFormat>>,
    pub compress: Option<bool>,
}

/// `[render]`: camera and image settings of `rtmpm render` / `rtmpm run --render`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRender {
    pub camera: Option<V3>,
    pub target: Option<V3>,
    pub fov: Option<f32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub color_by: Option<String>,
}

with_geometry_fields!(shaped_table! {
    /// An `[[emitter]]` table: particles that appear while the run goes on.
    pub struct RawEmitter {
        pub name: Option<String>,
        pub material: String,
        pub velocity: Option<V3>,
        /// Particles per second.
        pub rate: Option<f64>,
        /// Volume per second (m^3/s).
        pub volume_rate: Option<f64>,
        pub start: Option<f64>,
        pub stop: Option<f64>,
        pub particles_per_cell: Option<u32>,
    }
});

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawRigidKind {
    Dynamic,
    Kinematic,
    Fixed,
}

with_geometry_fields!(shaped_table! {
    /// A `[[rigid_body]]` table: a rigid body the material pushes and is pushed by. A
    /// cylinder's `axis` defaults to y; a mesh body's OBJ file (relative to the scene file) is
    /// placed by its scale about the file's origin and its translation (the mesh as placed in
    /// the world at t = 0).
    pub struct RawRigidBody {
        pub name: Option<String>,
        /// A mesh body collides with other bodies and the walls as its convex hull.
        pub convex: Option<bool>,
        #[serde(rename = "type")]
        pub kind: Option<RawRigidKind>,
        pub density: Option<f32>,
        pub mass: Option<f32>,
        /// Rotation vector (rad) about the centre.
        pub rotation: Option<V3>,
        pub velocity: Option<V3>,
        pub angular_velocity: Option<V3>,
        pub condition: Option<RawCondition>,
        pub friction: Option<f32>,
    }
});

/// A rigid body named in a `[[joint]]`: its index in `[[rigid_body]]` or its `name`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum RawBodyRef {
    Index(i64),
    Name(String),
}

/// The kind of a `[[joint]]`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawJointKind {
    Fixed,
    Spherical,
    Revolute,
    Prismatic,
}

/// A `[[joint]]` table: a rigid body held to the world or to another body.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawJoint {
    #[serde(rename = "type")]
    pub kind: RawJointKind,
    /// The jointed body.
    pub body: RawBodyRef,
    /// The other body (absent: the world).
    pub to: Option<RawBodyRef>,
    /// World position of the joint at t = 0.
    pub anchor: V3,
    /// Hinge (revolute) or slide (prismatic) axis in the world at t = 0.
    pub axis: Option<V3>,
    /// Angle (rad, revolute) or distance (m, prismatic) limits: `[lower, upper]` (a list, so
    /// that a third value is refused rather than dropped).
    pub limits: Option<Vec<f32>>,
}
