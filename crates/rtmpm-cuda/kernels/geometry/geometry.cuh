// The device twins of the shapes of rtmpm_geometry::shape: one header per shape
// (geometry/<name>.cuh: <name>_distance, <name>_normal, <name>_contains), included and dispatched
// on the shape's kind code by geometry/registry.cuh, which src/contract/headers.rs generates from
// rtmpm_geometry::Shape::ALL. Each formula is written once, for an arithmetic A: the grid update's
// and the render stage's `real` (RealArith, sdf.cuh) and the device sampler's f32 rounded
// operation by operation as on the host (SpArith, sample.cuh), where a point is inside a body
// exactly when the host says so. A shape reads its parameters as its Rust file's `gpu()` writes
// them (GeoShape). This header compiles for the CPU too (the sampler's twin tests,
// src/setup/sample/tests.rs).
//
// An arithmetic A has a type T and static functions: add, sub, mul, div, sqrt, abs, max, min,
// floor (T, T) -> T; lt, le, gt, ge, ne (T, T) -> bool; of (float) -> T; of_u (unsigned) -> T;
// to_u (T) -> unsigned (truncated, for T >= 0).
#pragma once

#if defined(__CUDACC__)
#define GEO_FN __device__ __forceinline__
#define GEO_MEMBER __device__ __forceinline__
#else
#define GEO_FN static inline
#define GEO_MEMBER inline
#endif

// A shape's parameters on the device (rtmpm_geometry::shape::GpuParams): eight floats, and a
// mesh's distance grid (its dims, its values x fastest; else unused).
struct GeoShape {
    const float* p;
    const unsigned* dims;
    const float* values;
};

// The largest finite f32: a distance "far outside".
#define GEO_FAR 3.402823466e38f

// glam's Vec3::dot: (a.x b.x + a.y b.y) + a.z b.z.
template <class A, class T = typename A::T>
GEO_FN T geo_dot(const T* a, const T* b) {
    return A::add(A::add(A::mul(a[0], b[0]), A::mul(a[1], b[1])), A::mul(a[2], b[2]));
}

// glam's Vec3::length.
template <class A, class T = typename A::T>
GEO_FN T geo_length(const T* a) {
    return A::sqrt(geo_dot<A>(a, a));
}

// out = x - p[0..3].
template <class A, class T = typename A::T>
GEO_FN void geo_minus(const T* x, const float* p, T* out) {
    for (int a = 0; a < 3; ++a) out[a] = A::sub(x[a], A::of(p[a]));
}

// glam's try_normalize(v).unwrap_or(Vec3::Y): v times the reciprocal of its length where that
// is finite and positive, else (0, 1, 0).
template <class A, class T = typename A::T>
GEO_FN void geo_unit_or_y(T* v) {
    T rcp = A::div(A::of(1.0f), geo_length<A>(v));
    if (A::gt(rcp, A::of(0.0f)) && A::le(rcp, A::of(GEO_FAR))) {
        for (int a = 0; a < 3; ++a) v[a] = A::mul(v[a], rcp);
    } else {
        v[0] = A::of(0.0f);
        v[1] = A::of(1.0f);
        v[2] = A::of(0.0f);
    }
}
