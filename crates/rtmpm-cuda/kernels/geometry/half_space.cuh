// A half-space (rtmpm-geometry/src/shape/half_space.rs): p[0..3] a point of its plane, p[3..6]
// its unit outward normal.
#pragma once
#include "geometry.cuh"

template <class A, class T = typename A::T>
GEO_FN T half_space_distance(const GeoShape& g, const T* x) {
    T d[3];
    geo_minus<A>(x, g.p, d);
    T n[3] = {A::of(g.p[3]), A::of(g.p[4]), A::of(g.p[5])};
    return geo_dot<A>(d, n);
}

template <class A, class T = typename A::T>
GEO_FN void half_space_normal(const GeoShape& g, const T*, T* n) {
    for (int a = 0; a < 3; ++a) n[a] = A::of(g.p[3 + a]);
}

template <class A, class T = typename A::T>
GEO_FN bool half_space_contains(const GeoShape& g, const T* x) {
    return A::le(half_space_distance<A>(g, x), A::of(0.0f));
}
