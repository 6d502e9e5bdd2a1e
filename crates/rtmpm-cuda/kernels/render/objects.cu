// Colliders, rigid bodies and the user's tool in the picture (colliders.rs of the CPU renderer):
// each object's signed distance, clipped to the scene box, sphere-traced through every pixel after
// the particles' splat (a hit nearer than the pixel's key replaces it) and through every texel of
// the light's shadow map (so objects cast shadows).
#include "render.cuh"

extern "C" __global__ void render_objects(Ctx c, RenderParams r) {
    unsigned n_pix = r.width * r.height;
    for (unsigned t = thread_index(); t < n_pix; t += gridDim.x * blockDim.x) {
        unsigned x = t % r.width, y = t / r.width;
        f3 ray = view_ray(r, (float)x + 0.5f, (float)y + 0.5f);
        unsigned long long key = r.keys[t];
        float depth = key_depth(key);
        for (unsigned k = 0; k < r.n_objects; ++k) {
            float s = object_trace(c, r, r.objects[k], ld3(r.eye), ray, depth, 1e-6f, r.eps1);
            if (!(s > r.near) || !(s < depth)) continue;
            depth = s;
            key = ((unsigned long long)order_bits(s) << 32) | (RENDER_OBJECT_ID + k);
        }
        r.keys[t] = key;
    }
}

extern "C" __global__ void render_shadow_objects(Ctx c, RenderParams r) {
    float texel = 1.f / r.shadow_scale;
    f3 fwd = ld3(r.shadow_fwd);
    for (unsigned t = thread_index(); t < RENDER_SHADOW_RES * RENDER_SHADOW_RES; t += gridDim.x * blockDim.x) {
        unsigned x = t % RENDER_SHADOW_RES, y = t / RENDER_SHADOW_RES;
        f3 o = ld3(r.shadow_origin) + ld3(r.shadow_right) * (((float)x + 0.5f) * texel) -
               ld3(r.shadow_up) * (((float)y + 0.5f) * texel);
        float d = order_float(r.shadow[t]);
        bool hit = false;
        for (unsigned k = 0; k < r.n_objects; ++k) {
            float s = object_trace(c, r, r.objects[k], o, fwd, d, 0.25f * texel, 0.f);
            if (s < d) {
                d = s;
                hit = true;
            }
        }
        if (hit) r.shadow[t] = order_bits(d);
    }
}
