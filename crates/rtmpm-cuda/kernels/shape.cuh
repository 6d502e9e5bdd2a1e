// Shape functions of the transfers: the mirror of rtmpm_physics::shape_function (and transfer::flip_blend),
// formula by formula. Quadratic B-splines (MLS-MPM), uGIMP with particle half-size dx/4
// (Bardenhagen & Kober 2004) and linear hats (Sulsky et al. 1994); every one is a tensor product
// of 1D weights over the same 3x3x3 stencil (base = floor(xg - 0.5), fx = xg - base in [0.5, 1.5)).
#pragma once
#include "contract.cuh"  // TRANSFER_* (Ctx::transfer)
#include "math.cuh"

// Quadratic B-spline weights of the three nodes of one axis (shape.rs: weights_1d).
__device__ __forceinline__ void weights_1d(real fx, real w[3]) {
    w[0] = (real)0.5 * ((real)1.5 - fx) * ((real)1.5 - fx);
    w[1] = (real)0.75 - (fx - (real)1.0) * (fx - (real)1.0);
    w[2] = (real)0.5 * (fx - (real)0.5) * (fx - (real)0.5);
}
// Their derivatives d w / d fx (shape.rs: dweights_1d).
__device__ __forceinline__ void dweights_1d(real fx, real d[3]) {
    d[0] = fx - (real)1.5;
    d[1] = (real)-2.0 * (fx - (real)1.0);
    d[2] = fx - (real)0.5;
}

// uGIMP half-size in cells (shape.rs: GIMP_HALF_SIZE).
#define GIMP_HALF_SIZE ((real)0.25)

// uGIMP weight and d S / d r at r = x_p - x_i in cells (shape.rs: gimp_1d; B&K 2004, eq. 31).
__device__ __forceinline__ void gimp_1d(real r, real* w, real* d) {
    const real l = GIMP_HALF_SIZE;
    real a = fabs(r);
    real s = r < 0 ? (real)-1 : (real)1;
    if (a < l) {
        *w = (real)1 - (r * r + l * l) / ((real)2 * l);
        *d = -r / l;
    } else if (a < (real)1 - l) {
        *w = (real)1 - a;
        *d = -s;
    } else if (a < (real)1 + l) {
        real e = (real)1 + l - a;
        *w = e * e / ((real)4 * l);
        *d = -s * e / ((real)2 * l);
    } else {
        *w = 0;
        *d = 0;
    }
}

// Linear hat weight and right derivative (shape.rs: linear_1d).
__device__ __forceinline__ void linear_1d(real r, real* w, real* d) {
    if (!(r >= (real)-1 && r < (real)1)) { *w = 0; *d = 0; }
    else if (r >= 0) { *w = (real)1 - r; *d = (real)-1; }
    else { *w = (real)1 + r; *d = (real)1; }
}

// Weights and derivatives d w / d fx of one axis for a transfer (shape.rs: shape_1d).
__device__ __forceinline__ void shape_1d(unsigned transfer, real fx, real w[3], real d[3]) {
    if (transfer == TRANSFER_GIMP) {
        for (int n = 0; n < 3; ++n) gimp_1d(fx - (real)n, &w[n], &d[n]);
    } else if (transfer == TRANSFER_LINEAR) {
        for (int n = 0; n < 3; ++n) linear_1d(fx - (real)n, &w[n], &d[n]);
    } else {
        weights_1d(fx, w);
        dweights_1d(fx, d);
    }
}

// Gradient (per cell) of the weight of node (i, j, k) (shape.rs: Stencil::grad).
__device__ __forceinline__ vec3 shape_grad(const real w[3][3], const real d[3][3], int i, int j, int k) {
    return make_v3(d[0][i] * w[1][j] * w[2][k], w[0][i] * d[1][j] * w[2][k], w[0][i] * w[1][j] * d[2][k]);
}

// PIC/FLIP blend (transfer.rs: flip_blend): (1 - alpha) v_pic + alpha (v_p + dv).
__device__ __forceinline__ vec3 flip_blend(real alpha, vec3 v_p, vec3 v_pic, vec3 dv) {
    return v_pic * ((real)1 - alpha) + (v_p + dv) * alpha;
}
