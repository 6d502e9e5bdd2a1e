//! Dynamic rigid bodies coupled two ways to the material (`[[rigid_body]]`).
//!
//! The coupling is the boundary-condition form of the compatible particle-in-cell (CPIC)
//! coupling of Hu, Fang, Ge, Qu, Zhu, Pradhana & Jiang, "A Moving Least Squares Material Point
//! Method with Displacement Discontinuity and Two-Way Rigid Body Coupling" (ACM TOG 37(4),
//! SIGGRAPH 2018), section 5: every grid node inside a body takes, by the body's boundary rule,
//! the body's velocity `v_b(x) = v + w x (x - c)` (the same rule as a collider's, on the
//! velocity relative to the body), and the momentum the rule takes from the node,
//! `dp_i = m_i (v_i' - v_i)`, goes to the body as the impulse `-sum dp_i` and the angular
//! impulse `-sum (x_i - c) x dp_i` about its centre of mass `c`, less the gravity the node
//! received in the step (the weight of the material that the transfer kernel spreads onto nodes
//! inside the body, a shell about half a cell thick, is a discretisation artefact, not a load:
//! with it a box of half the water's density sank). Material plus bodies conserve momentum (up
//! to gravity and the walls). Particles are not kept out of a body: a few cross the surface
//! when a body enters the material fast, and then ride with it (their nodes take the body's
//! velocity), adding nothing to its load. Putting them back on the surface instead was tried and
//! biased the floating depth (a box of density 500 floated 0.568 submerged against 0.517).
//! Known limit: at rest a node of material carries `f = -m g`, so a body's load changes only when
//! a plane of nodes enters or leaves it, and a floating body's rest locks onto node planes (its
//! draft is right to about half a cell; validation/RESULTS.md, "Archimedes: tilt, the displaced
//! volume ..."): a load continuous in the body's position needs CPIC's particle-side
//! compatibility or a penalty force (both tried on the CPU, not kept: the same file, "Three more
//! coupling variants"). Dithering which nodes count as inside removes most of the lock, but the
//! bodies then float about 0.2 of a cell high (the same file, "Dithered node membership"). The
//! bodies move under gravity, these impulses and their contacts with each other and the walls
//! in rapier3d (cargo feature `rigid`;
//! [`RigidWorld`]); without the feature a scene with rigid bodies is refused when the backend is
//! built. The CPU backend couples them (`cpu/grid_update.rs`), the CUDA backend too
//! (`rtmpm-cuda/src/rigid.rs`). A body is a box, sphere, cylinder or closed triangle mesh
//! (`rtmpm_geometry::RigidMesh`: its signed distance grid in the body frame, the mesh colliders' code).

mod joint;
mod spec;
mod state;
#[cfg(feature = "rigid")]
mod world;
#[cfg(not(feature = "rigid"))]
mod world_stub;

pub use joint::{JointKind, JointSpec};
pub use spec::{HANG_LAYER_CELLS, RigidBodySpec, RigidKind, resolution_warnings};
pub use state::{BodyLoad, BodyPose, BodyState, Exchange};
/// True when this build simulates rigid bodies (the cargo feature `rigid`: rapier3d).
pub const AVAILABLE: bool = cfg!(feature = "rigid");
#[cfg(feature = "rigid")]
pub use world::RigidWorld;
#[cfg(not(feature = "rigid"))]
pub use world_stub::RigidWorld;
