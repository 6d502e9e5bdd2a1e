//! Raw serde structs of the scene file, exactly as written (before validation).
//!
//! Every struct denies unknown fields so that typos are reported with their position.
//! Optional fields are `Option` so that the validator can tell "absent" (use the default)
//! from "given" (check it, and reject it where it does not apply).

use serde::Deserialize;

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

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawShape {
    HalfSpace,
    Box,
    Sphere,
    Cylinder,
    Mesh,
    Particles,
}

impl RawShape {
    pub fn name(self) -> &'static str {
        match self {
            RawShape::HalfSpace => "half_space",
            RawShape::Box => "box",
            RawShape::Sphere => "sphere",
            RawShape::Cylinder => "cylinder",
            RawShape::Mesh => "mesh",
            RawShape::Particles => "particles",
        }
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

/// Shape parameters shared by bodies and colliders.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawGeometry {
    pub min: Option<V3>,
    pub max: Option<V3>,
    pub center: Option<V3>,
    pub radius: Option<f32>,
    pub axis: Option<V3>,
    pub height: Option<f32>,
    pub file: Option<String>,
    pub scale: Option<RawScale>,
    pub translate: Option<V3>,
    pub point: Option<V3>,
    pub normal: Option<V3>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBody {
    pub name: Option<String>,
    pub material: String,
    pub shape: RawShape,
    pub min: Option<V3>,
    pub max: Option<V3>,
    pub center: Option<V3>,
    pub radius: Option<f32>,
    pub axis: Option<V3>,
    pub height: Option<f32>,
    pub file: Option<String>,
    pub scale: Option<RawScale>,
    pub translate: Option<V3>,
    pub particles_per_cell: Option<u32>,
    pub sampling: Option<RawSampling>,
    pub count: Option<u64>,
    pub velocity: Option<V3>,
    pub angular_velocity: Option<V3>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCollider {
    pub shape: RawShape,
    pub min: Option<V3>,
    pub max: Option<V3>,
    pub center: Option<V3>,
    pub radius: Option<f32>,
    pub axis: Option<V3>,
    pub height: Option<f32>,
    pub file: Option<String>,
    pub scale: Option<RawScale>,
    pub translate: Option<V3>,
    pub point: Option<V3>,
    pub normal: Option<V3>,
    pub condition: Option<RawCondition>,
    pub friction: Option<f32>,
    pub velocity: Option<V3>,
    pub angular_velocity: Option<V3>,
    pub pivot: Option<V3>,
    pub keyframes: Option<Vec<RawKeyframe>>,
}

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

impl RawBody {
    pub fn geometry(&self) -> RawGeometry {
        RawGeometry {
            min: self.min,
            max: self.max,
            center: self.center,
            radius: self.radius,
            axis: self.axis,
            height: self.height,
            file: self.file.clone(),
            scale: self.scale,
            translate: self.translate,
            point: None,
            normal: None,
        }
    }
}

impl RawCollider {
    pub fn geometry(&self) -> RawGeometry {
        RawGeometry {
            min: self.min,
            max: self.max,
            center: self.center,
            radius: self.radius,
            axis: self.axis,
            height: self.height,
            file: self.file.clone(),
            scale: self.scale,
            translate: self.translate,
            point: self.point,
            normal: self.normal,
        }
    }
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

/// An `[[emitter]]` table: particles that appear while the run goes on.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawEmitter {
    pub name: Option<String>,
    pub material: String,
    pub shape: RawShape,
    pub min: Option<V3>,
    pub max: Option<V3>,
    pub center: Option<V3>,
    pub radius: Option<f32>,
    pub axis: Option<V3>,
    pub height: Option<f32>,
    pub velocity: Option<V3>,
    /// Particles per second.
    pub rate: Option<f64>,
    /// Volume per second (m^3/s).
    pub volume_rate: Option<f64>,
    pub start: Option<f64>,
    pub stop: Option<f64>,
    pub particles_per_cell: Option<u32>,
}

impl RawEmitter {
    pub fn geometry(&self) -> RawGeometry {
        RawGeometry {
            min: self.min,
            max: self.max,
            center: self.center,
            radius: self.radius,
            axis: self.axis,
            height: self.height,
            ..Default::default()
        }
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum RawRigidKind {
    Dynamic,
    Kinematic,
    Fixed,
}

/// A `[[rigid_body]]` table: a rigid body the material pushes and is pushed by.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRigidBody {
    pub name: Option<String>,
    pub shape: RawShape,
    pub min: Option<V3>,
    pub max: Option<V3>,
    pub center: Option<V3>,
    pub radius: Option<f32>,
    /// A cylinder's axis (default y) and height.
    pub axis: Option<V3>,
    pub height: Option<f32>,
    /// A mesh body's OBJ file (relative to the scene file), its scale about the file's origin
    /// and translation (the mesh as placed in the world at t = 0).
    pub file: Option<String>,
    pub scale: Option<RawScale>,
    pub translate: Option<V3>,
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

impl RawRigidBody {
    pub fn geometry(&self) -> RawGeometry {
        RawGeometry {
            min: self.min,
            max: self.max,
            center: self.center,
            radius: self.radius,
            axis: self.axis,
            height: self.height,
            file: self.file.clone(),
            scale: self.scale,
            translate: self.translate,
            ..Default::default()
        }
    }
}

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
    /// Angle (rad, revolute) or distance (m, prismatic) limits.
    pub limits: Option<[f32; 2]>,
}
