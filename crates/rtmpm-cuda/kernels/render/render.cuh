// The render stage of a live view (host side: src/render.rs): the particles drawn from the
// simulation's own state arrays as shaded spheres, the colliders, rigid bodies and the user's tool
// sphere-traced from their signed distances (sdf.cuh), a checkered floor and a sky, shaded as the
// CPU renderer shades a frame (rtmpm_render: the same camera model, palette, viridis, light,
// shadow map and depth darkening), so that the two pictures of one state agree.
//
// The passes, in stream order after the steps: clear; the field and its automatic range (colouring
// by a field); the light's shadow map (particles, then objects); the splat of every particle into
// a G-buffer of 64-bit keys, (depth << 32 | particle slot), by atomicMin (the nearest sphere surface
// of each pixel wins); the objects traced into the same keys; the resolve, one thread a pixel.
#pragma once
#include "../common.cuh"
#include "../sdf.cuh"

// src/contract/render.rs: RenderObject.
struct RenderObject {
    GpuCollider shape;  // rest pose
    float rot[9];       // rest -> world (column-major)
    float pivot[3];     // world position of shape.pivot
    float lo[3], hi[3]; // padded world bounds, clipped to the scene box
    float plane_p[3], plane_n[3];  // a half-space's plane (world)
    unsigned plane;     // 1: a half-space
};

// src/contract/render.rs: RenderParams.
struct RenderParams {
    unsigned long long* keys;    // per pixel
    unsigned* image;             // RGBA8 words (or RGB8 bytes, channels 3)
    unsigned* shadow;            // per shadow texel: order_bits(depth)
    float* field;                // per particle slot
    unsigned* scratch;           // RS_WORDS
    const RenderObject* objects;
    const float* palette;        // 3 per material
    float eye[3], fwd[3], right[3], up[3];
    float focal, cx, cy;
    float radius, near, eps1;
    float range[2];
    float floor_y;
    float bounds_lo[3], bounds_hi[3];
    float light[3];
    float object_rgb[3];
    float shadow_origin[3], shadow_right[3], shadow_up[3], shadow_fwd[3];
    float shadow_scale;
    unsigned width, height, color_by, auto_range, floor, shadows, n_objects, n_palette, channels, pad;
};

// +infinity (NVRTC has no math.h).
#define RENDER_INF __int_as_float(0x7f800000)

// Float vectors of the picture (the state may be double).
struct f3 { float x, y, z; };
__device__ __forceinline__ f3 mk3(float x, float y, float z) { f3 v; v.x = x; v.y = y; v.z = z; return v; }
__device__ __forceinline__ f3 ld3(const float* p) { return mk3(p[0], p[1], p[2]); }
__device__ __forceinline__ f3 operator+(f3 a, f3 b) { return mk3(a.x + b.x, a.y + b.y, a.z + b.z); }
__device__ __forceinline__ f3 operator-(f3 a, f3 b) { return mk3(a.x - b.x, a.y - b.y, a.z - b.z); }
__device__ __forceinline__ f3 operator*(f3 a, float s) { return mk3(a.x * s, a.y * s, a.z * s); }
__device__ __forceinline__ float dot3(f3 a, f3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
__device__ __forceinline__ float len3(f3 a) { return sqrtf(dot3(a, a)); }
__device__ __forceinline__ f3 abs3(f3 a) { return mk3(fabsf(a.x), fabsf(a.y), fabsf(a.z)); }
__device__ __forceinline__ float comp(f3 a, int k) { return k == 0 ? a.x : (k == 1 ? a.y : a.z); }

// Order-preserving bits of a float: a < b as floats <=> order_bits(a) < order_bits(b) as unsigned.
__device__ __forceinline__ unsigned order_bits(float f) {
    unsigned b = __float_as_uint(f);
    return (b & 0x80000000u) ? ~b : (b | 0x80000000u);
}
__device__ __forceinline__ float order_float(unsigned o) {
    return __uint_as_float((o & 0x80000000u) ? (o & 0x7fffffffu) : ~o);
}
#define RENDER_EMPTY 0xffffffffffffffffull
// The depth of a G-buffer key (infinity for an empty pixel).
__device__ __forceinline__ float key_depth(unsigned long long k) {
    return k == RENDER_EMPTY ? RENDER_INF : order_float((unsigned)(k >> 32));
}

// A particle's position as floats.
__device__ __forceinline__ f3 particle_x(const Ctx& c, unsigned i) {
    return mk3((float)c.state[sidx(c.cap, F_X, i)], (float)c.state[sidx(c.cap, F_X + 1, i)],
               (float)c.state[sidx(c.cap, F_X + 2, i)]);
}

// View::project of the CPU renderer: pixel coordinates (x right, y down) and view depth.
__device__ __forceinline__ f3 project(const RenderParams& r, f3 p) {
    f3 d = p - ld3(r.eye);
    float z = dot3(d, ld3(r.fwd));
    float s = r.focal / z;
    return mk3(r.cx + dot3(d, ld3(r.right)) * s, r.cy - dot3(d, ld3(r.up)) * s, z);
}
// View::ray: the direction through pixel coordinates (x, y), of component 1 along fwd.
__device__ __forceinline__ f3 view_ray(const RenderParams& r, float x, float y) {
    return ld3(r.fwd) + ld3(r.right) * ((x - r.cx) / r.focal) - ld3(r.up) * ((y - r.cy) / r.focal);
}

// A particle's radius on screen (pixels) at view depth z: at least 0.6 pixel, as the CPU
// renderer's; at most RENDER_MAX_SPLAT (a particle within a few radii of the eye, where one thread
// would otherwise cover most of the picture: the CPU renderer draws it whole).
#define RENDER_MAX_SPLAT 256.f
__device__ __forceinline__ float splat_radius(const RenderParams& r, float z) {
    return fminf(fmaxf(r.radius * r.focal / z, 0.6f), RENDER_MAX_SPLAT);
}

// The pixels a splat covers (raster.rs: the same rows, columns and test u^2 + v^2 < 1): for each,
// visit(px, py, u, v). Rows y0..=y1 clipped to the image, columns x0..=x1.
template <typename F>
__device__ __forceinline__ void splat_pixels(float sx, float sy, float rad, unsigned w, unsigned h, F visit) {
    float y0f = fmaxf(floorf(sy - rad), 0.f), y1f = fminf(ceilf(sy + rad), (float)h - 1.f);
    if (y1f < y0f || sx + rad < 0.f || sx - rad > (float)w) return;
    float inv = 1.f / rad;
    int x0 = (int)fmaxf(floorf(sx - rad), 0.f);
    int x1 = min((int)fmaxf(ceilf(sx + rad), 0.f), (int)w - 1);
    for (int y = (int)y0f; y <= (int)y1f; ++y) {
        float v = ((float)y + 0.5f - sy) * inv;
        float vv = v * v;
        if (vv >= 1.f) continue;
        for (int x = x0; x <= x1; ++x) {
            float u = ((float)x + 0.5f - sx) * inv;
            if (u * u + vv < 1.f) visit(x, y, u, v);
        }
    }
}

// ---- Objects (colliders.rs of the CPU renderer: PosedCollider) ----

__device__ __forceinline__ float box_dist(f3 x, f3 center, f3 half) {
    f3 q = abs3(x - center) - half;
    f3 qp = mk3(fmaxf(q.x, 0.f), fmaxf(q.y, 0.f), fmaxf(q.z, 0.f));
    return len3(qp) + fminf(fmaxf(q.x, fmaxf(q.y, q.z)), 0.f);
}
__device__ __forceinline__ f3 clip_center(const RenderParams& r) { return (ld3(r.bounds_lo) + ld3(r.bounds_hi)) * 0.5f; }
__device__ __forceinline__ f3 clip_half(const RenderParams& r) { return (ld3(r.bounds_hi) - ld3(r.bounds_lo)) * 0.5f; }

// Signed distance of the object clipped to the scene box.
__device__ float object_distance(const Ctx& c, const RenderParams& r, const RenderObject& o, f3 p) {
    f3 d = p - ld3(o.pivot);
    // rest = R^T (p - pivot_t) + shape.pivot
    vec3 rest = make_v3(o.rot[0] * d.x + o.rot[1] * d.y + o.rot[2] * d.z + o.shape.pivot[0],
                        o.rot[3] * d.x + o.rot[4] * d.y + o.rot[5] * d.z + o.shape.pivot[1],
                        o.rot[6] * d.x + o.rot[7] * d.y + o.rot[8] * d.z + o.shape.pivot[2]);
    float s = (float)shape_distance(c, o.shape, rest);
    return fmaxf(s, box_dist(p, clip_center(r), clip_half(r)));
}

// PosedCollider::normal: outward unit normal at the hit p, central differences of step h (a
// half-space: its plane's normal, or the box face's where the hit is on the clipping box).
__device__ f3 object_normal(const Ctx& c, const RenderParams& r, const RenderObject& o, f3 p, float h) {
    if (o.plane) {
        f3 q = abs3(p - clip_center(r)) - clip_half(r);
        int a = (q.x >= q.y && q.x >= q.z) ? 0 : (q.y >= q.z ? 1 : 2);
        if (comp(q, a) > -h) {
            float s = comp(p, a) - comp(clip_center(r), a);
            s = s > 0.f ? 1.f : (s < 0.f ? -1.f : 0.f);
            return mk3(a == 0 ? s : 0.f, a == 1 ? s : 0.f, a == 2 ? s : 0.f);
        }
        return ld3(o.plane_n);
    }
    f3 n = mk3(object_distance(c, r, o, p + mk3(h, 0, 0)) - object_distance(c, r, o, p - mk3(h, 0, 0)),
               object_distance(c, r, o, p + mk3(0, h, 0)) - object_distance(c, r, o, p - mk3(0, h, 0)),
               object_distance(c, r, o, p + mk3(0, 0, h)) - object_distance(c, r, o, p - mk3(0, 0, h)));
    float l = len3(n);
    return (l > 0.f && isfinite(l)) ? n * (1.f / l) : mk3(0, 1, 0);
}

// PosedCollider::trace: the first hit of origin + dir s below s_max, sphere tracing from the
// ray's entry into the padded bounds (96 steps at most), converged below eps0 + eps1 s; a
// half-space clipped to the box is intersected exactly. Returns infinity for none.
#define RENDER_TRACE_STEPS 96
__device__ float object_trace(const Ctx& c, const RenderParams& r, const RenderObject& o, f3 origin, f3 dir,
                              float s_max, float eps0, float eps1) {
    float s0 = 0.f, s1 = RENDER_INF;
    for (int a = 0; a < 3; ++a) {
        float da = comp(dir, a), oa = comp(origin, a);
        if (fabsf(da) < 1e-12f) {
            if (oa < o.lo[a] || oa > o.hi[a]) return RENDER_INF;
        } else {
            float inv = 1.f / da;
            float ta = (o.lo[a] - oa) * inv, tb = (o.hi[a] - oa) * inv;
            s0 = fmaxf(s0, fminf(ta, tb));
            s1 = fminf(s1, fmaxf(ta, tb));
        }
    }
    if (!(s0 <= s1)) return RENDER_INF;
    s1 = fminf(s1, s_max);
    if (o.plane) {
        f3 n = ld3(o.plane_n);
        float f0 = dot3(origin - ld3(o.plane_p), n), fd = dot3(dir, n);
        if (fabsf(fd) < 1e-12f) {
            if (f0 >= 0.f) return RENDER_INF;
        } else if (fd < 0.f) {
            s0 = fmaxf(s0, -f0 / fd);
        } else {
            s1 = fminf(s1, -f0 / fd);
        }
        return s0 <= s1 ? s0 : RENDER_INF;
    }
    float inv_len = 1.f / len3(dir);
    float s = s0;
    for (int k = 0; k < RENDER_TRACE_STEPS; ++k) {
        if (s > s1) return RENDER_INF;
        float d = object_distance(c, r, o, origin + dir * s);
        if (d < eps0 + eps1 * s) return s;
        s += d * inv_len;
    }
    return RENDER_INF;
}

// ---- Shading (render/mod.rs and shadow.rs of the CPU renderer) ----

// ShadowMap::light: the fraction of light reaching p (0: in shadow), 3x3 percentage-closer.
__device__ float shadow_light(const RenderParams& r, f3 p, float bias) {
    f3 d = p - ld3(r.shadow_origin);
    float x = dot3(d, ld3(r.shadow_right)) * r.shadow_scale;
    float y = -dot3(d, ld3(r.shadow_up)) * r.shadow_scale;
    float z = dot3(d, ld3(r.shadow_fwd)) - bias;
    long long xi = (long long)floorf(x), yi = (long long)floorf(y);
    float lit = 0.f;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            long long sx = xi + dx, sy = yi + dy;
            bool occluded = sx >= 0 && sy >= 0 && sx < RENDER_SHADOW_RES && sy < RENDER_SHADOW_RES &&
                            order_float(r.shadow[sy * RENDER_SHADOW_RES + sx]) < z;
            if (!occluded) lit += 1.f;
        }
    return lit / 9.f;
}

// colormap.rs: viridis at 0, 0.1, ..., 1, linearly interpolated; NaN maps to 0.
__device__ __forceinline__ f3 viridis(float t) {
    const float V[11][3] = {{0.267004f, 0.004874f, 0.329415f}, {0.282623f, 0.140926f, 0.457517f},
                            {0.253935f, 0.265254f, 0.529983f}, {0.206756f, 0.371758f, 0.553117f},
                            {0.163625f, 0.471133f, 0.558148f}, {0.127568f, 0.566949f, 0.550556f},
                            {0.134692f, 0.658636f, 0.517649f}, {0.266941f, 0.748751f, 0.440573f},
                            {0.477504f, 0.821444f, 0.318195f}, {0.741388f, 0.873449f, 0.149561f},
                            {0.993248f, 0.906157f, 0.143936f}};
    t = isnan(t) ? 0.f : fminf(fmaxf(t, 0.f), 1.f);
    float s = t * 10.f;
    int i = min((int)floorf(s), 9);
    float f = s - (float)i;
    return mk3(V[i][0] + (V[i + 1][0] - V[i][0]) * f, V[i][1] + (V[i + 1][1] - V[i][1]) * f,
               V[i][2] + (V[i + 1][2] - V[i][2]) * f);
}

// colormap::to_u8.
__device__ __forceinline__ unsigned to_u8(float c) { return (unsigned)(fminf(fmaxf(c, 0.f), 1.f) * 255.f + 0.5f); }
