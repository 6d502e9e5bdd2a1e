// The field a picture is coloured by, per particle, and its automatic range: the 1st and 99th
// percentiles of the finite values (rtmpm_render::field_range), found without the host by
// two histograms: one over [min, max], then one inside each of the two bins that hold the
// percentiles, to 1/RENDER_BINS^2 of the field's span.
#include "render.cuh"
#include "../material/dispatch.cuh"

// The field of slot i (the `rtmpm render` colourings: speed |v|, J = det F, the von Mises
// equivalent of the Cauchy stress tau / J, the plastic scalar).
__device__ float field_value(const Ctx& c, unsigned color_by, unsigned i) {
    const real* s = c.state;
    if (color_by == RENDER_COLOR_SPEED) return (float)length(load_vel(s, c.cap, i));
    if (color_by == RENDER_COLOR_PLASTIC) return (float)load_plastic(s, c.cap, i);
    mat3 f = load_deformation(s, c.cap, i, false);
    real j = determinant(f);
    if (color_by == RENDER_COLOR_J) return (float)j;
    const MaterialGpu& m = material_at(c, state_word_bits(s, c.cap, F_MAT, i));
    mat3 t = material_kirchhoff(m, f, load_plastic(s, c.cap, i), load_affine(s, c.cap, i)) * ((real)1 / j);
    real xx = t.m[0], yy = t.m[4], zz = t.m[8], xy = t.m[3], yz = t.m[7], xz = t.m[6];
    real q = (real)0.5 * ((xx - yy) * (xx - yy) + (yy - zz) * (yy - zz) + (zz - xx) * (zz - xx)) +
             (real)3 * (xy * xy + yz * yz + xz * xz);
    return (float)sqrt(fmax(q, (real)0));
}

// Every particle's field into r.field; with the automatic range, the minimum and maximum of the
// finite values (a warp's reduced first, then one atomic each). Every lane of a warp runs the same
// iterations (blocks of whole warps), so the warp reductions see the whole warp.
extern "C" __global__ void render_field(Ctx c, RenderParams r) {
    for (unsigned base = blockIdx.x * blockDim.x; base < c.n; base += gridDim.x * blockDim.x) {
        unsigned i = base + threadIdx.x;
        unsigned lo = 0xffffffffu, hi = 0u;
        if (i < c.n) {
            float f = field_value(c, r.color_by, i);
            r.field[i] = f;
            if (isfinite(f)) lo = hi = order_bits(f);
        }
        if (!r.auto_range) continue;
        lo = __reduce_min_sync(0xffffffffu, lo);
        hi = __reduce_max_sync(0xffffffffu, hi);
        if ((threadIdx.x & 31u) == 0 && lo != 0xffffffffu) {
            atomicMin(r.scratch + RS_MIN, lo);
            atomicMax(r.scratch + RS_MAX, hi);
        }
    }
}

// The coarse bin of f in [mn, mx] (the same expression in both passes).
__device__ __forceinline__ int coarse_bin(float f, float mn, float mx) {
    float span = mx - mn;
    if (!(span > 0.f)) return 0;
    return min(max((int)((f - mn) / span * (float)RENDER_BINS), 0), RENDER_BINS - 1);
}
// The bounds of coarse bin b.
__device__ __forceinline__ float coarse_edge(int b, float mn, float mx) {
    return mn + (mx - mn) * ((float)b / (float)RENDER_BINS);
}

// pass 0: the coarse histogram of the finite values; pass 1: the fine histograms of the two bins
// picked by render_pick (pass 0). Counted in shared memory, then added to the scratch.
extern "C" __global__ void render_histogram(Ctx c, RenderParams r, unsigned pass) {
    __shared__ unsigned h[2 * RENDER_BINS];
    unsigned words = pass == 0 ? RENDER_BINS : 2 * RENDER_BINS;
    for (unsigned k = threadIdx.x; k < words; k += blockDim.x) h[k] = 0;
    __syncthreads();
    unsigned lo_bits = r.scratch[RS_MIN], hi_bits = r.scratch[RS_MAX];
    if (lo_bits != 0xffffffffu) {
        float mn = order_float(lo_bits), mx = order_float(hi_bits);
        int pick[2] = {(int)r.scratch[RS_PICK], (int)r.scratch[RS_PICK + 2]};
        for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
            float f = r.field[i];
            if (!isfinite(f)) continue;
            int b = coarse_bin(f, mn, mx);
            if (pass == 0) {
                atomicAdd(&h[b], 1u);
                continue;
            }
            for (int e = 0; e < 2; ++e) {
                if (b != pick[e]) continue;
                float b0 = coarse_edge(b, mn, mx), b1 = coarse_edge(b + 1, mn, mx);
                int sub = b1 > b0 ? (int)((f - b0) / (b1 - b0) * (float)RENDER_BINS) : 0;
                atomicAdd(&h[e * RENDER_BINS + min(max(sub, 0), RENDER_BINS - 1)], 1u);
            }
        }
    }
    __syncthreads();
    unsigned* out = r.scratch + (pass == 0 ? RS_COARSE : RS_FINE);
    for (unsigned k = threadIdx.x; k < words; k += blockDim.x)
        if (h[k]) atomicAdd(out + k, h[k]);
}

// Inclusive prefix sums of the counts of `bins` (RENDER_BINS, one block of 1024 threads, two bins a
// thread) into sums.
__device__ void block_prefix(const unsigned* bins, unsigned* sums) {
    __shared__ unsigned part[1024];
    unsigned t = threadIdx.x;
    unsigned a = bins[2 * t], b = bins[2 * t + 1];
    part[t] = a + b;
    __syncthreads();
    for (unsigned off = 1; off < 1024; off <<= 1) {
        unsigned v = t >= off ? part[t - off] : 0u;
        __syncthreads();
        part[t] += v;
        __syncthreads();
    }
    unsigned before = t ? part[t - 1] : 0u;
    sums[2 * t] = before + a;
    sums[2 * t + 1] = before + a + b;
    __syncthreads();
}

// The bin holding rank k (0-based) of the inclusive prefix sums, and k's rank inside it.
__device__ void find_rank(const unsigned* sums, unsigned k, unsigned* bin, unsigned* rank) {
    for (unsigned b = threadIdx.x; b < RENDER_BINS; b += blockDim.x) {
        unsigned before = b ? sums[b - 1] : 0u;
        if (k >= before && k < sums[b]) {
            *bin = b;
            *rank = k - before;
        }
    }
}

// One block of 1024 threads. pass 0: the coarse bins holding the ranks (N-1)/100 and
// (N-1) - (N-1)/100 of the N finite values, and their ranks inside them; pass 1: the fine bins
// of those ranks, whose lower edges are the range (widened as field_range widens an empty one).
extern "C" __global__ void render_pick(RenderParams r, unsigned pass) {
    __shared__ unsigned sums[RENDER_BINS];
    unsigned* s = r.scratch;
    if (s[RS_MIN] == 0xffffffffu) {  // no finite value
        if (threadIdx.x == 0) {
            s[RS_LO] = __float_as_uint(0.f);
            s[RS_HI] = __float_as_uint(1.f);
        }
        return;
    }
    float mn = order_float(s[RS_MIN]), mx = order_float(s[RS_MAX]);
    if (pass == 0) {
        block_prefix(s + RS_COARSE, sums);
        unsigned n = sums[RENDER_BINS - 1];
        unsigned k_lo = (n - 1) / 100, k_hi = (n - 1) - (n - 1) / 100;
        find_rank(sums, k_lo, s + RS_PICK, s + RS_PICK + 1);
        find_rank(sums, k_hi, s + RS_PICK + 2, s + RS_PICK + 3);
        return;
    }
    __shared__ float value[2];
    for (int e = 0; e < 2; ++e) {
        block_prefix(s + RS_FINE + e * RENDER_BINS, sums);
        __shared__ unsigned sub, rank;
        if (threadIdx.x == 0) sub = rank = 0;
        __syncthreads();
        find_rank(sums, s[RS_PICK + 2 * e + 1], &sub, &rank);
        __syncthreads();
        if (threadIdx.x == 0) {
            int b = (int)s[RS_PICK + 2 * e];
            float b0 = coarse_edge(b, mn, mx), b1 = coarse_edge(b + 1, mn, mx);
            value[e] = b0 + (b1 - b0) * ((float)sub / (float)RENDER_BINS);
        }
        __syncthreads();
    }
    if (threadIdx.x == 0) {
        float lo = value[0], hi = value[1];
        if (!(hi > lo)) {
            float pad = fmaxf(fabsf(lo) * 0.01f, 1e-6f);
            lo -= pad;
            hi += pad;
        }
        s[RS_LO] = __float_as_uint(lo);
        s[RS_HI] = __float_as_uint(hi);
    }
}
