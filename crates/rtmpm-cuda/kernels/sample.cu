// Deferred bodies drawn on the device (host side: src/setup/sample/mod.rs; the walk: sample.cuh). Two
// passes over the rows of a body's walk (lattice rows, or SAMPLE_TRIES_PER_ROW random tries),
// one thread a row (`sdf`: a mesh body's distances, else unused): `sample_count` counts each row's
// points, the host sums the counts into each row's first particle, and `sample_write` writes the
// positions of one piece of the body (particles lo .. lo + len) as 3 f32 each, which `fill_body`
// (fill.cu) then turns into particles.
#include "common.cuh"
#include "sample.cuh"

// counts[t] = the points of row row0 + t inside the shape, for t < nrows.
extern "C" __global__ void sample_count(const unsigned* __restrict__ recipe, const float* __restrict__ sdf,
                                        unsigned long long row0, unsigned nrows, unsigned long long* __restrict__ counts) {
    const SpRecipe R = sp_load(recipe, sdf);
    for (unsigned t = blockIdx.x * blockDim.x + threadIdx.x; t < nrows; t += gridDim.x * blockDim.x) {
        unsigned long long n = 0;
        sp_row(R, row0 + t, [&](const float*) { ++n; });
        counts[t] = n;
    }
}

// The points of rows row0 .. row0 + nrows whose particle index (offsets[t]: the first of row
// row0 + t, then one more per point) is in lo .. lo + len, into xs[3 (index - lo) ..].
extern "C" __global__ void sample_write(const unsigned* __restrict__ recipe, const float* __restrict__ sdf,
                                        unsigned long long row0, unsigned nrows,
                                        const unsigned long long* __restrict__ offsets, unsigned long long lo,
                                        unsigned len, float* __restrict__ xs) {
    const SpRecipe R = sp_load(recipe, sdf);
    const unsigned long long hi = lo + len;
    for (unsigned t = blockIdx.x * blockDim.x + threadIdx.x; t < nrows; t += gridDim.x * blockDim.x) {
        unsigned long long at = offsets[t];
        if (at >= hi) continue;
        sp_row(R, row0 + t, [&](const float* x) {
            if (at >= lo && at < hi) {
                float* out = xs + 3ull * (at - lo);
                out[0] = x[0];
                out[1] = x[1];
                out[2] = x[2];
            }
            ++at;
        });
    }
}
