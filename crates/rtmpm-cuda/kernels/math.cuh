// Small vector/matrix types for the rtmpm kernels. Column-major like glam on the host:
// m[c * 3 + r] is row r, column c. `real` is float unless RTMPM_F64 is defined (double precision,
// `[solver] precision = "f64"`).
#pragma once

#ifdef RTMPM_F64
typedef double real;
#else
typedef float real;
#endif

struct vec3 { real x, y, z; };
struct mat3 { real m[9]; };

__device__ __forceinline__ vec3 make_v3(real x, real y, real z) { vec3 v; v.x = x; v.y = y; v.z = z; return v; }
__device__ __forceinline__ vec3 operator+(vec3 a, vec3 b) { return make_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
__device__ __forceinline__ vec3 operator-(vec3 a, vec3 b) { return make_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
__device__ __forceinline__ vec3 operator*(vec3 a, real s) { return make_v3(a.x * s, a.y * s, a.z * s); }
__device__ __forceinline__ vec3 operator*(real s, vec3 a) { return make_v3(a.x * s, a.y * s, a.z * s); }
__device__ __forceinline__ real dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
__device__ __forceinline__ vec3 cross(vec3 a, vec3 b) { return make_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
__device__ __forceinline__ real length(vec3 a) { return sqrt(dot(a, a)); }

__device__ __forceinline__ real at(const mat3& a, int r, int c) { return a.m[c * 3 + r]; }
__device__ __forceinline__ mat3 mat3_zero() { mat3 a; for (int i = 0; i < 9; ++i) a.m[i] = 0; return a; }
__device__ __forceinline__ mat3 mat3_identity() { mat3 a = mat3_zero(); a.m[0] = a.m[4] = a.m[8] = 1; return a; }
__device__ __forceinline__ mat3 mat3_diag(vec3 d) { mat3 a = mat3_zero(); a.m[0] = d.x; a.m[4] = d.y; a.m[8] = d.z; return a; }
__device__ __forceinline__ mat3 operator+(const mat3& a, const mat3& b) { mat3 c; for (int i = 0; i < 9; ++i) c.m[i] = a.m[i] + b.m[i]; return c; }
__device__ __forceinline__ mat3 operator-(const mat3& a, const mat3& b) { mat3 c; for (int i = 0; i < 9; ++i) c.m[i] = a.m[i] - b.m[i]; return c; }
__device__ __forceinline__ mat3 operator*(const mat3& a, real s) { mat3 c; for (int i = 0; i < 9; ++i) c.m[i] = a.m[i] * s; return c; }
__device__ __forceinline__ mat3 operator*(real s, const mat3& a) { return a * s; }
__device__ __forceinline__ mat3 operator*(const mat3& a, const mat3& b) {
    mat3 c;
    for (int col = 0; col < 3; ++col)
        for (int r = 0; r < 3; ++r)
            c.m[col * 3 + r] = a.m[r] * b.m[col * 3] + a.m[3 + r] * b.m[col * 3 + 1] + a.m[6 + r] * b.m[col * 3 + 2];
    return c;
}
__device__ __forceinline__ vec3 operator*(const mat3& a, vec3 v) {
    return make_v3(a.m[0] * v.x + a.m[3] * v.y + a.m[6] * v.z,
                   a.m[1] * v.x + a.m[4] * v.y + a.m[7] * v.z,
                   a.m[2] * v.x + a.m[5] * v.y + a.m[8] * v.z);
}
__device__ __forceinline__ mat3 transpose(const mat3& a) {
    mat3 t;
    for (int c = 0; c < 3; ++c) for (int r = 0; r < 3; ++r) t.m[r * 3 + c] = a.m[c * 3 + r];
    return t;
}
__device__ __forceinline__ real trace(const mat3& a) { return a.m[0] + a.m[4] + a.m[8]; }
__device__ __forceinline__ real determinant(const mat3& a) {
    return a.m[0] * (a.m[4] * a.m[8] - a.m[7] * a.m[5])
         - a.m[3] * (a.m[1] * a.m[8] - a.m[7] * a.m[2])
         + a.m[6] * (a.m[1] * a.m[5] - a.m[4] * a.m[2]);
}
// Outer product a b^T.
__device__ __forceinline__ mat3 outer(vec3 a, vec3 b) {
    mat3 c;
    c.m[0] = a.x * b.x; c.m[1] = a.y * b.x; c.m[2] = a.z * b.x;
    c.m[3] = a.x * b.y; c.m[4] = a.y * b.y; c.m[5] = a.z * b.y;
    c.m[6] = a.x * b.z; c.m[7] = a.y * b.z; c.m[8] = a.z * b.z;
    return c;
}

// Inverse of a (glam's Mat3::inverse, the same operations): the cofactor columns over the
// determinant, transposed. a must be invertible.
__device__ __forceinline__ mat3 inverse(const mat3& a) {
    vec3 x = make_v3(a.m[0], a.m[1], a.m[2]), y = make_v3(a.m[3], a.m[4], a.m[5]), z = make_v3(a.m[6], a.m[7], a.m[8]);
    vec3 t0 = cross(y, z), t1 = cross(z, x), t2 = cross(x, y);
    real inv_det = (real)1 / dot(z, t2);
    mat3 r;
    r.m[0] = t0.x * inv_det; r.m[1] = t0.y * inv_det; r.m[2] = t0.z * inv_det;
    r.m[3] = t1.x * inv_det; r.m[4] = t1.y * inv_det; r.m[5] = t1.z * inv_det;
    r.m[6] = t2.x * inv_det; r.m[7] = t2.y * inv_det; r.m[8] = t2.z * inv_det;
    return transpose(r);
}

// ---- helpers added for svd.cuh / material/*.cuh ----
__device__ __forceinline__ vec3 operator-(vec3 a) { return make_v3(-a.x, -a.y, -a.z); }
__device__ __forceinline__ vec3 make_v3s(real s) { return make_v3(s, s, s); }
__device__ __forceinline__ real sum(vec3 a) { return a.x + a.y + a.z; }
__device__ __forceinline__ mat3 mat3_from_cols(vec3 c0, vec3 c1, vec3 c2) {
    mat3 a;
    a.m[0] = c0.x; a.m[1] = c0.y; a.m[2] = c0.z;
    a.m[3] = c1.x; a.m[4] = c1.y; a.m[5] = c1.z;
    a.m[6] = c2.x; a.m[7] = c2.y; a.m[8] = c2.z;
    return a;
}
__device__ __forceinline__ vec3 mat3_col(const mat3& a, int c) { return make_v3(a.m[c * 3], a.m[c * 3 + 1], a.m[c * 3 + 2]); }
// a * diag(d) * b^T
__device__ __forceinline__ mat3 mul_diag_bt(const mat3& a, vec3 d, const mat3& b) { return a * mat3_diag(d) * transpose(b); }
