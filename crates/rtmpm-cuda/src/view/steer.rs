//! The user steering a running simulation (a live view): gravity and the tool, changed between
//! steps. Both are parameters the kernels read from constant memory (and its global copy), written
//! on the compute stream before the next step: a step replayed from a CUDA graph reads the new
//! values too (a graph holds the kernels' arguments, not the constants).

use crate::backend::CudaBackend;
use crate::error::err;
use crate::kernels::write_symbol;
use rtmpm_geometry::Shape;
use rtmpm_physics::math::Vec3;
use rtmpm_sim::SimError;

impl CudaBackend {
    /// Gravity from the next step on: the step parameters (uploaded before the next step, as any
    /// change of them is) and the rigid bodies' world.
    pub fn set_gravity_vector(&mut self, gravity: Vec3) -> Result<(), SimError> {
        if !gravity.is_finite() {
            return Err(SimError::Backend(format!(
                "gravity must be finite, got {gravity}"
            )));
        }
        self.scene.gravity = gravity;
        if let Some(b) = self.bodies.as_mut() {
            b.set_gravity(gravity);
        }
        Ok(())
    }

    /// The user's tool from the next step on (`None`: no tool): a separating, frictionless
    /// collider of world shape `shape` (a sphere or a box) moving at `velocity`, applied in the
    /// grid update after the scene's colliders.
    pub fn set_tool_shape(&mut self, tool: Option<(Shape, Vec3)>) -> Result<(), SimError> {
        if let Some((shape, velocity)) = &tool {
            if !matches!(shape, Shape::Sphere(_) | Shape::Box(_)) {
                return Err(SimError::Backend(
                    "the tool is a sphere or a box".to_string(),
                ));
            }
            if !velocity.is_finite() {
                return Err(SimError::Backend(format!(
                    "the tool's velocity must be finite, got {velocity}"
                )));
            }
        }
        let g = crate::encode::tool(tool.as_ref().map(|(s, v)| (s, *v)));
        let bytes = bytemuck::bytes_of(&g);
        self.stream
            .memcpy_htod(bytes, &mut self.buffers.tool.slice_mut(..bytes.len()))
            .map_err(err("upload the tool"))?;
        write_symbol(&self.module, &self.stream, "c_tool", bytes)?;
        self.tool = tool.map(|(s, _)| s);
        Ok(())
    }

    /// The tool's shape now, if there is one (drawn by the render stage).
    pub fn tool_shape(&self) -> Option<&Shape> {
        self.tool.as_ref()
    }
}
