//! The G-buffer: what the particles, colliders and surfaces put in each pixel.

/// One texel of the G-buffer: depth along the view axis, the splat coordinates (giving the
/// sphere normal) and the particle index.
#[derive(Clone, Copy)]
pub(crate) struct GTexel {
    pub(crate) depth: f32,
    pub(crate) u: f32,
    pub(crate) v: f32,
    pub(crate) id: u32,
}
