// The shape of a collider, a rigid body or the user's tool on the device (GpuCollider: the
// shape in its rest pose), read by the grid update and by the render stage (render/objects.cu),
// which sphere-traces it: the shape's own formulas (geometry/<name>.cuh, dispatched on its kind
// code by the generated geometry/registry.cuh) in `real`.
#pragma once
#include "common.cuh"
#include "geometry/registry.cuh"

__device__ __forceinline__ vec3 normalize_or_y(vec3 v) {
    real l = length(v);
    if (l > 0 && isfinite(l)) return v * ((real)1 / l);
    return make_v3(0, 1, 0);
}
__device__ __forceinline__ vec3 v3f(const float* p) { return make_v3(p[0], p[1], p[2]); }

// The arithmetic of the shapes' formulas here (geometry/geometry.cuh): `real`, as the compiler
// rounds it.
struct RealArith {
    typedef real T;
    static GEO_MEMBER real add(real a, real b) { return a + b; }
    static GEO_MEMBER real sub(real a, real b) { return a - b; }
    static GEO_MEMBER real mul(real a, real b) { return a * b; }
    static GEO_MEMBER real div(real a, real b) { return a / b; }
    static GEO_MEMBER real sqrt(real a) { return ::sqrt(a); }
    static GEO_MEMBER real abs(real a) { return fabs(a); }
    static GEO_MEMBER real max(real a, real b) { return fmax(a, b); }
    static GEO_MEMBER real min(real a, real b) { return fmin(a, b); }
    static GEO_MEMBER real floor(real a) { return ::floor(a); }
    static GEO_MEMBER bool lt(real a, real b) { return a < b; }
    static GEO_MEMBER bool le(real a, real b) { return a <= b; }
    static GEO_MEMBER bool gt(real a, real b) { return a > b; }
    static GEO_MEMBER bool ge(real a, real b) { return a >= b; }
    static GEO_MEMBER bool ne(real a, real b) { return a != b; }
    static GEO_MEMBER real of(float a) { return (real)a; }
    static GEO_MEMBER real of_u(unsigned a) { return (real)a; }
    static GEO_MEMBER unsigned to_u(real a) { return (unsigned)a; }
};

// The shape's parameters; a mesh's distance grid in the backend's mesh table.
__device__ __forceinline__ GeoShape geo_shape(const Ctx& c, const GpuCollider& col) {
    GeoShape g;
    g.p = col.p;
    g.dims = col.dims;
    g.values = c.mesh_values + col.mesh_offset;
    return g;
}

// Signed distance (negative inside) of the rest-pose shape (rtmpm_geometry::Shape::distance).
__device__ real shape_distance(const Ctx& c, const GpuCollider& col, vec3 x) {
    real xs[3] = {x.x, x.y, x.z};
    return shape_distance_of<RealArith>(col.kind, geo_shape(c, col), xs);
}

// Outward unit normal of the rest-pose shape (rtmpm_geometry::Shape::normal).
__device__ vec3 shape_normal(const Ctx& c, const GpuCollider& col, vec3 x) {
    real xs[3] = {x.x, x.y, x.z}, n[3];
    shape_normal_of<RealArith>(col.kind, geo_shape(c, col), xs, n);
    return make_v3(n[0], n[1], n[2]);
}
