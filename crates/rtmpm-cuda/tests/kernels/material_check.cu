// Device side of the GPU material check (crates/rtmpm-cuda/tests/materials.rs): every material's
// stress and return map, and the 3x3 SVD, evaluated by the kernels' own code for inputs the host
// draws; the host compares them with the Rust models. Compiled against the kernel headers
// (rtmpm_cuda::compile::compile_unit), like the pipeline.
#include "material/dispatch.cuh"

// Item i: material i / n of `mats`, input k = i % n. In: F, C (9 reals each, column-major) and the
// plastic scalar per item; out: tau, the projected F, the new plastic scalar.
extern "C" __global__ void material_check(const MaterialGpu* mats, unsigned n_mats, unsigned n, const real* f,
                                          const real* c, const real* plastic, real dt, real* tau, real* fe,
                                          real* plastic_out) {
    unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n * n_mats) return;
    unsigned k = i % n;
    MaterialGpu m = mats[i / n];
    mat3 F, C;
    for (int q = 0; q < 9; ++q) {
        F.m[q] = f[9 * k + q];
        C.m[q] = c[9 * k + q];
    }
    mat3 t = material_kirchhoff(m, F, plastic[i], C);
    real p = plastic[i];
    mat3 g = material_project(m, F, &p, dt);
    for (int q = 0; q < 9; ++q) {
        tau[9 * i + q] = t.m[q];
        fe[9 * i + q] = g.m[q];
    }
    plastic_out[i] = p;
}

// F = U diag(sigma) V^T of each input: U, sigma, V out.
extern "C" __global__ void svd_check(const real* f, unsigned n, real* u, real* sigma, real* v) {
    unsigned k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    mat3 F, U, V;
    vec3 s;
    for (int q = 0; q < 9; ++q) F.m[q] = f[9 * k + q];
    svd3(F, U, s, V);
    for (int q = 0; q < 9; ++q) {
        u[9 * k + q] = U.m[q];
        v[9 * k + q] = V.m[q];
    }
    sigma[3 * k] = s.x;
    sigma[3 * k + 1] = s.y;
    sigma[3 * k + 2] = s.z;
}
