// Batches of worlds (crate::batch): one world's particles put back into the state (a reset to
// its initial state, or to a given one), wherever the sort has moved them. `src` holds the
// world's `count` particles, structure of arrays with stride `count`, in original order from
// `first`; a slot whose id lies in [first, first + count) takes every word of its particle but
// the id. Launched in the batch's program; compiled in every program (it reads nothing of a batch).
#include "common.cuh"

extern "C" __global__ void batch_put_world(Ctx c, const real* src, unsigned first, unsigned count) {
    for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
        unsigned k = state_bits(c.state[sidx(c.cap, F_ID, i)]) - first;
        if (k >= count) continue;
        for (int f = 0; f < RTMPM_NFIELDS; ++f)
            if (f != F_ID) c.state[sidx(c.cap, f, i)] = src[(size_t)f * count + k];
    }
}
