//! The scene as GPU parameters, in the kernels' precision: the structs of [`crate::contract`]
//! filled from a [`Scene`] and returned as the bytes that are copied to the device. Each
//! material's parameters come from its own model (`Model::gpu_params`); in f64 from the model
//! built in f64 (rtmpm-physics-f64) from the scene's parameters, so the GPU's f64 materials are the CPU's.

use crate::contract::{
    self, ColliderPoses, GpuCollider, GpuColliderPose, GpuReal, MAX_COLLIDERS, MAX_MATERIALS,
    Scalars, StepParams,
};
use rtmpm_geometry::Collider;
use rtmpm_geometry::Shape;
use rtmpm_physics::math::Vec3;
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;

/// The read-only tables of a run, as copied to the device.
pub struct Tables {
    /// [`Scalars`] in the kernels' precision.
    pub scalars: Vec<u8>,
    /// The materials ([`contract::MaterialGpu`]) in the kernels' precision.
    pub materials: Vec<u8>,
    /// The colliders.
    pub colliders: Vec<GpuCollider>,
    /// The values of the mesh colliders' distance grids, then those of the mesh rigid bodies.
    pub mesh: Vec<f32>,
    /// Where each rigid body's distance grid starts in `mesh` (0 for a body that is not a
    /// mesh), in the scene's order.
    pub body_mesh: Vec<u32>,
}

/// Every table of `scene` in the precision `f64` or f32.
pub fn tables(scene: &Scene, f64: bool) -> Result<Tables, SimError> {
    let (colliders, mut mesh) = colliders(scene)?;
    let body_mesh = body_meshes(scene, &mut mesh);
    Ok(Tables {
        scalars: scalars_bytes(scene, f64),
        materials: materials(scene, f64)?,
        colliders,
        mesh,
        body_mesh,
    })
}

/// [`tables`] of the merged scene of a batch of worlds ([`crate::batch`]): one material row
/// per world and material, read from global memory, so any number of them.
pub fn batch_tables(scene: &Scene, f64: bool) -> Result<Tables, SimError> {
    let (colliders, mut mesh) = colliders(scene)?;
    let body_mesh = body_meshes(scene, &mut mesh);
    Ok(Tables {
        scalars: scalars_bytes(scene, f64),
        materials: material_rows(scene, f64)?,
        colliders,
        mesh,
        body_mesh,
    })
}

/// The distance grids of the mesh rigid bodies appended to `mesh` (the same table as the mesh
/// colliders', read by the same `mesh_distance`); where each starts (0 for the other shapes).
pub fn body_meshes(scene: &Scene, mesh: &mut Vec<f32>) -> Vec<u32> {
    scene
        .rigid_bodies
        .iter()
        .map(|b| match &b.shape {
            Shape::Mesh(m) => {
                let at = mesh.len() as u32;
                mesh.extend_from_slice(&m.sdf.values);
                at
            }
            _ => 0,
        })
        .collect()
}

/// The material table in the kernels' precision (`f64` or f32), as bytes.
pub fn materials(scene: &Scene, f64: bool) -> Result<Vec<u8>, SimError> {
    if scene.materials.len() > MAX_MATERIALS {
        return Err(SimError::Backend(format!(
            "CUDA backend: at most {MAX_MATERIALS} materials (the scene has {})",
            scene.materials.len()
        )));
    }
    material_rows(scene, f64)
}

/// The material table without the constant memory's limit on its rows.
fn material_rows(scene: &Scene, f64: bool) -> Result<Vec<u8>, SimError> {
    let bytes = if f64 {
        let models = rtmpm_physics_f64::convert::materials(&scene.materials)
            .map_err(SimError::Backend)?
            .iter()
            .map(|m| (m.model.code(), m.model.gpu_params()))
            .collect::<Vec<_>>();
        bytemuck::cast_slice(&contract::materials(&models).map_err(SimError::Backend)?).to_vec()
    } else {
        let models = scene
            .materials
            .iter()
            .map(|m| (m.model.code(), m.model.gpu_params()))
            .collect::<Vec<_>>();
        bytemuck::cast_slice(&contract::materials(&models).map_err(SimError::Backend)?).to_vec()
    };
    Ok(bytes)
}

/// The collider table and the concatenated values of the mesh colliders' distance grids.
pub fn colliders(scene: &Scene) -> Result<(Vec<GpuCollider>, Vec<f32>), SimError> {
    if scene.colliders.len() > MAX_COLLIDERS {
        return Err(SimError::Backend(format!(
            "CUDA backend: at most {MAX_COLLIDERS} colliders (the scene has {})",
            scene.colliders.len()
        )));
    }
    let mut mesh = Vec::new();
    let cols = scene
        .colliders
        .iter()
        .map(|c| collider(c, &mut mesh))
        .collect();
    mesh.push(0.0);
    Ok((cols, mesh))
}

fn collider(c: &Collider, mesh: &mut Vec<f32>) -> GpuCollider {
    let mut g = GpuCollider {
        kind: contract::collider_kind(&c.shape),
        cond: contract::condition(c.rule.condition),
        friction: c.rule.friction,
        pivot: c.pivot.to_array(),
        ..Default::default()
    };
    shape_params(&c.shape, &mut g);
    let values = c.shape.gpu().values;
    if !values.is_empty() {
        g.mesh_offset = mesh.len() as u32;
        mesh.extend_from_slice(values);
    }
    g
}

/// The shape's kind and parameters into `g` ([`Shape::gpu`]), as its device twin
/// (`kernels/geometry/<name>.cuh`) reads them; a mesh's grid dimensions (its values are in the
/// mesh table, at `g.mesh_offset`).
pub fn shape_params(shape: &Shape, g: &mut GpuCollider) {
    let p = shape.gpu();
    g.kind = shape.code();
    g.p = p.p;
    g.dims = p.dims;
}

/// The run's constants in precision `R`, computed in `R` from the scene's values as the CPU
/// backend of that precision does (`cpu::StepConstants`).
pub fn scalars<R: GpuReal>(scene: &Scene) -> Scalars<R> {
    let r = R::from_f32;
    let dx = r(scene.dx);
    let v3 = |v: Vec3| v.to_array().map(r);
    let lo = v3(scene.domain_min);
    Scalars {
        origin: lo.map(|x| x - r(4.0) * dx),
        dx,
        inv_dx: r(1.0) / dx,
        domain_min: lo,
        domain_max: v3(scene.domain_max),
        wall_friction: scene.walls.faces.map(|f| r(f.friction)),
        flip: r(scene.solver.flip),
    }
}

/// [`scalars`] in the precision `f64` or f32, as bytes.
pub fn scalars_bytes(scene: &Scene, f64: bool) -> Vec<u8> {
    if f64 {
        bytemuck::bytes_of(&scalars::<f64>(scene)).to_vec()
    } else {
        bytemuck::bytes_of(&scalars::<f32>(scene)).to_vec()
    }
}

/// The parameters of the step of length `dt` starting at `t`.
pub fn step<R: GpuReal>(scene: &Scene, dt: f32, t: f32) -> StepParams<R> {
    let r = R::from_f32;
    StepParams {
        dt: r(dt),
        t: r(t),
        gravity: scene.gravity.to_array().map(r),
        damping: r(scene.time.damping.factor(dt, t)),
    }
}

/// [`step`] in the precision `f64` or f32, as bytes; with `t` zeroed when `without_t` (the
/// kernels never read `t`: two steps whose bytes differ only in it need no new upload).
pub fn step_bytes(scene: &Scene, dt: f32, t: f32, f64: bool, without_t: bool) -> Vec<u8> {
    let t = if without_t { 0.0 } else { t };
    if f64 {
        bytemuck::bytes_of(&step::<f64>(scene, dt, t)).to_vec()
    } else {
        bytemuck::bytes_of(&step::<f32>(scene, dt, t)).to_vec()
    }
}

/// Every collider's pose and velocity at time `t` ([`collider_pose`]).
pub fn poses(scene: &Scene, t: f32) -> ColliderPoses {
    let mut p = ColliderPoses::default();
    for (k, c) in scene.colliders.iter().enumerate().take(MAX_COLLIDERS) {
        let r = collider_pose(c, t);
        (p.rot[k], p.pivot[k], p.velocity[k], p.omega[k]) = (r.rot, r.pivot, r.velocity, r.omega);
    }
    p
}

/// Collider `c`'s pose and velocity at time `t`, as the CPU backend evaluates them
/// (`Collider::rotation`, `pivot_at`, `motion_at`: constant velocities or keyframes).
pub fn collider_pose(c: &Collider, t: f32) -> GpuColliderPose {
    let (v, w) = c.motion_at(t);
    GpuColliderPose {
        rot: c.rotation(t).to_cols_array(),
        pivot: c.pivot_at(t).to_array(),
        velocity: v.to_array(),
        omega: w.to_array(),
    }
}

/// The user's tool as the grid update reads it (`kernels/grid_update.cu`: `node_boundary`): its
/// world shape (a sphere or a box; pivot 0, not rotated) with the separating rule and no
/// friction, moving at `velocity`; inactive for `None`.
pub fn tool(tool: Option<(&Shape, Vec3)>) -> contract::GpuTool {
    let Some((shape, velocity)) = tool else {
        return contract::GpuTool::default();
    };
    let rule = rtmpm_physics::boundary::BoundaryRule::default();
    let mut g = GpuCollider {
        kind: contract::collider_kind(shape),
        cond: contract::condition(rule.condition),
        friction: rule.friction,
        ..Default::default()
    };
    shape_params(shape, &mut g);
    contract::GpuTool {
        shape: g,
        velocity: velocity.to_array(),
        active: 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/mixed.toml");
        Scene::from_file(&path).expect("mixed scene")
    }

    #[test]
    fn materials_carry_their_kind_and_parameters_in_both_precisions() {
        let s = scene();
        let f32s: Vec<contract::MaterialGpu<f32>> =
            bytemuck::pod_collect_to_vec(&materials(&s, false).unwrap());
        assert_eq!(f32s.len(), s.materials.len());
        for (g, m) in f32s.iter().zip(&s.materials) {
            assert_eq!(g.kind, m.model.code());
            let p = m.model.gpu_params();
            assert_eq!(&g.p[..p.len()], &p[..]);
        }
        let f64s: Vec<contract::MaterialGpu<f64>> =
            bytemuck::pod_collect_to_vec(&materials(&s, true).unwrap());
        for (a, b) in f64s.iter().zip(&f32s) {
            assert_eq!(a.kind, b.kind);
            for (x, y) in a.p.iter().zip(&b.p) {
                assert!(
                    (x - *y as f64).abs() <= 1e-6 * x.abs().max(1.0),
                    "{x} vs {y}"
                );
            }
        }
    }

    #[test]
    fn scalars_are_computed_in_their_precision() {
        let s = scene();
        let a = scalars::<f32>(&s);
        let b = scalars::<f64>(&s);
        assert_eq!(a.origin[0], s.domain_min.x - 4.0 * s.dx);
        assert_eq!(b.origin[0], s.domain_min.x as f64 - 4.0 * s.dx as f64);
        assert_eq!(a.inv_dx, 1.0 / s.dx);
        assert_eq!(
            scalars_bytes(&s, true).len(),
            std::mem::size_of::<Scalars<f64>>()
        );
        let p = step_bytes(&s, 1e-4, 0.5, false, true);
        assert_eq!(p, step_bytes(&s, 1e-4, 0.0, false, false));
    }

    #[test]
    fn the_tool_is_a_separating_frictionless_collider_or_nothing() {
        let none = tool(None);
        assert_eq!(none.active, 0);
        let ball = Shape::Sphere(rtmpm_geometry::shape::Sphere {
            center: Vec3::new(0.1, 0.2, 0.3),
            radius: 0.05,
        });
        let t = tool(Some((&ball, Vec3::new(1.0, 0.0, -2.0))));
        assert_eq!(t.active, 1);
        assert_eq!(t.shape.kind, contract::collider_kind(&ball));
        assert_eq!(
            t.shape.cond,
            contract::condition(rtmpm_physics::boundary::Condition::Separate)
        );
        assert_eq!(t.shape.friction, 0.0);
        assert_eq!(&t.shape.p[..4], &[0.1, 0.2, 0.3, 0.05]);
        assert_eq!(t.shape.pivot, [0.0; 3]);
        assert_eq!(t.velocity, [1.0, 0.0, -2.0]);
    }

    #[test]
    fn poses_move_the_pivot_and_turn_about_it() {
        let s = scene();
        let p = poses(&s, 0.25);
        for (k, c) in s.colliders.iter().enumerate() {
            let pivot = c.pivot + c.velocity * 0.25;
            assert_eq!(p.pivot[k], pivot.to_array());
            assert_eq!(p.velocity[k], c.velocity.to_array());
            assert_eq!(p.omega[k], c.angular_velocity.to_array());
        }
    }

    #[test]
    fn keyframed_poses_and_velocities_are_the_cpu_ones() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paddle.toml");
        let s = Scene::from_file(&path).expect("paddle scene");
        let c = &s.colliders[0];
        assert!(c.keyframes.is_some());
        for t in [0.0, 0.2, 0.7, 1.3, 2.5] {
            let p = poses(&s, t);
            assert_eq!(p.rot[0], c.rotation(t).to_cols_array());
            assert_eq!(p.pivot[0], c.pivot_at(t).to_array());
            let (v, w) = c.motion_at(t);
            assert_eq!((p.velocity[0], p.omega[0]), (v.to_array(), w.to_array()));
        }
        // Lowering at 0.3 m/s, then turning at 2 pi rad/s about y.
        assert!((poses(&s, 0.2).velocity[0][1] + 0.3).abs() < 1e-5);
        assert!((poses(&s, 0.7).omega[0][1] - 2.0 * std::f32::consts::PI).abs() < 1e-4);
    }
}
