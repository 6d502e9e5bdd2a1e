//! Rigid bodies on the GPU (`[[rigid_body]]`): the bodies move in rapier3d on the host
//! ([`rtmpm_core::rigid::RigidWorld`], cargo feature `rigid` of rtmpm-core), the grid update
//! couples them (`kernels/grid_update.cu`: `couple_bodies`, the same rule as the CPU backend's
//! `cpu/grid_update.rs`).
//!
//! Per step: the bodies' states at the step's time go to constant memory with the step
//! parameters, the impulse sums are cleared; after the step the host reads the sums (one small
//! copy and a wait for the step: the host round trip of the coupling), gives them to the bodies
//! and advances the rapier world by dt. The step itself (its graph) is unchanged.

use crate::contract::{BODY_EXCHANGE_SLOTS, GpuBody, GpuCollider, MAX_BODIES};
use cudarc::driver::{CudaModule, CudaSlice, CudaStream, DevicePtr};
use rtmpm_core::Scene;
use rtmpm_core::boundary::sdf::Shape;
use rtmpm_core::rigid::{BodyState, Exchange, RigidShape, RigidWorld};
use rtmpm_core::sim::SimError;
use std::sync::Arc;

fn err(what: &'static str) -> impl Fn(cudarc::driver::DriverError) -> SimError {
    move |e| SimError::Backend(format!("CUDA: {what}: {e:?}"))
}

/// A body's shape as the collider shape the kernels evaluate (rest pose, centre at 0).
fn shape(s: &RigidShape) -> Shape {
    match *s {
        RigidShape::Box { half_extents } => Shape::Box {
            center: glam::Vec3::ZERO,
            half_extents,
        },
        RigidShape::Sphere { radius } => Shape::Sphere {
            center: glam::Vec3::ZERO,
            radius,
        },
        RigidShape::Cylinder {
            radius,
            half_height,
        } => Shape::Cylinder {
            center: glam::Vec3::ZERO,
            axis: glam::Vec3::Y,
            radius,
            half_height,
        },
    }
}

/// The device record of a body's state.
pub fn encode(b: &BodyState) -> GpuBody {
    let s = shape(&b.shape);
    let mut col = GpuCollider {
        kind: crate::contract::collider_kind(&s),
        cond: crate::contract::condition(b.condition),
        friction: b.friction,
        ..Default::default()
    };
    crate::encode::shape_params(&s, &mut col, &mut Vec::new());
    GpuBody {
        shape: col,
        rot: b.rotation.to_cols_array(),
        center: b.center.to_array(),
        velocity: b.velocity.to_array(),
        omega: b.angular_velocity.to_array(),
        // The farthest point of the shape from its centre, and a little more for rounding.
        bound: b.shape.world_half_extents(glam::Mat3::IDENTITY).length() * 1.001 + 1e-6,
        dynamic: b.dynamic as u32,
    }
}

/// The rigid bodies of a GPU run: their rapier world and the device buffers of the coupling.
pub struct Bodies {
    world: RigidWorld,
    /// Global copy of `c_bodies` (`Ctx::bodies`): `MAX_BODIES` [`GpuBody`] records.
    states: CudaSlice<u8>,
    /// `BODY_EXCHANGE_SLOTS` x bodies x 6 f64 impulse sums (`Ctx::body_exchange`).
    exchange: CudaSlice<f64>,
}

impl Bodies {
    /// The bodies of `scene` (`None` without any), their device buffers allocated on `stream`.
    /// Refused with several GPUs (`multi`) and with the MUSL update, as on the CPU.
    pub fn new(scene: &Scene, stream: &Arc<CudaStream>) -> Result<Option<Bodies>, SimError> {
        if scene.rigid_bodies.is_empty() {
            return Ok(None);
        }
        if scene.rigid_bodies.len() > MAX_BODIES {
            return Err(SimError::Backend(format!(
                "CUDA backend: at most {MAX_BODIES} rigid bodies (the scene has {}); merge \
                 bodies or run on the CPU backend",
                scene.rigid_bodies.len()
            )));
        }
        if scene.solver.update == rtmpm_core::transfer::Update::Musl {
            return Err(SimError::Backend(
                "rigid bodies are coupled in the grid update of USL steps: use [solver] update \
                 = \"usl\" with [[rigid_body]] tables"
                    .into(),
            ));
        }
        let Some(world) = RigidWorld::new(&scene.rigid_bodies, scene.gravity, scene.interior())?
        else {
            return Ok(None);
        };
        let n = scene.rigid_bodies.len();
        let states = stream
            .alloc_zeros::<u8>(MAX_BODIES * std::mem::size_of::<GpuBody>())
            .map_err(err("alloc rigid bodies"))?;
        let exchange = stream
            .alloc_zeros::<f64>(BODY_EXCHANGE_SLOTS * n * 6)
            .map_err(err("alloc rigid-body impulses"))?;
        Ok(Some(Bodies {
            world,
            states,
            exchange,
        }))
    }

    /// Device addresses for [`crate::contract::Ctx`]: (bodies, impulse sums, count).
    pub fn ctx_fields(&self, stream: &Arc<CudaStream>) -> (u64, u64, u32) {
        let (a, _) = self.states.device_ptr(stream);
        let (b, _) = self.exchange.device_ptr(stream);
        (a, b, self.world.states().len() as u32)
    }

    /// The bodies' states at the current time.
    pub fn states(&self) -> &[BodyState] {
        self.world.states()
    }

    /// Before a step: the bodies' states to constant memory (and its global copy), the impulse
    /// sums cleared.
    pub fn upload(
        &mut self,
        module: &Arc<CudaModule>,
        stream: &Arc<CudaStream>,
    ) -> Result<(), SimError> {
        let recs: Vec<GpuBody> = self.world.states().iter().map(encode).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&recs);
        stream
            .memcpy_htod(bytes, &mut self.states.slice_mut(..bytes.len()))
            .map_err(err("upload rigid bodies"))?;
        crate::backend::write_symbol(module, stream, "c_bodies", bytes)?;
        stream
            .memset_zeros(&mut self.exchange)
            .map_err(err("clear rigid-body impulses"))
    }

    /// After a step of `dt`: read the impulse sums (waits for the step), give them to the
    /// bodies and advance the rapier world.
    pub fn advance(&mut self, stream: &Arc<CudaStream>, dt: f32) -> Result<(), SimError> {
        let sums = stream
            .clone_dtoh(&self.exchange)
            .map_err(err("read rigid-body impulses"))?;
        let ex = exchange_sums(&sums, self.world.states().len());
        self.world.advance(&ex, dt);
        Ok(())
    }
}

/// The impulse sums of every body from the `BODY_EXCHANGE_SLOTS` copies (slot-major: slot,
/// body, 6 values), added in slot order (the same sum for the same copies).
pub fn exchange_sums(sums: &[f64], bodies: usize) -> Vec<Exchange> {
    let mut out = vec![Exchange::default(); bodies];
    for slot in sums
        .chunks_exact(6 * bodies.max(1))
        .take(BODY_EXCHANGE_SLOTS)
    {
        for (e, v) in out.iter_mut().zip(slot.chunks_exact(6)) {
            for a in 0..3 {
                e.impulse[a] += v[a];
                e.torque[a] += v[3 + a];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_core::boundary::Condition;

    #[test]
    fn the_slots_add_up_body_by_body() {
        let mut sums = vec![0.0; BODY_EXCHANGE_SLOTS * 2 * 6];
        // Body 1's impulse y in slot 0 and slot 31, body 0's torque z in slot 5.
        sums[6 + 1] = 1.5;
        sums[31 * 12 + 6 + 1] = 2.0;
        sums[5 * 12 + 5] = -3.0;
        let e = exchange_sums(&sums, 2);
        assert_eq!(e[1].impulse, [0.0, 3.5, 0.0]);
        assert_eq!(e[0].torque, [0.0, 0.0, -3.0]);
        assert_eq!(e[0].impulse, [0.0; 3]);
    }

    #[test]
    fn a_body_is_encoded_as_its_collider_shape_about_its_centre() {
        let b = BodyState {
            shape: RigidShape::Box {
                half_extents: glam::Vec3::new(0.1, 0.2, 0.3),
            },
            rotation: glam::Mat3::from_rotation_z(0.5),
            center: glam::Vec3::new(1.0, 2.0, 3.0),
            velocity: glam::Vec3::X,
            angular_velocity: glam::Vec3::Y,
            dynamic: true,
            condition: Condition::Separate,
            friction: 0.25,
        };
        let g = encode(&b);
        assert_eq!(g.shape.kind, 1);
        assert_eq!(&g.shape.p[..6], &[0.0, 0.0, 0.0, 0.1, 0.2, 0.3]);
        assert_eq!(
            g.shape.cond,
            crate::contract::condition(Condition::Separate)
        );
        assert_eq!(g.rot, b.rotation.to_cols_array());
        assert_eq!(g.dynamic, 1);
        // Every corner of the box is inside the bounding sphere.
        let corner = glam::Vec3::new(0.1, 0.2, 0.3).length();
        assert!(g.bound >= corner && g.bound < corner * 1.01, "{}", g.bound);
    }
}
