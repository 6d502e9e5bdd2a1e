// A capped cylinder (rtmpm-geometry/src/shape/cylinder.rs): p[0..3] its centre, p[3..6] its
// unit axis, p[6] its radius, p[7] its half height.
#pragma once
#include "geometry.cuh"

// The offset from the axis q - h a (radial), the height h along the axis, and the distances
// beyond the mantle (dr) and beyond the caps (dh).
template <class A, class T = typename A::T>
GEO_FN void cylinder_parts(const GeoShape& g, const T* x, T* radial, T* h, T* r, T* dr, T* dh) {
    T q[3], axis[3] = {A::of(g.p[3]), A::of(g.p[4]), A::of(g.p[5])};
    geo_minus<A>(x, g.p, q);
    *h = geo_dot<A>(q, axis);
    for (int a = 0; a < 3; ++a) radial[a] = A::sub(q[a], A::mul(*h, axis[a]));
    *r = geo_length<A>(radial);
    *dr = A::sub(*r, A::of(g.p[6]));
    *dh = A::sub(A::abs(*h), A::of(g.p[7]));
}

template <class A, class T = typename A::T>
GEO_FN T cylinder_distance(const GeoShape& g, const T* x) {
    T radial[3], h, r, dr, dh;
    cylinder_parts<A>(g, x, radial, &h, &r, &dr, &dh);
    T ox = A::max(dr, A::of(0.0f)), oy = A::max(dh, A::of(0.0f));
    return A::add(A::sqrt(A::add(A::mul(ox, ox), A::mul(oy, oy))), A::min(A::max(dr, dh), A::of(0.0f)));
}

// The mantle's, a cap's or (beyond both) the rim's outward normal.
template <class A, class T = typename A::T>
GEO_FN void cylinder_normal(const GeoShape& g, const T* x, T* n) {
    T radial[3], h, r, dr, dh, er[3], ea[3];
    cylinder_parts<A>(g, x, radial, &h, &r, &dr, &dh);
    T zero = A::of(0.0f);
    for (int a = 0; a < 3; ++a) ea[a] = A::ge(h, zero) ? A::of(g.p[3 + a]) : A::mul(A::of(-1.0f), A::of(g.p[3 + a]));
    if (A::gt(r, zero)) {
        for (int a = 0; a < 3; ++a) er[a] = A::div(radial[a], r);
    } else {
        // Any unit vector perpendicular to the axis: axis x (x or y).
        T ax[3] = {A::of(g.p[3]), A::of(g.p[4]), A::of(g.p[5])};
        T t[3] = {zero, zero, zero};
        t[A::lt(A::abs(ax[0]), A::of(0.9f)) ? 0 : 1] = A::of(1.0f);
        er[0] = A::sub(A::mul(ax[1], t[2]), A::mul(t[1], ax[2]));
        er[1] = A::sub(A::mul(ax[2], t[0]), A::mul(t[2], ax[0]));
        er[2] = A::sub(A::mul(ax[0], t[1]), A::mul(t[0], ax[1]));
        geo_unit_or_y<A>(er);
    }
    if (A::gt(dr, zero) && A::gt(dh, zero)) {
        for (int a = 0; a < 3; ++a) n[a] = A::add(A::mul(er[a], dr), A::mul(ea[a], dh));
        geo_unit_or_y<A>(n);
        return;
    }
    bool mantle = A::gt(dr, zero) || (A::le(dr, zero) && A::le(dh, zero) && A::ge(dr, dh));
    for (int a = 0; a < 3; ++a) n[a] = mantle ? er[a] : ea[a];
}

// Distance <= 0: the surface included.
template <class A, class T = typename A::T>
GEO_FN bool cylinder_contains(const GeoShape& g, const T* x) {
    return A::le(cylinder_distance<A>(g, x), A::of(0.0f));
}
