// Compile check of the device headers: every function instantiated once.
// nvcc -arch=sm_90 -c crates/rtmpm-cuda/kernels/tests/compile_check.cu -o /tmp/compile_check.o
#include "../material/materials.cuh"

__global__ void compile_check(const MaterialGpu* mats, const mat3* f, const mat3* c, real* plastic, mat3* tau, mat3* fe, mat3* out, vec3* sig, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const MaterialGpu& m = mats[i % 6];
    tau[i] = material_kirchhoff(m, f[i], plastic[i], c[i]);
    real q = plastic[i];
    fe[i] = material_project(m, f[i], &q);
    plastic[i] = q;
    mat3 u, v, r, s;
    svd3(f[i], u, sig[i], v);
    polar(f[i], r, s);
    out[i] = u * v + r * s;
}
