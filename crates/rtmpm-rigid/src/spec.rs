//! A validated `[[rigid_body]]`, and the resolution a dynamic body needs in a fluid.

use glam::{Quat, Vec3};
use rtmpm_geometry::Shape;
use rtmpm_physics::boundary::Condition;

/// How a body moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RigidKind {
    /// Moved by gravity, the material and contacts.
    Dynamic,
    /// Moves at its constant initial velocity and spin, pushing the material without being
    /// pushed.
    Kinematic,
    /// Never moves.
    Fixed,
}

/// A validated `[[rigid_body]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidBodySpec {
    pub name: String,
    /// The shape in the body frame (about the centre of mass, in the rest orientation).
    pub shape: Shape,
    pub kind: RigidKind,
    /// Mass (kg), from `mass` or `density` x volume.
    pub mass: f32,
    /// Centre (m) at t = 0.
    pub position: Vec3,
    /// Orientation at t = 0.
    pub rotation: Quat,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    /// The boundary rule between the material and the body.
    pub condition: Condition,
    pub friction: f32,
}

/// The excess weight of a dynamic body denser than a fluid, as a layer of that fluid over the
/// body's surface in cells, `(rho_b - rho_f) V / (rho_f A dx)`, below which the body can hang
/// in the fluid or sink far too slowly. The material loads a body through the grid nodes inside
/// it, so its buoyancy is counted in cells and jumps as node planes pass into it, and a body
/// lighter in the fluid than about a quarter-cell layer over its surface can stop on a node
/// plane. Measured on the 2-core CPU in water (`scripts/validation/small_bodies.py`,
/// validation/RESULTS.md, "Small and near-neutral rigid bodies"): spheres that hung were at
/// 0.25 or less, and every one still off the floor after 2 s at 0.375 or less; 0.4 was chosen
/// after seeing those runs.
pub const HANG_LAYER_CELLS: f32 = 0.4;

/// A warning for each dynamic body that can hang in a fluid of the scene (`fluids`: each fluid
/// material's name and density) it is denser than ([`HANG_LAYER_CELLS`]), with the grid
/// spacing that would let it sink; empty when there is none.
pub fn resolution_warnings(
    bodies: &[RigidBodySpec],
    fluids: &[(&str, f32)],
    dx: f32,
) -> Vec<String> {
    let mut out = Vec::new();
    for (i, b) in bodies.iter().enumerate() {
        if b.kind != RigidKind::Dynamic {
            continue;
        }
        let volume = b.shape.volume();
        let density = b.mass / volume;
        // The fluid it is least denser than decides.
        let Some(&(fluid, rho)) = fluids
            .iter()
            .filter(|&&(_, rho)| density > rho)
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            continue;
        };
        // (rho_b - rho_f) V / (rho_f A): the fluid layer, in metres, the excess weight equals.
        let layer = (density - rho) * volume / (rho * b.shape.area());
        if layer >= HANG_LAYER_CELLS * dx {
            continue;
        }
        out.push(format!(
            "rigid_body[{i}] `{}` (density {}) can hang in `{fluid}` (density {}) or sink in it \
             far too slowly: the material loads a body through the grid nodes inside it, so its \
             buoyancy comes in whole cells, and its weight beyond its buoyancy is that of a \
             layer of `{fluid}` only {:.2} cells thick over its surface (under {HANG_LAYER_CELLS}); \
             use dx <= {} or a larger or denser body (docs/scene-format.md, \"Resolution of \
             rigid bodies\")",
            b.name,
            sig3(density),
            sig3(rho),
            layer / dx,
            sig3(layer / HANG_LAYER_CELLS)
        ));
    }
    out
}

/// `x` to 3 significant digits, as `0.1` or `0.00125`.
fn sig3(x: f32) -> f64 {
    let x = x as f64;
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(2 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}
