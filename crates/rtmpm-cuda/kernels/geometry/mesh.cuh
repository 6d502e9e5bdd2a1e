// A mesh's signed distance grid (rtmpm-geometry/src/shape/mesh.rs, mesh/mod.rs MeshSdf):
// p[0..3] the grid's origin, p[3] its spacing; dims and values in GeoShape.
#pragma once
#include "geometry.cuh"

// MeshSdf::distance: trilinear in the grid; outside it, the distance to the grid's box plus the
// value at the nearest point of the box.
template <class A, class T = typename A::T>
GEO_FN T mesh_distance(const GeoShape& g, const T* x) {
    const unsigned* d = g.dims;
    T h = A::of(g.p[3]);
    T clamped[3], off[3], frac[3];
    unsigned base[3];
    for (int a = 0; a < 3; ++a) {
        T o = A::of(g.p[a]);
        T gmax = A::add(o, A::mul(A::of_u(d[a] - 1), h));
        clamped[a] = A::min(A::max(x[a], o), gmax);
        off[a] = A::sub(x[a], clamped[a]);
    }
    T outside = geo_length<A>(off);
    for (int a = 0; a < 3; ++a) {
        T ga = A::div(A::sub(clamped[a], A::of(g.p[a])), h);
        if (d[a] < 2) {
            base[a] = 0;
            frac[a] = A::of(0.0f);
            continue;
        }
        unsigned b = A::to_u(A::max(A::floor(ga), A::of(0.0f)));
        base[a] = b < d[a] - 2 ? b : d[a] - 2;
        T f = A::sub(ga, A::of_u(base[a]));
        frac[a] = A::lt(f, A::of(0.0f)) ? A::of(0.0f) : (A::gt(f, A::of(1.0f)) ? A::of(1.0f) : f);
    }
    T v = A::of(0.0f);
    for (int corner = 0; corner < 8; ++corner) {
        unsigned ix[3];
        T w = A::of(1.0f);
        for (int a = 0; a < 3; ++a) {
            unsigned o = (corner >> a) & 1;
            ix[a] = base[a] + o < d[a] - 1 ? base[a] + o : d[a] - 1;
            w = A::mul(w, o ? frac[a] : A::sub(A::of(1.0f), frac[a]));
        }
        unsigned long long at = ix[0] + (unsigned long long)d[0] * (ix[1] + (unsigned long long)d[1] * ix[2]);
        if (A::ne(w, A::of(0.0f))) v = A::add(v, A::mul(w, A::of(g.values[at])));
    }
    return A::add(v, outside);
}

// MeshSdf::normal: central differences of step half the grid spacing, normalised.
template <class A, class T = typename A::T>
GEO_FN void mesh_normal(const GeoShape& g, const T* x, T* n) {
    T e = A::mul(A::of(0.5f), A::of(g.p[3]));
    for (int a = 0; a < 3; ++a) {
        T xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
        xp[a] = A::add(x[a], e);
        xm[a] = A::sub(x[a], e);
        n[a] = A::sub(mesh_distance<A>(g, xp), mesh_distance<A>(g, xm));
    }
    geo_unit_or_y<A>(n);
}

// Distance < 0.
template <class A, class T = typename A::T>
GEO_FN bool mesh_contains(const GeoShape& g, const T* x) {
    return A::lt(mesh_distance<A>(g, x), A::of(0.0f));
}
