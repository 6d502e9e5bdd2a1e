// Batches of worlds (crate::batch): one world's particles put back into the state (a reset to
// its initial state, or to a given one), wherever the sort has moved them. `src` holds the
// world's `count` particles, structure of arrays with stride `count`, in original order from
// `first`; a slot whose id lies in [first, first + count) takes every word of its particle but
// the id. Launched in the batch's program; compiled in every program (there a particle's world
// is 0).
//
// The mapping is rebuilt only when a particle put needs it (not for every put, which would
// rebuild every world's mapping for a few worlds' reset). A slot stays mapped to the gblock B
// the last rebuild gave it, and a step needs no rebuild while each particle's stencil base lies
// in B's free zone, [4B - 4, 4B + 5] per axis (g2p_finish, g2p/particle.cuh). This kernel does
// not know B, but the slot's old particle lay in that zone (otherwise the step that moved it
// there set the rebuild flag, which this kernel never clears), so B is one of the blocks whose
// zone holds the old base ob: (ob - 5) / 4 <= B <= (ob + 4) / 4, rounded inwards. The new
// particle keeps the mapping valid when its base lies in the zone of every such block;
// otherwise the kernel sets the rebuild flag, as G2P does for a particle that leaves its zone.
// What the slot holds after the put lies in B's zone either way (or a rebuild is due), so puts
// one after another keep the rule true.
#include "common.cuh"

// Whether stencil base `nb` lies in the free zone of every gblock whose zone holds `ob` (one
// axis; `>> 2` rounds towards minus infinity, as the rebuild's `base >> 2`).
__device__ __forceinline__ bool stays_in_zone(int ob, int nb) {
    int lowest = (ob - 2) >> 2;  // ceil((ob - 5) / 4)
    int highest = (ob + 4) >> 2; // floor((ob + 4) / 4)
    return nb >= 4 * highest - 4 && nb <= 4 * lowest + 5;
}

extern "C" __global__ void batch_put_world(Ctx c, const real* src, unsigned first, unsigned count) {
    bool rebuild = false;
    for (unsigned i = thread_index(); i < c.n; i += gridDim.x * blockDim.x) {
        unsigned k = state_bits(c.state[sidx(c.cap, F_ID, i)]) - first;
        if (k >= count) continue;
        unsigned world = particle_world(c, i);
        vec3 old_x = load_v3(c.state, c.cap, F_X, i);
        vec3 new_x = make_v3(src[(size_t)F_X * count + k], src[(size_t)(F_X + 1) * count + k],
                             src[(size_t)(F_X + 2) * count + k]);
        int ob[3], nb[3];
        real fx[3];
        stencil_of(c, old_x, world, ob, fx);
        stencil_of(c, new_x, world, nb, fx);
        for (int a = 0; a < 3; ++a) rebuild = rebuild || !stays_in_zone(ob[a], nb[a]);
        for (int f = 0; f < RTMPM_NFIELDS; ++f)
            if (f != F_ID) c.state[sidx(c.cap, f, i)] = src[(size_t)f * count + k];
    }
    if (rebuild) c.ctl[CTL_NEED_REBUILD] = 1;
}
