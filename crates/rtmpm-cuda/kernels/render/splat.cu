// The render stage's clear and splats (render.cuh): the G-buffer of the camera and the light's
// shadow map, one thread a particle, from the particle state in place.
#include "render.cuh"

// Empty keys, an empty shadow map (infinitely far) and the range's minimum and maximum.
extern "C" __global__ void render_clear(RenderParams r) {
    unsigned n_pix = r.width * r.height;
    unsigned stride = gridDim.x * blockDim.x;
    for (unsigned i = thread_index(); i < n_pix; i += stride) r.keys[i] = RENDER_EMPTY;
    if (r.shadows)
        for (unsigned i = thread_index(); i < RENDER_SHADOW_RES * RENDER_SHADOW_RES; i += stride)
            r.shadow[i] = order_bits(RENDER_INF);
    if (r.auto_range)
        for (unsigned i = thread_index(); i < RS_WORDS; i += stride)
            r.scratch[i] = i == RS_MIN ? 0xffffffffu : 0u;
}

// Every particle in front of the near plane, as a sphere: each covered pixel keeps the smaller of
// its key and (depth of the sphere's surface there << 32 | slot). One thread a particle. A plain read first skips the
// atomic where the pixel already holds something nearer (most of a dense block's particles).
extern "C" __global__ void render_splat(Ctx c, RenderParams r) {
    for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
        f3 p = project(r, particle_x(c, i));
        if (!(p.z > r.near) || !isfinite(p.x) || !isfinite(p.y)) continue;
        float rad = splat_radius(r, p.z);
        splat_pixels(p.x, p.y, rad, r.width, r.height, [&](int x, int y, float u, float v) {
            float d = p.z - sqrtf(fmaxf(1.f - u * u - v * v, 0.f)) * r.radius;
            unsigned long long key = ((unsigned long long)order_bits(d) << 32) | i;
            unsigned long long* at = r.keys + (size_t)y * r.width + x;
            if (key < *at) atomicMin(at, key);
        });
    }
}

// The light's orthographic depth map of the particles (ShadowMap::build).
extern "C" __global__ void render_shadow_splat(Ctx c, RenderParams r) {
    for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
        f3 x = particle_x(c, i);
        if (!isfinite(x.x) || !isfinite(x.y) || !isfinite(x.z)) continue;
        f3 d = x - ld3(r.shadow_origin);
        float sx = dot3(d, ld3(r.shadow_right)) * r.shadow_scale;
        float sy = -dot3(d, ld3(r.shadow_up)) * r.shadow_scale;
        float sz = dot3(d, ld3(r.shadow_fwd));
        float rad = fmaxf(r.radius * r.shadow_scale, 0.75f);
        splat_pixels(sx, sy, rad, RENDER_SHADOW_RES, RENDER_SHADOW_RES, [&](int px, int py, float u, float v) {
            unsigned o = order_bits(sz - sqrtf(fmaxf(1.f - u * u - v * v, 0.f)) * r.radius);
            unsigned* at = r.shadow + py * RENDER_SHADOW_RES + px;
            if (o < *at) atomicMin(at, o);
        });
    }
}
