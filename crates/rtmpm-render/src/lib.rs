//! A small CPU renderer for particle frames: shaded spheres with a depth buffer, a ground plane
//! with a shadow map, depth-based ambient occlusion, colour by material or by a scalar field
//! (viridis, with a colour bar and its range as text), PNG and animated GIF output.
//!
//! * [`camera`]: pinhole camera and automatic framing of the domain.
//! * [`raster`]: sphere splatting, parallel over bands of rows (rayon).
//! * `mesh`: triangle meshes (fluid surfaces) rasterised into the same depth buffers, shaded
//!   with a specular highlight.
//! * `colliders`: colliders drawn by sphere tracing their signed distances, clipped to the
//!   scene box, into the same depth buffers (they hide, and cast and receive shadows).
//! * [`colormap`]: viridis and the material palette.
//! * [`text`]: a built-in 5x7 bitmap font for labels.
//! * [`image`]: RGB images, PNG encoding/decoding, resizing, GIF movies.
//! * [`view`]: what a live view asks a backend to draw ([`ViewRequest`]), as options of this
//!   renderer.
//!
//! [`render`] (`frame.rs`) draws one frame from particle arrays in memory ([`input`]: what it
//! takes); the G-buffer (`gbuffer.rs`) holds what the particles, colliders and surfaces put in
//! each pixel, [`colorbar`] the bar and its labels; callers that read PLY frames
//! build the same [`RenderInput`] from the file's columns.

pub mod camera;
mod colliders;
pub mod colorbar;
pub mod colormap;
mod frame;
mod gbuffer;
pub mod image;
pub mod input;
mod mesh;
pub mod plot;
pub(crate) mod raster;
mod shadow;
#[cfg(test)]
mod tests;
pub mod text;
pub mod view;

pub use camera::{Camera, View};
pub use colliders::COLLIDER_COLOR;
pub use colorbar::{draw_color_bar, format_value};
pub use frame::render;
pub use image::{GifMovie, Image};
pub use input::{RenderError, RenderInput, RenderOptions, estimate_radius, field_range, von_mises};
pub use shadow::{LIGHT, SHADOW_RES, ShadowFrame};
pub use view::{MAX_VIEW_SIDE, ViewRequest, particle_field};
