// GPU check of the device ports against the hand-computed values of the Rust unit tests.
// Build: nvcc -arch=sm_90 crates/rtmpm-cuda/kernels/tests/material_check.cu -o material_check
// Run on a GPU: ./material_check  (prints FAIL lines and exits 1 on mismatch)
#include <cstdio>
#include <cmath>
#include "../material/materials.cuh"

#define NOUT 64

__device__ mat3 dmat(real a, real b, real c) { return mat3_diag(make_v3(a, b, c)); }
__device__ mat3 rot(vec3 axis, real ang) {  // Rodrigues
    real l = length(axis); axis = axis * ((real)1 / l);
    real c = cos(ang), s = sin(ang), t = 1 - c;
    mat3 m;
    m.m[0] = t * axis.x * axis.x + c;          m.m[3] = t * axis.x * axis.y - s * axis.z; m.m[6] = t * axis.x * axis.z + s * axis.y;
    m.m[1] = t * axis.x * axis.y + s * axis.z; m.m[4] = t * axis.y * axis.y + c;          m.m[7] = t * axis.y * axis.z - s * axis.x;
    m.m[2] = t * axis.x * axis.z - s * axis.y; m.m[5] = t * axis.y * axis.z + s * axis.x; m.m[8] = t * axis.z * axis.z + c;
    return m;
}
__device__ real maxabs(const mat3& a) { real r = 0; for (int i = 0; i < 9; ++i) r = fmax(r, fabs(a.m[i])); return r; }

__global__ void check(real* out) {
    int k = 0;
    mat3 r1 = rot(make_v3(1, 2, 3), 0.7f), r2 = rot(make_v3(-0.3f, 1, 0.2f), 2.1f);
    mat3 hard[6] = {r1 * dmat(1, 0.5f, 1e-6f) * r2, r1 * dmat(1e3f, 1, 1e-3f) * r2, r1 * dmat(1.2f, 0.9f, -0.3f) * r2,
                    outer(make_v3(0.3f, -0.4f, 1.2f), make_v3(-2, 0.1f, 0.7f)), mat3_zero(), dmat(2, 2, 2)};
    for (int i = 0; i < 6; ++i) {  // relative reconstruction + orthogonality errors
        mat3 u, v; vec3 s;
        svd3(hard[i], u, s, v);
        mat3 e = mul_diag_bt(u, s, v) - hard[i];
        out[k++] = maxabs(e) / fmax(maxabs(hard[i]), (real)1e-30);
        out[k++] = maxabs(transpose(u) * u - mat3_identity()) + fabs(determinant(v) - 1);
    }
    { mat3 u, v; vec3 s; svd3(r1 * dmat(1e3f, 1, 1e-3f) * r2, u, s, v); out[k++] = s.z; }  // 12: 1e-3
    FixedCorotatedParams fc = {1, 2};
    out[k++] = at(fixed_corotated_kirchhoff(fc, dmat(1.1f, 1, 1)), 0, 0);  // 13: 0.44
    NeoHookeanParams nh = {1, 2};
    out[k++] = at(neo_hookean_kirchhoff(nh, dmat(1.1f, 1, 1)), 0, 0);  // 14: 0.4006204
    FluidParams fl = {2, FLUID_EOS_TAIT, 7, 0};
    out[k++] = at(fluid_kirchhoff(fl, dmat(1, 0.9f, 1), mat3_zero()), 1, 1);  // 15: -1.9633527
    SnowParams sn = {1, 2, 0.025f, 0.0075f, 10};
    real jp = 1;
    mat3 fe = snow_project(sn, dmat(1.1f, 0.9f, 1), &jp);
    out[k++] = jp;           // 16: 1.0078259
    out[k++] = at(fe, 0, 0);  // 17: 1.0075
    out[k++] = at(snow_kirchhoff(sn, dmat(1.1f, 1, 1), 0.95f), 0, 0);  // 18: 0.7254374
    DruckerPragerParams dp = {1, 2, 0.3265986f, 0};  // alpha of 30 degrees, compression cone
    real dq;
    drucker_prager_project_strain(dp, make_v3(0.09f, -0.11f, -0.01f), &dq);
    out[k++] = dq;  // 19: 0.1022296
    real q = 0;
    fe = drucker_prager_project(dp, dmat(1.1f, 1.1f, 1.1f), &q);
    out[k++] = q;                // 20: sqrt(3) ln 1.1 = 0.1650820
    out[k++] = maxabs(fe - mat3_identity());  // 21: 0
    VonMisesParams vm = {100, 200, 1, 0};
    real dpv;
    von_mises_project_strain(vm, make_v3(0.01f, -0.01f, 0), 0, &dpv);
    out[k++] = dpv;  // 22: 0.00821365
    MaterialGpu m = {};
    m.kind = MATERIAL_SNOW; m.snow = sn;
    out[k++] = maxabs(material_kirchhoff(m, mat3_identity(), 1, mat3_zero()));  // 23: 0
    out[k++] = (real)sizeof(MaterialGpu);  // 24: 88
}

int main() {
    real* d; real h[NOUT] = {0};
    cudaMalloc(&d, sizeof(h));
    cudaMemset(d, 0, sizeof(h));
    check<<<1, 1>>>(d);
    if (cudaMemcpy(h, d, sizeof(h), cudaMemcpyDeviceToHost) != cudaSuccess) { printf("cuda error\n"); return 2; }
    int fail = 0;
    for (int i = 0; i < 12; ++i) if (!(h[i] < 2e-6)) { printf("FAIL svd %d: %g\n", i, (double)h[i]); fail = 1; }
    struct { int i; double want, tol; } c[] = {{12, 1e-3, 1e-8}, {13, 0.44, 1e-6}, {14, 0.4006204, 1e-6}, {15, -1.9633527, 1e-5},
        {16, 1.0078259, 1e-6}, {17, 1.0075, 1e-6}, {18, 0.7254374, 1e-5}, {19, 0.1022296, 1e-6}, {20, 0.1650820, 1e-6},
        {21, 0, 1e-6}, {22, 0.00821365, 1e-6}, {23, 0, 1e-7}, {24, 88, 0}};
    for (auto& t : c) {
        bool ok = fabs(h[t.i] - t.want) <= t.tol;
        printf("%s out[%d] = %.8g (want %.8g)\n", ok ? "ok  " : "FAIL", t.i, (double)h[t.i], t.want);
        if (!ok) fail = 1;
    }
    printf(fail ? "FAILED\n" : "ALL OK\n");
    return fail;
}
