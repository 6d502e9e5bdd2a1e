// The resolve of the render stage: one thread a pixel shades what its key holds (a particle's
// sphere, an object's surface, the floor or the sky) as the CPU renderer's shading pass does
// (rtmpm_render::render: Lambert and ambient light, shadow, depth darkening from eight
// neighbours, a rim light on spheres; checkered floor fading into the sky far from the scene).
#include "render.cuh"

// The colour of particle slot i before shading (palette by material, or viridis of its field).
__device__ f3 particle_colour(const Ctx& c, const RenderParams& r, unsigned i) {
    if (r.color_by == RENDER_COLOR_MATERIAL) {
        unsigned m = state_word_bits(c.state, c.cap, F_MAT, i) % r.n_palette;
        return ld3(r.palette + 3 * m);
    }
    float lo = r.range[0], hi = r.range[1];
    if (r.auto_range) {
        lo = __uint_as_float(r.scratch[RS_LO]);
        hi = __uint_as_float(r.scratch[RS_HI]);
    }
    float inv = hi > lo ? 1.f / (hi - lo) : 0.f;
    return viridis((r.field[i] - lo) * inv);
}

// Depth darkening: the share of eight neighbours at ao_r pixels clearly in front of depth.
__device__ float occlusion(const RenderParams& r, int x, int y, float depth) {
    int ao = max((int)r.height / 140, 2);
    int d7 = ao * 7 / 10;
    const int off[8][2] = {{ao, 0}, {-ao, 0}, {0, ao}, {0, -ao}, {d7, d7}, {-d7, d7}, {d7, -d7}, {-d7, -d7}};
    float occ = 0.f;
    for (int k = 0; k < 8; ++k) {
        int sx = x + off[k][0], sy = y + off[k][1];
        if (sx < 0 || sy < 0 || sx >= (int)r.width || sy >= (int)r.height) continue;
        float d = depth - key_depth(r.keys[(size_t)sy * r.width + sx]);
        if (d > 0.5f * r.radius && d < 12.f * r.radius) occ += 1.f;
    }
    return 1.f - 0.55f * occ / 8.f;
}

// A particle's sphere or an object's surface at depth along the ray of pixel (x, y).
__device__ f3 shade_surface(const Ctx& c, const RenderParams& r, int x, int y, f3 ray, unsigned long long key) {
    float depth = key_depth(key);
    unsigned id = (unsigned)key;
    f3 right = ld3(r.right), up = ld3(r.up), fwd = ld3(r.fwd);
    float u, v, rim;
    f3 base;
    if (id >= RENDER_OBJECT_ID) {
        const RenderObject& o = r.objects[id - RENDER_OBJECT_ID];
        f3 p = ld3(r.eye) + ray * depth;
        f3 n = object_normal(c, r, o, p, fmaxf(2.f * r.eps1 * depth, 1e-5f));
        u = dot3(n, right);
        v = -dot3(n, up);
        base = ld3(r.object_rgb);
        rim = 0.f;
    } else {
        f3 s = project(r, particle_x(c, id));
        float rad = splat_radius(r, s.z);
        u = ((float)x + 0.5f - s.x) / rad;
        v = ((float)y + 0.5f - s.y) / rad;
        base = particle_colour(c, r, id);
        rim = -1.f;
    }
    float nz = sqrtf(fmaxf(1.f - u * u - v * v, 0.f));
    if (rim < 0.f) rim = 0.12f * (1.f - nz) * (1.f - nz);
    f3 normal = right * u - up * v - fwd * nz;
    f3 p = ld3(r.eye) + ray * depth;
    f3 light = ld3(r.light);
    float lambert = fmaxf(dot3(normal, light), 0.f);
    float lit = r.shadows ? shadow_light(r, p + normal * (0.5f * r.radius), 2.f * r.radius) : 1.f;
    float ao = occlusion(r, x, y, depth);
    float k = 0.32f * ao + 0.68f * lambert * (0.5f + 0.5f * lit);
    float add = rim * ao;
    return mk3(base.x * k + add, base.y * k + add, base.z * k + add);
}

// The floor at distance ground_t along the ray: checkers inside the scene box, fading into the sky.
__device__ f3 shade_floor(const RenderParams& r, f3 ray, float ground_t, f3 sky) {
    f3 blo = ld3(r.bounds_lo), bhi = ld3(r.bounds_hi);
    f3 ext = bhi - blo;
    float bsize = fmaxf(fmaxf(ext.x, fmaxf(ext.y, ext.z)), 1e-6f);
    float checker = bsize / 12.f;
    f3 p = ld3(r.eye) + ray * ground_t;
    bool inside = p.x >= blo.x && p.x <= bhi.x && p.z >= blo.z && p.z <= bhi.z;
    float albedo = 0.55f;
    if (inside) {
        long long k = (long long)floorf(p.x / checker) + (long long)floorf(p.z / checker);
        albedo = (k & 1) == 0 ? 0.80f : 0.70f;
    }
    float lit = r.shadows ? shadow_light(r, p, 0.5f * r.radius) : 1.f;
    float g = albedo * (0.35f + 0.65f * r.light[1] * (0.3f + 0.7f * lit));
    f3 centre = (blo + bhi) * 0.5f;
    f3 d = p - centre;
    float dist = sqrtf(d.x * d.x + d.z * d.z) / bsize;
    float fade = expf(-fmaxf(dist - 0.6f, 0.f) * 1.2f);
    return mk3(g, g, g) * fade + sky * (1.f - fade);
}

extern "C" __global__ void render_resolve(Ctx c, RenderParams r) {
    unsigned n_pix = r.width * r.height;
    for (unsigned t = thread_index(); t < n_pix; t += gridDim.x * blockDim.x) {
        int x = (int)(t % r.width), y = (int)(t / r.width);
        float sky_t = (float)y / (float)r.height;
        f3 sky = mk3(0.15f, 0.17f, 0.21f) * (1.f - sky_t) + mk3(0.36f, 0.38f, 0.43f) * sky_t;
        f3 ray = view_ray(r, (float)x + 0.5f, (float)y + 0.5f);
        float ground_t = (r.floor && ray.y < 0.f && r.eye[1] > r.floor_y) ? (r.floor_y - r.eye[1]) / ray.y : RENDER_INF;
        unsigned long long key = r.keys[t];
        f3 col = sky;
        if (key_depth(key) < ground_t) col = shade_surface(c, r, x, y, ray, key);
        else if (isfinite(ground_t)) col = shade_floor(r, ray, ground_t, sky);
        unsigned cr = to_u8(col.x), cg = to_u8(col.y), cb = to_u8(col.z);
        if (r.channels == 4) {
            r.image[t] = cr | (cg << 8) | (cb << 16) | 0xff000000u;
        } else {
            unsigned char* b = reinterpret_cast<unsigned char*>(r.image) + 3 * (size_t)t;
            b[0] = (unsigned char)cr;
            b[1] = (unsigned char)cg;
            b[2] = (unsigned char)cb;
        }
    }
}
