// An axis-aligned box (rtmpm-geometry/src/shape/cuboid.rs): p[0..3] its min, p[3..6] its max;
// its distance about its centre (min + max) / 2 with half-extents (max - min) / 2.
#pragma once
#include "geometry.cuh"

// q = |x - centre| - half-extents, and the sign of x - centre per axis.
template <class A, class T = typename A::T>
GEO_FN void box_offset(const GeoShape& g, const T* x, T* q, T* sign) {
    for (int a = 0; a < 3; ++a) {
        T lo = A::of(g.p[a]), hi = A::of(g.p[3 + a]);
        T c = A::mul(A::of(0.5f), A::add(lo, hi));
        T h = A::mul(A::of(0.5f), A::sub(hi, lo));
        T d = A::sub(x[a], c);
        q[a] = A::sub(A::abs(d), h);
        sign[a] = A::lt(d, A::of(0.0f)) ? A::of(-1.0f) : A::of(1.0f);
    }
}

template <class A, class T = typename A::T>
GEO_FN T box_distance(const GeoShape& g, const T* x) {
    T q[3], s[3], qp[3];
    box_offset<A>(g, x, q, s);
    for (int a = 0; a < 3; ++a) qp[a] = A::max(q[a], A::of(0.0f));
    return A::add(geo_length<A>(qp), A::min(A::max(q[0], A::max(q[1], q[2])), A::of(0.0f)));
}

// Outside: the gradient of the distance; inside: the face of least penetration.
template <class A, class T = typename A::T>
GEO_FN void box_normal(const GeoShape& g, const T* x, T* n) {
    T q[3], s[3];
    box_offset<A>(g, x, q, s);
    if (A::gt(A::max(q[0], A::max(q[1], q[2])), A::of(0.0f))) {
        for (int a = 0; a < 3; ++a) n[a] = A::mul(A::max(q[a], A::of(0.0f)), s[a]);
        geo_unit_or_y<A>(n);
        return;
    }
    int axis = (A::ge(q[0], q[1]) && A::ge(q[0], q[2])) ? 0 : (A::ge(q[1], q[2]) ? 1 : 2);
    for (int a = 0; a < 3; ++a) n[a] = a == axis ? s[a] : A::of(0.0f);
}

// The surface included.
template <class A, class T = typename A::T>
GEO_FN bool box_contains(const GeoShape& g, const T* x) {
    for (int a = 0; a < 3; ++a) {
        if (!(A::ge(x[a], A::of(g.p[a])) && A::le(x[a], A::of(g.p[3 + a])))) return false;
    }
    return true;
}
