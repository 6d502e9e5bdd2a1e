// A ball (rtmpm-geometry/src/shape/sphere.rs): p[0..3] its centre, p[3] its radius.
#pragma once
#include "geometry.cuh"

template <class A, class T = typename A::T>
GEO_FN T sphere_distance(const GeoShape& g, const T* x) {
    T d[3];
    geo_minus<A>(x, g.p, d);
    return A::sub(geo_length<A>(d), A::of(g.p[3]));
}

template <class A, class T = typename A::T>
GEO_FN void sphere_normal(const GeoShape& g, const T* x, T* n) {
    geo_minus<A>(x, g.p, n);
    geo_unit_or_y<A>(n);
}

// |x - c|^2 <= r^2: the surface included.
template <class A, class T = typename A::T>
GEO_FN bool sphere_contains(const GeoShape& g, const T* x) {
    T d[3];
    geo_minus<A>(x, g.p, d);
    T r = A::of(g.p[3]);
    return A::le(geo_dot<A>(d, d), A::mul(r, r));
}
