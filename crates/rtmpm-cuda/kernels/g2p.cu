// G2P (merged): interpolation of v and C, F update, plasticity, advection, domain clamp,
// free-zone check (sets the rebuild flag) and health check (first bad particle, max speed).
#include "common.cuh"
#include "material_dispatch.cuh"

extern "C" __global__ void g2p(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned w = thread_index() >> 5, lane = threadIdx.x & 31;
    if (w >= c.ctl[CTL_WARPS]) return;
    unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
    if (lane >= count) return;
    unsigned p = first + lane;
    vec3 x = load_v3(c.state, c.cap, F_X, p);
    int base[3]; real fx[3]; real wt[3][3];
    stencil_of(c, x, base, fx);
    for (int a = 0; a < 3; ++a) weights_1d(fx[a], wt[a]);
    const int* bc = c.block_coords + 3 * g;
    const unsigned* nbs = c.neighbors + 27 * g;
    vec3 v = make_v3(0, 0, 0);
    mat3 B = mat3_zero();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) {
                int n0 = base[0] + i, n1 = base[1] + j, n2 = base[2] + k;
                unsigned id = nbs[nb_slot((n0 >> 2) - bc[0], (n1 >> 2) - bc[1], (n2 >> 2) - bc[2])];
                const real* node = c.grid + 4u * (id * 64u + (unsigned)cell_code(n0, n1, n2));
                vec3 vi = make_v3(node[1], node[2], node[3]);
                real weight = wt[0][i] * wt[1][j] * wt[2][k];
                vec3 dpos = make_v3(((real)i - fx[0]) * c.dx, ((real)j - fx[1]) * c.dx, ((real)k - fx[2]) * c.dx);
                v = v + vi * weight;
                B = B + outer(vi * weight, dpos);
            }
    real dt = c.step->dt;
    mat3 C = B * ((real)4 * c.inv_dx * c.inv_dx);
    x = x + v * dt;
    mat3 F = load_m3(c.state, c.cap, F_F, p);
    F = (mat3_identity() + C * dt) * F;
    real plastic = c.state[F_PLASTIC * c.cap + p];
    GpuMaterial mat = c.materials[__float_as_uint(c.state[F_MAT * c.cap + p])];
    F = material_project(mat, F, &plastic);
    // Health check before the clamp (the clamp would hide NaN).
    unsigned id = __float_as_uint(c.state[F_ID * c.cap + p]);
    real speed = length(v);
    bool finite = isfinite(x.x) && isfinite(x.y) && isfinite(x.z) && isfinite(v.x) && isfinite(v.y) && isfinite(v.z);
    if (!finite || speed * dt > (real)2 * c.dx) {
        unsigned prev = atomicMin(&c.ctl[CTL_BAD_INDEX], id);
        if (prev > id) atomicExch(&c.ctl[CTL_BAD_REASON], finite ? 2u : 1u);
    }
    if (finite) atomicMax(&c.ctl[CTL_MAX_SPEED], __float_as_uint((float)speed));
    x.x = fmin(fmax(x.x, (real)c.domain_min[0]), (real)c.domain_max[0]);
    x.y = fmin(fmax(x.y, (real)c.domain_min[1]), (real)c.domain_max[1]);
    x.z = fmin(fmax(x.z, (real)c.domain_min[2]), (real)c.domain_max[2]);
    // Free zone: the 3x3x3 neighbourhood of gblock B covers the stencil iff base in [4B-4, 4B+5].
    int nb[3]; real nfx[3];
    stencil_of(c, x, nb, nfx);
    bool leave = !finite;
    for (int a = 0; a < 3; ++a) leave = leave || nb[a] < 4 * bc[a] - 4 || nb[a] > 4 * bc[a] + 5;
    if (leave) c.ctl[CTL_NEED_REBUILD] = 1;
    store_v3(c.state, c.cap, F_X, p, x);
    store_v3(c.state, c.cap, F_V, p, v);
    store_m3(c.state, c.cap, F_C, p, C);
    store_m3(c.state, c.cap, F_F, p, F);
    c.state[F_PLASTIC * c.cap + p] = (float)plastic;
}
