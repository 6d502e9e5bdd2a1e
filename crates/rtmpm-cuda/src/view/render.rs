//! Host side of the render stage (`kernels/render/`): a live view's picture drawn on the GPU from
//! the simulation's own state arrays, nothing of the particles copied to the host; only the
//! finished image comes back (8-bit RGB, through page-locked memory).
//!
//! The picture is the CPU renderer's (`rtmpm_render::render`) for the same
//! [`RenderOptions`]: the same camera ([`rtmpm_render::View`]), light and shadow map
//! ([`ShadowFrame`]), palette and viridis, colour modes and automatic range (the 1st to 99th
//! percentile), colliders (sphere-traced, clipped to the scene box), floor and sky; the colour
//! bar and label are drawn on the host by the CPU renderer's own functions. The kernels, in
//! stream order after the steps (one launch each): clear; the field and its range (colouring by a
//! field); the shadow map; the splat of every particle into 64-bit depth keys (atomicMin of
//! depth << 32 | slot); the objects traced into the same keys; the resolve, one thread a pixel.

use crate::backend::{CudaBackend, PendingPicture, RenderBuffers};
use crate::contract::render::{
    RENDER_MAX_OBJECTS, RENDER_OBJECT_ID, RENDER_SHADOW_RES, RS_HI, RS_LO, RS_WORDS, RenderObject,
    RenderParams, color_code,
};
use crate::contract::{Ctx, GpuCollider};
use crate::error::err;
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::{CudaEvent, CudaStream, DevicePtr, DriverError, LaunchConfig, PushKernelArg};
use rtmpm_geometry::Collider;
use rtmpm_geometry::Shape;
use rtmpm_physics::boundary::BoundaryRule;
use rtmpm_physics::math::Vec3;
use rtmpm_render::{COLLIDER_COLOR, Image, LIGHT, RenderOptions, ShadowFrame, colormap};
use rtmpm_scene::ColorBy;
use rtmpm_sim::SimError;

/// Largest side of a picture (pixels), as the CPU renderer's.
pub const MAX_SIDE: u32 = 16384;

/// The parameters of a picture of `opts` without its buffers and objects (the host's part:
/// camera, colouring, floor, scene box, light, shadow map). Checks what the CPU renderer checks.
pub fn params(opts: &RenderOptions) -> Result<RenderParams, String> {
    let (w, h) = (opts.width, opts.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(format!(
            "image size {w}x{h} is out of range (1 to {MAX_SIDE} per side)"
        ));
    }
    opts.camera.check()?;
    if !(opts.radius.is_finite() && opts.radius > 0.0) {
        return Err(format!(
            "particle radius must be positive, got {}",
            opts.radius
        ));
    }
    let v = opts.camera.view(w, h);
    let sf = ShadowFrame::new(opts.bounds, opts.radius);
    let a = |v: Vec3| v.to_array();
    Ok(RenderParams {
        eye: a(v.pos),
        fwd: a(v.fwd),
        right: a(v.right),
        up: a(v.up),
        focal: v.focal,
        cx: v.cx,
        cy: v.cy,
        radius: opts.radius,
        near: 1e-4_f32.max(opts.radius),
        // A hit is accepted within a quarter of a pixel's footprint (the CPU renderer's).
        eps1: 0.25 / v.focal,
        range: opts.range.map_or([0.0, 1.0], |(lo, hi)| [lo, hi]),
        auto_range: u32::from(opts.range.is_none() && opts.color_by != ColorBy::Material),
        floor_y: opts.floor.unwrap_or(0.0),
        floor: u32::from(opts.floor.is_some()),
        bounds_lo: a(opts.bounds.0),
        bounds_hi: a(opts.bounds.1),
        light: a(LIGHT.normalize()),
        object_rgb: COLLIDER_COLOR,
        shadow_origin: a(sf.origin),
        shadow_right: a(sf.right),
        shadow_up: a(sf.up),
        shadow_fwd: a(sf.fwd),
        shadow_scale: sf.scale,
        width: w,
        height: h,
        color_by: color_code(opts.color_by),
        shadows: u32::from(opts.shadows),
        channels: 3,
        ..Default::default()
    })
}

/// The palette of `opts` as the kernels read it: 3 floats a material (the fixed palette when
/// `opts.palette` is empty).
pub fn palette(opts: &RenderOptions) -> Vec<f32> {
    let p: &[[f32; 3]] = if opts.palette.is_empty() {
        &colormap::PALETTE
    } else {
        &opts.palette
    };
    p.iter().flatten().copied().collect()
}

/// `c` at time `t` as the kernels draw it: posed, its bounds clipped to the scene box `clip`
/// and padded as the CPU renderer pads them; `None` when it lies outside the box. A mesh's
/// distance grid is read at `mesh_offset` in the backend's mesh table.
pub fn collider_object(
    c: &Collider,
    mesh_offset: u32,
    t: f32,
    clip: (Vec3, Vec3),
) -> Option<RenderObject> {
    let (mut lo, mut hi) = clip;
    if let Some((clo, chi)) = c.bounds(t) {
        lo = lo.max(clo);
        hi = hi.min(chi);
    }
    if !(lo.cmple(hi).all() && lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let pad = Vec3::splat(1e-4 + 1e-3 * (hi - lo).max_element());
    let mut shape = GpuCollider {
        kind: crate::contract::collider_kind(&c.shape),
        cond: crate::contract::condition(c.rule.condition),
        friction: c.rule.friction,
        pivot: c.pivot.to_array(),
        ..Default::default()
    };
    // A mesh's grid values are in the backend's table already, at `mesh_offset`.
    crate::encode::shape_params(&c.shape, &mut shape);
    if let Shape::Mesh(_) = c.shape {
        shape.mesh_offset = mesh_offset;
    }
    let rot = c.rotation(t);
    let (plane, plane_p, plane_n) = match c.shape {
        Shape::HalfSpace(h) => (
            1,
            c.to_world(h.point, t).to_array(),
            (rot * h.normal).normalize_or(h.normal).to_array(),
        ),
        _ => (0, [0.0; 3], [0.0; 3]),
    };
    Some(RenderObject {
        shape,
        rot: rot.to_cols_array(),
        pivot: c.pivot_at(t).to_array(),
        lo: (lo - pad).to_array(),
        hi: (hi + pad).to_array(),
        plane_p,
        plane_n,
        plane,
    })
}

/// The user's tool as a motionless collider (its world shape; drawn like the colliders).
pub fn tool_collider(shape: Shape) -> Collider {
    Collider {
        shape,
        rule: BoundaryRule::default(),
        velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
        pivot: Vec3::ZERO,
        keyframes: None,
    }
}

impl RenderBuffers {
    fn new(b: &CudaBackend, width: u32, height: u32) -> Result<RenderBuffers, SimError> {
        let s = &b.stream;
        let pixels = width as usize * height as usize;
        let tables = b.tables()?;
        let n_materials = b.scene.materials.len().max(colormap::PALETTE.len());
        // SAFETY: written by the copies before the host reads it; plain page-locked memory.
        let pinned = unsafe { s.context().alloc_pinned_with_flags::<u8>(3 * pixels, 0) }
            .map_err(err("allocate pinned memory"))?;
        // SAFETY: as above (the range found, two f32 words as bits).
        let range = unsafe { s.context().alloc_pinned_with_flags::<u32>(2, 0) }
            .map_err(err("allocate pinned memory"))?;
        let done = s
            .context()
            .new_event(Some(CUevent_flags::CU_EVENT_DISABLE_TIMING))
            .map_err(err("event"))?;
        Ok(RenderBuffers {
            width,
            height,
            keys: s.alloc_zeros(pixels).map_err(err("alloc render keys"))?,
            image: s
                .alloc_zeros(4 * pixels)
                .map_err(err("alloc render image"))?,
            shadow: s
                .alloc_zeros(RENDER_SHADOW_RES * RENDER_SHADOW_RES)
                .map_err(err("alloc shadow map"))?,
            scratch: s
                .alloc_zeros(RS_WORDS)
                .map_err(err("alloc render scratch"))?,
            objects: s
                .alloc_zeros(RENDER_MAX_OBJECTS * size_of::<RenderObject>())
                .map_err(err("alloc render objects"))?,
            palette: s
                .alloc_zeros(3 * n_materials)
                .map_err(err("alloc palette"))?,
            field: None,
            pinned,
            range,
            done,
            pending: None,
            collider_mesh: tables.colliders.iter().map(|c| c.mesh_offset).collect(),
            body_mesh: tables.body_mesh,
        })
    }
}

/// Enqueue the kernels of one picture on `s` (`r` complete: buffers, objects, palette).
pub(crate) fn enqueue(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    r: &RenderParams,
) -> Result<(), DriverError> {
    let pixels = r.width as usize * r.height as usize;
    let texels = RENDER_SHADOW_RES * RENDER_SHADOW_RES;
    let particles = c.n as usize;
    let one_block = LaunchConfig {
        grid_dim: (1, 1, 1),
        block_dim: (1024, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: every kernel bounds-checks against the sizes in `c` and `r`, whose buffers the
    // caller allocated to them.
    unsafe {
        s.launch_builder(&k[Kernel::RenderClear])
            .arg(r)
            .launch(k.wave(pixels.max(texels), 256))?;
        if r.color_by != 0 {
            s.launch_builder(&k[Kernel::RenderField])
                .arg(c)
                .arg(r)
                .launch(k.wave(particles, 256))?;
            if r.auto_range != 0 {
                for pass in [0u32, 1] {
                    s.launch_builder(&k[Kernel::RenderHistogram])
                        .arg(c)
                        .arg(r)
                        .arg(&pass)
                        .launch(k.wave(particles, 256))?;
                    s.launch_builder(&k[Kernel::RenderPick])
                        .arg(r)
                        .arg(&pass)
                        .launch(one_block)?;
                }
            }
        }
        if r.shadows != 0 {
            s.launch_builder(&k[Kernel::RenderShadowSplat])
                .arg(c)
                .arg(r)
                .launch(k.wave(particles, 256))?;
            if r.n_objects > 0 {
                s.launch_builder(&k[Kernel::RenderShadowObjects])
                    .arg(c)
                    .arg(r)
                    .launch(cfg(texels, 128))?;
            }
        }
        s.launch_builder(&k[Kernel::RenderSplat])
            .arg(c)
            .arg(r)
            .launch(k.wave(particles, 256))?;
        if r.n_objects > 0 {
            s.launch_builder(&k[Kernel::RenderObjects])
                .arg(c)
                .arg(r)
                .launch(cfg(pixels, 128))?;
        }
        s.launch_builder(&k[Kernel::RenderResolve])
            .arg(c)
            .arg(r)
            .launch(cfg(pixels, 256))?;
    }
    Ok(())
}

/// Where the time of a picture went ([`CudaBackend::time_picture`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct RenderTiming {
    /// The render kernels (CUDA events).
    pub kernels_ms: f64,
    /// The image's copy to page-locked host memory (CUDA events).
    pub copy_ms: f64,
    /// The whole call on the host's clock, uploads, wait and copy into the image included.
    pub total_ms: f64,
}

impl CudaBackend {
    /// Draw the particles as `opts` asks (the CPU renderer's picture of the same options) into
    /// `out` (resized to `opts.width x opts.height`), from the state on the GPU; with
    /// `objects` the scene's colliders at `opts.time`, the rigid bodies and the user's tool
    /// (`opts.colliders` is not read: the backend draws its own). Returns the colour range used
    /// when colouring by a field (found on the GPU when `opts.range` is `None`). Synchronises.
    pub fn render_picture(
        &mut self,
        opts: &RenderOptions,
        objects: bool,
        out: &mut Image,
    ) -> Result<Option<(f32, f32)>, SimError> {
        self.picture(opts, objects, out, None)
    }

    /// [`Self::render_picture`], timed: the kernels and the copy to page-locked memory with CUDA
    /// events, the whole call (the objects' upload, the wait, the copy into `out`, the colour
    /// bar) with the host's clock.
    pub fn time_picture(
        &mut self,
        opts: &RenderOptions,
        objects: bool,
        out: &mut Image,
    ) -> Result<RenderTiming, SimError> {
        let ctx = self.stream.context();
        let new = || {
            ctx.new_event(Some(CUevent_flags::CU_EVENT_DEFAULT))
                .map_err(err("event"))
        };
        let events = [new()?, new()?, new()?];
        let t0 = std::time::Instant::now();
        self.picture(opts, objects, out, Some(&events))?;
        let total_ms = t0.elapsed().as_secs_f64() * 1e3;
        let ms = |a: usize, b: usize| -> Result<f64, SimError> {
            Ok(events[a].elapsed_ms(&events[b]).map_err(err("elapsed"))? as f64)
        };
        Ok(RenderTiming {
            kernels_ms: ms(0, 1)?,
            copy_ms: ms(1, 2)?,
            total_ms,
        })
    }

    fn picture(
        &mut self,
        opts: &RenderOptions,
        objects: bool,
        out: &mut Image,
        events: Option<&[CudaEvent; 3]>,
    ) -> Result<Option<(f32, f32)>, SimError> {
        self.begin_picture(opts, objects, events)?;
        // The whole stream waited for, as before pictures could be begun and collected later.
        self.stream.synchronize().map_err(err("render"))?;
        self.finish_picture(out)
    }

    /// Queue the picture of `opts` (as [`Self::render_picture`] draws it) and its copy, with the
    /// range found, to page-locked memory, then an event; returns without waiting, so that more
    /// work (the next steps) can be queued before [`Self::finish_picture`] collects it.
    pub fn begin_picture(
        &mut self,
        opts: &RenderOptions,
        objects: bool,
        events: Option<&[CudaEvent; 3]>,
    ) -> Result<(), SimError> {
        let mut r = params(opts).map_err(|e| SimError::Backend(format!("render: {e}")))?;
        if self.ctx.cap >= RENDER_OBJECT_ID {
            return Err(SimError::Backend(format!(
                "render: {} particle slots, the GPU renderer draws at most {RENDER_OBJECT_ID}",
                self.ctx.cap
            )));
        }
        let objects = self.render_objects(opts, objects)?;
        self.enqueue_picture(&mut r, opts, &objects, events)?;
        let b = self.render.as_mut().ok_or_else(no_buffers)?;
        let auto_range = r.auto_range != 0;
        if auto_range {
            let host = b.range.as_mut_slice().map_err(err("pinned memory"))?;
            self.stream
                .memcpy_dtoh(&b.scratch.slice(RS_LO..RS_HI + 1), &mut host[..2])
                .map_err(err("read the range"))?;
        }
        b.done
            .record(&self.stream)
            .map_err(err("record an event"))?;
        b.pending = Some(PendingPicture {
            width: r.width,
            height: r.height,
            color_by: opts.color_by,
            range: opts.range,
            auto_range,
            label: opts.label.clone(),
        });
        Ok(())
    }

    /// The picture queued by [`Self::begin_picture`] into `out` (resized to it), its colour bar
    /// and label drawn: waits for that picture's copy only, not for work queued after it.
    /// Returns the colour range used when colouring by a field.
    pub fn finish_picture(&mut self, out: &mut Image) -> Result<Option<(f32, f32)>, SimError> {
        let b = self.render.as_mut().ok_or_else(no_buffers)?;
        let p = b.pending.take().ok_or_else(|| {
            SimError::Backend("CUDA render: no picture begun to finish".to_string())
        })?;
        b.done.synchronize().map_err(err("render"))?;
        let host = b.pinned.as_slice().map_err(err("pinned memory"))?;
        let n = 3 * p.width as usize * p.height as usize;
        if out.width != p.width || out.height != p.height || out.rgb.len() != n {
            *out = Image::new(p.width, p.height, [0, 0, 0]);
        }
        out.rgb.copy_from_slice(&host[..n]);
        let found = if p.auto_range {
            let r = b.range.as_slice().map_err(err("pinned memory"))?;
            (f32::from_bits(r[0]), f32::from_bits(r[1]))
        } else {
            (0.0, 0.0)
        };
        let scale = (p.height / 360).max(1);
        let used = (p.color_by != ColorBy::Material).then(|| p.range.unwrap_or(found));
        if let Some((lo, hi)) = used {
            rtmpm_render::draw_color_bar(out, p.color_by.label(), lo, hi, scale);
        }
        if let Some(label) = &p.label {
            let m = 6 * scale as i32;
            rtmpm_render::text::draw_text(out, m, m, label, scale, [235, 235, 235]);
        }
        Ok(used)
    }

    /// The objects of a picture: the scene's colliders at `opts.time`, the rigid bodies as they
    /// are, the tool.
    fn render_objects(
        &mut self,
        opts: &RenderOptions,
        objects: bool,
    ) -> Result<Vec<RenderObject>, SimError> {
        if !objects {
            return Ok(Vec::new());
        }
        self.render_buffers(opts.width, opts.height)?;
        let b = self.render.as_ref().ok_or_else(no_buffers)?;
        let clip = opts.bounds;
        let mut v: Vec<RenderObject> = Vec::new();
        for (k, c) in self.scene.colliders.iter().enumerate() {
            let mesh = b.collider_mesh.get(k).copied().unwrap_or(0);
            v.extend(collider_object(c, mesh, opts.time, clip));
        }
        for (k, body) in self.rigid_body_states().iter().enumerate() {
            let mesh = b.body_mesh.get(k).copied().unwrap_or(0);
            v.extend(collider_object(&body.collider(), mesh, 0.0, clip));
        }
        if let Some(tool) = &self.tool {
            v.extend(collider_object(&tool_collider(tool.clone()), 0, 0.0, clip));
        }
        v.truncate(RENDER_MAX_OBJECTS);
        Ok(v)
    }

    /// The buffers of a `width x height` picture (allocated, or reallocated for another size).
    fn render_buffers(&mut self, width: u32, height: u32) -> Result<(), SimError> {
        if self
            .render
            .as_ref()
            .is_none_or(|b| b.width != width || b.height != height)
        {
            self.render = None;
            self.render = Some(Box::new(RenderBuffers::new(self, width, height)?));
        }
        Ok(())
    }

    /// Upload the objects and palette, fill in the buffers of `r` and enqueue the picture and
    /// the copy of the image (and the range found) to page-locked memory.
    fn enqueue_picture(
        &mut self,
        r: &mut RenderParams,
        opts: &RenderOptions,
        objects: &[RenderObject],
        events: Option<&[CudaEvent; 3]>,
    ) -> Result<(), SimError> {
        self.render_buffers(r.width, r.height)?;
        let cap = self.ctx.cap as usize;
        let s = self.stream.clone();
        let b = self.render.as_mut().ok_or_else(no_buffers)?;
        if r.color_by != 0 && b.field.as_ref().is_none_or(|f| f.len() < cap) {
            b.field = Some(
                s.alloc_zeros(cap.max(1))
                    .map_err(err("alloc render field"))?,
            );
        }
        let pal = palette(opts);
        if !objects.is_empty() {
            s.memcpy_htod(
                bytemuck::cast_slice::<RenderObject, u8>(objects),
                &mut b.objects.slice_mut(..size_of_val(objects)),
            )
            .map_err(err("upload render objects"))?;
        }
        let n_pal = (pal.len() / 3).min(b.palette.len() / 3).max(1);
        s.memcpy_htod(&pal[..3 * n_pal], &mut b.palette.slice_mut(..3 * n_pal))
            .map_err(err("upload palette"))?;
        r.keys = b.keys.device_ptr(&s).0;
        r.image = b.image.device_ptr(&s).0;
        r.shadow = b.shadow.device_ptr(&s).0;
        r.scratch = b.scratch.device_ptr(&s).0;
        r.objects = b.objects.device_ptr(&s).0;
        r.palette = b.palette.device_ptr(&s).0;
        r.field = b.field.as_ref().map_or(0, |f| f.device_ptr(&s).0);
        r.n_objects = objects.len() as u32;
        r.n_palette = n_pal as u32;
        let record = |k: usize| -> Result<(), SimError> {
            match events {
                Some(e) => e[k].record(&s).map_err(err("record an event")),
                None => Ok(()),
            }
        };
        record(0)?;
        enqueue(&self.kernels, &s, &self.ctx, r).map_err(err("render kernels"))?;
        record(1)?;
        let n = 3 * r.width as usize * r.height as usize;
        let host = b.pinned.as_mut_slice().map_err(err("pinned memory"))?;
        s.memcpy_dtoh(&b.image.slice(..n), &mut host[..n])
            .map_err(err("read the picture"))?;
        record(2)?;
        Ok(())
    }
}

fn no_buffers() -> SimError {
    SimError::Backend("CUDA: render buffers missing".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_physics::boundary::Condition;
    use rtmpm_render::Camera;

    fn opts() -> RenderOptions {
        let (lo, hi) = (Vec3::new(0.1, 0.1, 0.1), Vec3::new(0.9, 0.7, 0.9));
        let mut o = RenderOptions::new(lo, hi, 0.004);
        o.width = 320;
        o.height = 200;
        o.camera = Camera::framing(lo, hi, 1.6, 35.0);
        o
    }

    /// Pixel coordinates and depth of `p` as the kernels project (render.cuh: project).
    fn project(r: &RenderParams, p: Vec3) -> (f32, f32, f32) {
        let d = p - Vec3::from(r.eye);
        let z = d.dot(Vec3::from(r.fwd));
        let s = r.focal / z;
        (
            r.cx + d.dot(Vec3::from(r.right)) * s,
            r.cy - d.dot(Vec3::from(r.up)) * s,
            z,
        )
    }

    #[test]
    fn the_camera_light_and_shadow_map_are_the_cpu_renderers() {
        let o = opts();
        let r = params(&o).unwrap();
        let v = o.camera.view(o.width, o.height);
        assert_eq!(r.eye, v.pos.to_array());
        assert_eq!(
            (r.fwd, r.right, r.up),
            (v.fwd.to_array(), v.right.to_array(), v.up.to_array())
        );
        assert_eq!((r.focal, r.cx, r.cy), (v.focal, 160.0, 100.0));
        // The target is at the centre, a point above it above the centre (y grows downwards).
        let (x, y, z) = project(&r, o.camera.target);
        assert!((x - 160.0).abs() < 1e-3 && (y - 100.0).abs() < 1e-3 && z > 0.0);
        assert!(project(&r, o.camera.target + Vec3::Y * 0.1).1 < 100.0);
        assert_eq!((r.near, r.radius), (0.004, 0.004));
        assert!((r.eps1 * r.focal - 0.25).abs() < 1e-6);
        let sf = ShadowFrame::new(o.bounds, o.radius);
        assert_eq!(r.shadow_origin, sf.origin.to_array());
        assert_eq!(
            (r.shadow_fwd, r.shadow_scale),
            (sf.fwd.to_array(), sf.scale)
        );
        assert_eq!(r.light, LIGHT.normalize().to_array());
        assert_eq!(r.object_rgb, COLLIDER_COLOR);
        assert_eq!((r.floor, r.floor_y), (1, 0.1));
        assert_eq!((r.width, r.height, r.channels, r.shadows), (320, 200, 3, 1));
    }

    #[test]
    fn the_range_is_found_on_the_gpu_only_for_a_field_without_one() {
        let mut o = opts();
        assert_eq!(params(&o).unwrap().auto_range, 0);
        o.color_by = ColorBy::Stress;
        let r = params(&o).unwrap();
        assert_eq!((r.auto_range, r.color_by), (1, color_code(ColorBy::Stress)));
        o.range = Some((2.0, 5.0));
        let r = params(&o).unwrap();
        assert_eq!((r.auto_range, r.range), (0, [2.0, 5.0]));
        o.floor = None;
        o.shadows = false;
        let r = params(&o).unwrap();
        assert_eq!((r.floor, r.shadows), (0, 0));
    }

    #[test]
    fn bad_options_are_refused_as_the_cpu_renderer_refuses_them() {
        let mut o = opts();
        o.width = 0;
        assert!(params(&o).unwrap_err().contains("out of range"));
        o.width = MAX_SIDE + 1;
        assert!(params(&o).is_err());
        o.width = 10;
        o.radius = -1.0;
        assert!(params(&o).unwrap_err().contains("radius"));
        o.radius = 0.01;
        o.camera.target = o.camera.position;
        assert!(params(&o).is_err());
    }

    #[test]
    fn the_palette_is_the_options_or_the_fixed_one() {
        let mut o = opts();
        assert_eq!(palette(&o).len(), 3 * colormap::PALETTE.len());
        assert_eq!(&palette(&o)[..3], &colormap::PALETTE[0]);
        o.palette = vec![[0.1, 0.2, 0.3]];
        assert_eq!(palette(&o), vec![0.1, 0.2, 0.3]);
    }

    fn collider(shape: Shape) -> Collider {
        Collider {
            shape,
            rule: BoundaryRule {
                condition: Condition::Slip,
                friction: 0.3,
            },
            velocity: Vec3::new(0.5, 0.0, 0.0),
            angular_velocity: Vec3::ZERO,
            pivot: Vec3::new(0.3, 0.3, 0.3),
            keyframes: None,
        }
    }

    #[test]
    fn objects_are_posed_at_the_time_clipped_to_the_box_and_padded() {
        let clip = (Vec3::ZERO, Vec3::ONE);
        let ball = collider(Shape::Sphere(rtmpm_geometry::shape::Sphere {
            center: Vec3::new(0.3, 0.3, 0.3),
            radius: 0.1,
        }));
        let o = collider_object(&ball, 0, 0.2, clip).unwrap();
        // Moved by 0.1 along x at t = 0.2.
        assert_eq!(o.pivot, [0.4, 0.3, 0.3]);
        assert_eq!(o.shape.pivot, [0.3, 0.3, 0.3]);
        assert_eq!(&o.shape.p[..4], &[0.3, 0.3, 0.3, 0.1]);
        assert_eq!((o.shape.friction, o.plane), (0.3, 0));
        let pad = 1e-4 + 1e-3 * 0.2;
        assert!((o.lo[0] - (0.3 - pad)).abs() < 1e-6 && (o.hi[0] - (0.5 + pad)).abs() < 1e-6);
        // Out of the box: not drawn.
        assert!(collider_object(&ball, 0, 10.0, clip).is_none());
        // A half-space: its plane in the world, bounded by the box.
        let floor = collider(Shape::HalfSpace(rtmpm_geometry::shape::HalfSpace {
            point: Vec3::new(0.3, 0.2, 0.3),
            normal: Vec3::Y,
        }));
        let o = collider_object(&floor, 0, 0.0, clip).unwrap();
        assert_eq!(
            (o.plane, o.plane_p, o.plane_n),
            (1, [0.3, 0.2, 0.3], [0.0, 1.0, 0.0])
        );
        assert!(o.lo[1] < 0.0 && o.hi[1] > 1.0);
        // The tool: a motionless world shape.
        let t = collider_object(
            &tool_collider(Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                Vec3::splat(0.5),
                Vec3::splat(0.1),
            ))),
            0,
            3.0,
            clip,
        )
        .unwrap();
        assert_eq!((t.pivot, t.shape.pivot), ([0.0; 3], [0.0; 3]));
        assert_eq!(t.rot, rtmpm_physics::math::Mat3::IDENTITY.to_cols_array());
    }

    #[test]
    fn the_structs_have_the_sizes_the_kernels_check() {
        assert_eq!(size_of::<RenderParams>(), 280);
        assert_eq!(size_of::<RenderObject>(), 176);
        let a = crate::contract::layout_asserts(false);
        assert!(a.contains("static_assert(sizeof(RenderParams) == 280,"));
        assert!(a.contains("static_assert(offsetof(RenderObject, plane) == 172,"));
        assert!(a.contains("static_assert(sizeof(GpuTool) == 92,"));
    }
}
