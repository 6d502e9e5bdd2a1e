// Particle fields in original order for other programs (the Python package's `particles.x` and
// `.v`, host side in src/export/mod.rs): the three words of field `first` of slot i go to
// out[3 id + k] as float, id being the slot's original index (field F_ID), so the host copies one
// array in NumPy's (n, 3) layout and scatters nothing. An id out of range sets *bad.
#include "common.cuh"

extern "C" __global__ void export_vec3(const real* __restrict__ s, unsigned cap, unsigned n, int first,
                                       float* __restrict__ out, unsigned* __restrict__ bad) {
    for (unsigned i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
        unsigned id = state_bits(s[sidx(cap, F_ID, i)]);
        if (id >= n) { atomicOr(bad, 1u); continue; }
        unsigned long long o = 3ull * id;
        vec3 v = first == F_V ? load_vel(s, cap, i) : load_v3(s, cap, first, i);
        out[o] = (float)v.x;
        out[o + 1] = (float)v.y;
        out[o + 2] = (float)v.z;
    }
}

// One chunk of a frame for the frame writers (host side in src/export/chunks.rs): the particles of
// original index lo..lo+len. Slot i, of original index id in the chunk, writes word w (state field
// fields[w], an export code of state.cuh: export_word) at out[w * out_stride + id - lo]: the f32
// bits of the field (an f64 state rounded to nearest, C decoded in a compact layout), or for
// the material id its integer bits. Every slot's id is read once per chunk; an id
// out of range sets *bad.
extern "C" __global__ void export_chunk(const real* __restrict__ s, unsigned cap, unsigned n, unsigned lo,
                                        unsigned len, const int* __restrict__ fields, int nw,
                                        unsigned* __restrict__ out, unsigned out_stride,
                                        unsigned* __restrict__ bad) {
    for (unsigned i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
        unsigned id = state_bits(s[sidx(cap, F_ID, i)]);
        if (id >= n) { atomicOr(bad, 1u); continue; }
        unsigned j = id - lo;  // wraps above len when id < lo
        if (j >= len) continue;
        for (int w = 0; w < nw; ++w) out[(unsigned long long)w * out_stride + j] = export_word(s, cap, i, fields[w]);
    }
}
