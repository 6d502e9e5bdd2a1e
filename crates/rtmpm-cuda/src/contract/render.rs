//! The render stage's side of the contract (`kernels/render/`, host side in `crate::render`): its
//! constants and the two structs it copies to the GPU, [`RenderParams`] (one picture, passed by
//! value to every render kernel) and [`RenderObject`] (a collider, rigid body or the user's tool
//! posed for the picture).

use super::constants::{MAX_BODIES, MAX_COLLIDERS};
use super::layout::GpuCollider;
use bytemuck::{Pod, Zeroable};

/// Side of the light's square shadow map, texels (the CPU renderer's `SHADOW_RES`).
pub const RENDER_SHADOW_RES: usize = 1024;
/// Bins of each histogram of the automatic colour range.
pub const RENDER_BINS: usize = 2048;
/// The G-buffer id of object `k` is `RENDER_OBJECT_ID + k` (particle ids are their slots, below).
pub const RENDER_OBJECT_ID: u32 = 0xffff_ff00;
/// Objects a picture may hold: every collider, every rigid body and the tool.
pub const RENDER_MAX_OBJECTS: usize = MAX_COLLIDERS + MAX_BODIES + 1;

/// Words of the range scratch (u32): the finite field values' minimum and maximum (order-preserving
/// bits), the range found (f32 bits, `RS_LO`, `RS_HI`), the picked bins, then the histograms.
pub const RS_MIN: usize = 0;
/// See [`RS_MIN`].
pub const RS_MAX: usize = 1;
/// The range's low end (f32 bits) once picked.
pub const RS_LO: usize = 2;
/// The range's high end (f32 bits) once picked.
pub const RS_HI: usize = 3;
/// The first pick: the coarse bin of the low end, its rank in it, the same for the high end.
pub const RS_PICK: usize = 4;
/// The coarse histogram (`RENDER_BINS` counts).
pub const RS_COARSE: usize = 8;
/// The fine histograms of the two picked coarse bins (`2 RENDER_BINS` counts).
pub const RS_FINE: usize = RS_COARSE + RENDER_BINS;
/// Words of the scratch.
pub const RS_WORDS: usize = RS_FINE + 2 * RENDER_BINS;

/// Colour mode codes (`RenderParams::color_by`), in the order of `rtmpm_scene::ColorBy::ALL`.
pub fn color_code(c: rtmpm_scene::ColorBy) -> u32 {
    use rtmpm_scene::ColorBy;
    match c {
        ColorBy::Material => 0,
        ColorBy::Speed => 1,
        ColorBy::J => 2,
        ColorBy::Stress => 3,
        ColorBy::Plastic => 4,
    }
}

/// One picture (`kernels/render/render.cuh`): where it goes, the camera (the CPU renderer's view:
/// eye, orthonormal basis, focal length and centre in pixels), the particles' radius, colouring,
/// floor, scene box, light and shadow map.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct RenderParams {
    /// u64 depth key per pixel (`width x height`).
    pub keys: u64,
    /// The picture: RGBA8 words, or RGB8 bytes (`channels`).
    pub image: u64,
    /// u32 order-preserving depth per shadow texel (`RENDER_SHADOW_RES^2`).
    pub shadow: u64,
    /// f32 field value per particle slot (colouring by a field).
    pub field: u64,
    /// `RS_WORDS` u32 words of the automatic range.
    pub scratch: u64,
    /// `n_objects` [`RenderObject`]s.
    pub objects: u64,
    /// `n_palette` RGB colours (3 f32 each), by material index.
    pub palette: u64,
    /// Eye position (m).
    pub eye: [f32; 3],
    /// View direction (unit).
    pub fwd: [f32; 3],
    /// Right (unit).
    pub right: [f32; 3],
    /// Up (unit).
    pub up: [f32; 3],
    /// Focal length (pixels).
    pub focal: f32,
    /// Image centre (pixels).
    pub cx: f32,
    /// See `cx`.
    pub cy: f32,
    /// Particle radius (m).
    pub radius: f32,
    /// Nearest depth drawn (m).
    pub near: f32,
    /// Sphere tracing: a hit within `eps1` times its depth (a quarter pixel).
    pub eps1: f32,
    /// Colour range of the field (when `auto_range` is 0).
    pub range: [f32; 2],
    /// Height of the floor (when `floor` is 1).
    pub floor_y: f32,
    /// The scene box: clips the objects, bounds the floor's checkers and the shadow map.
    pub bounds_lo: [f32; 3],
    /// See `bounds_lo`.
    pub bounds_hi: [f32; 3],
    /// Towards the light (unit).
    pub light: [f32; 3],
    /// Colour of the objects (RGB, 0..1).
    pub object_rgb: [f32; 3],
    /// Shadow map: the corner of texel (0, 0) on its near plane.
    pub shadow_origin: [f32; 3],
    /// Shadow map basis (unit).
    pub shadow_right: [f32; 3],
    /// See `shadow_right`.
    pub shadow_up: [f32; 3],
    /// See `shadow_right` (from the light).
    pub shadow_fwd: [f32; 3],
    /// Shadow texels per metre.
    pub shadow_scale: f32,
    /// Image size (pixels).
    pub width: u32,
    /// See `width`.
    pub height: u32,
    /// [`color_code`].
    pub color_by: u32,
    /// 1: the range is the field's 1st to 99th percentile in this picture.
    pub auto_range: u32,
    /// 1: draw the floor at `floor_y`.
    pub floor: u32,
    /// 1: shadows from the light's shadow map.
    pub shadows: u32,
    /// Objects drawn.
    pub n_objects: u32,
    /// Colours in the palette (at least 1).
    pub n_palette: u32,
    /// 4: RGBA8 words; 3: RGB8 bytes.
    pub channels: u32,
    /// Padding to 8 bytes.
    pub pad: u32,
}

// SAFETY: Pod, passed by value with the C layout the kernels declare (checked by layout_asserts).
unsafe impl cudarc::driver::DeviceRepr for RenderParams {}

/// A collider, rigid body or the tool, posed for the picture (world = `rot` (rest - shape.pivot)
/// + `pivot`), with its bounds clipped to the scene box and padded as the CPU renderer pads them.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct RenderObject {
    /// The shape in its rest pose (`shape_distance`).
    pub shape: GpuCollider,
    /// Rest-to-world rotation, column-major.
    pub rot: [f32; 9],
    /// World position of the rest pivot (`shape.pivot`).
    pub pivot: [f32; 3],
    /// Padded world bounds (clipped to the scene box).
    pub lo: [f32; 3],
    /// See `lo`.
    pub hi: [f32; 3],
    /// A half-space: a point of its plane (world).
    pub plane_p: [f32; 3],
    /// A half-space: its outward unit normal (world).
    pub plane_n: [f32; 3],
    /// 1: a half-space, intersected exactly within the bounds.
    pub plane: u32,
}
