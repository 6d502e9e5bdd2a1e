// Signed distances and outward normals of the collider shapes (rtmpm_geometry::sdf::Shape,
// in the rest pose), read by the grid update (colliders, rigid bodies, the user's tool) and by the
// render stage (render/objects.cu), which sphere-traces them.
#pragma once
#include "common.cuh"

__device__ __forceinline__ vec3 normalize_or_y(vec3 v) {
    real l = length(v);
    if (l > 0 && isfinite(l)) return v * ((real)1 / l);
    return make_v3(0, 1, 0);
}
__device__ __forceinline__ vec3 v3f(const float* p) { return make_v3(p[0], p[1], p[2]); }
__device__ __forceinline__ real sgn1(real x) { return x < 0 ? (real)-1 : (real)1; }

__device__ real mesh_distance(const Ctx& c, const GpuCollider& col, vec3 x) {
    const float* vals = c.mesh_values + col.mesh_offset;
    real o[3] = {col.p[0], col.p[1], col.p[2]};
    real h = col.p[3];
    real xs[3] = {x.x, x.y, x.z};
    real out2 = 0;
    int b[3]; real fr[3];
    for (int a = 0; a < 3; ++a) {
        int d = (int)col.dims[a];
        real gmax = o[a] + (real)(d - 1) * h;
        real cl = fmin(fmax(xs[a], o[a]), gmax);
        out2 += (xs[a] - cl) * (xs[a] - cl);
        real g = (cl - o[a]) / h;
        if (d < 2) { b[a] = 0; fr[a] = 0; continue; }
        int bb = (int)fmax(floor(g), (real)0);
        bb = min(bb, d - 2);
        b[a] = bb;
        fr[a] = fmin(fmax(g - (real)bb, (real)0), (real)1);
    }
    real v = 0;
    for (int corner = 0; corner < 8; ++corner) {
        int ix[3]; real w = 1;
        for (int a = 0; a < 3; ++a) {
            int oa = (corner >> a) & 1;
            ix[a] = min(b[a] + oa, (int)col.dims[a] - 1);
            w *= oa ? fr[a] : (real)1 - fr[a];
        }
        v += w * vals[ix[0] + col.dims[0] * (ix[1] + col.dims[1] * ix[2])];
    }
    return v + sqrt(out2);
}

// Signed distance (negative inside) of the rest-pose shape (rtmpm_geometry::sdf::Shape).
__device__ real shape_distance(const Ctx& c, const GpuCollider& col, vec3 x) {
    const float* p = col.p;
    switch (col.kind) {
    case COLLIDER_HALF_SPACE: return dot(x - v3f(p), v3f(p + 3));
    case COLLIDER_BOX: {
        vec3 q = x - v3f(p);
        q = make_v3(fabs(q.x) - p[3], fabs(q.y) - p[4], fabs(q.z) - p[5]);
        vec3 qp = make_v3(fmax(q.x, (real)0), fmax(q.y, (real)0), fmax(q.z, (real)0));
        return length(qp) + fmin(fmax(q.x, fmax(q.y, q.z)), (real)0);
    }
    case COLLIDER_SPHERE: return length(x - v3f(p)) - p[3];
    case COLLIDER_CYLINDER: {
        vec3 a = v3f(p + 3);
        vec3 q = x - v3f(p);
        real h = dot(q, a);
        real r = length(q - a * h);
        real dr = r - p[6], dh = fabs(h) - p[7];
        real ox = fmax(dr, (real)0), oy = fmax(dh, (real)0);
        return sqrt(ox * ox + oy * oy) + fmin(fmax(dr, dh), (real)0);
    }
    default: return mesh_distance(c, col, x);
    }
}

__device__ vec3 shape_normal(const Ctx& c, const GpuCollider& col, vec3 x) {
    const float* p = col.p;
    switch (col.kind) {
    case COLLIDER_HALF_SPACE: return v3f(p + 3);
    case COLLIDER_BOX: {
        vec3 d = x - v3f(p);
        vec3 q = make_v3(fabs(d.x) - p[3], fabs(d.y) - p[4], fabs(d.z) - p[5]);
        vec3 s = make_v3(sgn1(d.x), sgn1(d.y), sgn1(d.z));
        if (fmax(q.x, fmax(q.y, q.z)) > 0)
            return normalize_or_y(make_v3(fmax(q.x, (real)0) * s.x, fmax(q.y, (real)0) * s.y, fmax(q.z, (real)0) * s.z));
        if (q.x >= q.y && q.x >= q.z) return make_v3(s.x, 0, 0);
        if (q.y >= q.z) return make_v3(0, s.y, 0);
        return make_v3(0, 0, s.z);
    }
    case COLLIDER_SPHERE: return normalize_or_y(x - v3f(p));
    case COLLIDER_CYLINDER: {
        vec3 a = v3f(p + 3);
        vec3 q = x - v3f(p);
        real h = dot(q, a);
        vec3 radial = q - a * h;
        real r = length(radial);
        vec3 er;
        if (r > 0) er = radial * ((real)1 / r);
        else {
            vec3 t = fabs(a.x) < (real)0.9 ? make_v3(1, 0, 0) : make_v3(0, 1, 0);
            er = normalize_or_y(cross(a, t));
        }
        vec3 ea = h >= 0 ? a : a * (real)-1;
        real dr = r - p[6], dh = fabs(h) - p[7];
        if (dr > 0 && dh > 0) return normalize_or_y(er * dr + ea * dh);
        if (dr > 0 || (dr <= 0 && dh <= 0 && dr >= dh)) return er;
        return ea;
    }
    default: {
        real e = (real)0.5 * p[3];
        vec3 g = make_v3(mesh_distance(c, col, x + make_v3(e, 0, 0)) - mesh_distance(c, col, x - make_v3(e, 0, 0)),
                         mesh_distance(c, col, x + make_v3(0, e, 0)) - mesh_distance(c, col, x - make_v3(0, e, 0)),
                         mesh_distance(c, col, x + make_v3(0, 0, e)) - mesh_distance(c, col, x - make_v3(0, 0, e)));
        return normalize_or_y(g);
    }
    }
}
