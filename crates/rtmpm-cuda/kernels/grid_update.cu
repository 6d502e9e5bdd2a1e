// Grid update (merged): momentum -> velocity, gravity, domain walls, colliders, in one kernel.
#include "common.cuh"
#include "sdf.cuh"

// rtmpm_physics::boundary::BoundaryRule::apply, literally. cond: COND_*.
__device__ __forceinline__ vec3 rule_apply(unsigned cond, real friction, vec3 v, vec3 n) {
    real vn = dot(v, n);
    if (cond == COND_STICKY) return make_v3(0, 0, 0);
    if (cond == COND_SEPARATE && vn >= 0) return v;
    vec3 vt = v - n * vn;
    real vt_len = length(vt);
    if (friction > 0 && vt_len > 0) {
        real reduced = vt_len - friction * fabs(vn);
        if (reduced <= 0) return make_v3(0, 0, 0);
        return vt * (reduced / vt_len);
    }
    return vt;
}

__device__ void grid_update_node(const Ctx& c, unsigned t);

// Zero node t of a grid of 4 reals per node.
__device__ __forceinline__ void clear_node(real* grid, unsigned t) {
#ifdef RTMPM_F64
    for (int e = 0; e < 4; ++e) grid[4u * t + e] = 0;
#else
    reinterpret_cast<float4*>(grid)[t] = make_float4(0.f, 0.f, 0.f, 0.f);
#endif
}

// Grid-stride over the nodes of the pblocks in use (launched with at most one wave of blocks).
// `part`: 0 every pblock; several GPUs: 1 the pblocks no other GPU shares (run while the shared
// ones are summed across GPUs), 2 the shared ones (after the sum).
extern "C" __global__ void grid_update(Ctx c, unsigned part) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_nodes = c.ctl[CTL_PBLOCKS] * 64u;
    if (c.grid_next && thread_index() == 0) c.ctl[CTL_P2G_PENDING] = 0;  // this step's P2G is done
    for (unsigned t = thread_index(); t < n_nodes; t += gridDim.x * blockDim.x) {
        if (part && (c.shared_pblock[t >> 6] != 0) != (part == 2)) continue;
        grid_update_node(c, t);
        // G2P2G: clear the next step's grid (CK-MPM: grids), which the fused kernel scatters into.
        if (c.grid_next) clear_node(c.grid_next, t);
        if (c.grid_aux_next) clear_node(c.grid_aux_next, t);
    }
}

// The world position of the node of grid index gi: origin + gi dx with the product and the sum
// rounded each on its own, as the CPU backend computes it (cpu/grid_update.rs: boundary, couple).
// Written plainly, NVRTC fuses it into one multiply-add (its default --fmad=true), which places
// a node lying on a collider's face on the other side of it than the CPU does: with a face at
// x = 0.06 m (dx 0.02, origin -0.08), 0.059999999 (distance 0: inside) against the CPU's
// 0.060000002 (+3.7e-9: outside), a whole node plane taking a moving collider's velocity on the
// GPU only.
__device__ __forceinline__ vec3 node_position(const Scalars& sc, int gx, int gy, int gz) {
#ifdef RTMPM_F64
    return make_v3(__dadd_rn(sc.origin[0], __dmul_rn((real)gx, sc.dx)), __dadd_rn(sc.origin[1], __dmul_rn((real)gy, sc.dx)),
                   __dadd_rn(sc.origin[2], __dmul_rn((real)gz, sc.dx)));
#else
    return make_v3(__fadd_rn(sc.origin[0], __fmul_rn((real)gx, sc.dx)), __fadd_rn(sc.origin[1], __fmul_rn((real)gy, sc.dx)),
                   __fadd_rn(sc.origin[2], __fmul_rn((real)gz, sc.dx)));
#endif
}

// Boundary conditions of node t at the step's time: walls, then colliders (cpu/grid_update.rs:
// boundary).
__device__ vec3 node_boundary(const Ctx& c, unsigned t, vec3 v) {
    const Scalars& sc = scalars(c);
    const ColliderPoses& pose = poses(c);
    unsigned id = t >> 6, cell = t & 63u;
    int gi[3] = {c.block_coords[3 * id] * 4 + (int)(cell >> 4), c.block_coords[3 * id + 1] * 4 + (int)((cell >> 2) & 3u),
                 c.block_coords[3 * id + 2] * 4 + (int)(cell & 3u)};
#ifdef RTMPM_BATCH
    unsigned world = node_world(gi[0]);
    gi[0] -= world_cells(world);  // in the node's world's own grid
    // The world's own colliders and poses (rows world * n_colliders + k), or the scene's shared
    // by every world.
    const GpuColliderPose* own = c_batch.poses ? c_batch.poses + world * c.n_colliders : nullptr;
#endif
    // Walls (rtmpm_physics::boundary::Walls::apply): index counted from the domain min = gi - 4.
    for (int a = 0; a < 3; ++a) {
        int i = gi[a] - 4;
        vec3 n = make_v3(0, 0, 0);
        if (i <= c.wall_thickness) {
            (&n.x)[a] = 1;
            v = rule_apply(c.wall_cond[2 * a], sc.wall_friction[2 * a], v, n);
        } else if (i >= c.n_cells[a] - c.wall_thickness) {
            (&n.x)[a] = -1;
            v = rule_apply(c.wall_cond[2 * a + 1], sc.wall_friction[2 * a + 1], v, n);
        }
    }
    // Colliders (rtmpm_geometry::Collider::query): v = vc + rule(v - vc, n), then the
    // user's tool, the same way.
    const GpuTool& tool = tool_at(c);
    if (c.n_colliders || tool.active) {
        vec3 x = node_position(sc, gi[0], gi[1], gi[2]);
        for (unsigned k = 0; k < c.n_colliders; ++k) {
#ifdef RTMPM_BATCH
            GpuCollider col = c_batch.colliders ? c_batch.colliders[world * c.n_colliders + k] : collider_at(c, k);
#else
            GpuCollider col = collider_at(c, k);
#endif
            mat3 R;
#ifdef RTMPM_BATCH
            // The world's own pose row at the step's time: the formula below on it (the single
            // run's lines are left as they are, so its PTX does not change).
            if (own) {
                const GpuColliderPose& p = own[k];
                for (int q = 0; q < 9; ++q) R.m[q] = p.rot[q];
                vec3 pt = v3f(p.pivot);
                vec3 xr = transpose(R) * (x - pt) + v3f(col.pivot);
                if (shape_distance(c, col, xr) > 0) continue;
                vec3 n = normalize_or_y(R * shape_normal(c, col, xr));
                vec3 vc = v3f(p.velocity) + cross(v3f(p.omega), x - pt);
                v = vc + rule_apply(col.cond, col.friction, v - vc, n);
                continue;
            }
#endif
            for (int q = 0; q < 9; ++q) R.m[q] = pose.rot[k][q];
            vec3 pt = v3f(pose.pivot[k]);
            vec3 xr = transpose(R) * (x - pt) + v3f(col.pivot);
            if (shape_distance(c, col, xr) > 0) continue;
            vec3 n = normalize_or_y(R * shape_normal(c, col, xr));
            vec3 vc = v3f(pose.velocity[k]) + cross(v3f(pose.omega[k]), x - pt);
            v = vc + rule_apply(col.cond, col.friction, v - vc, n);
        }
        if (tool.active && shape_distance(c, tool.shape, x) <= 0) {
            vec3 n = normalize_or_y(shape_normal(c, tool.shape, x));
            vec3 vt = v3f(tool.velocity);
            v = vt + rule_apply(tool.shape.cond, tool.shape.friction, v - vt, n);
        }
    }
    return v;
}

// Rigid bodies (rtmpm_rigid; cpu/grid_update.rs: couple): a node inside a body takes the
// body's velocity by its boundary rule, and the momentum the rule takes from the node, less the
// gravity the node received this step, goes to the body as impulse and angular impulse about its
// centre (the boundary-condition form of the CPIC coupling of Hu et al., "A Moving Least Squares
// Material Point Method with Displacement Discontinuity and Two-Way Rigid Body Coupling", 2018).
// The reaction is summed for every body, dynamic or not: a dynamic body is moved by it, a
// kinematic or fixed one reports it as its load (the force on a robot's tool; Backend::rigid_loads,
// as the CPU backend's couple does). `e`: the body's 6 f64 sums in this block's copy
// (blockIdx.x % BODY_EXCHANGE_SLOTS, crate::step::rigid); `share`: the part of the reaction this
// GPU adds (below). Node x, mass m, velocity v; returns the velocity after the body's rule.
__device__ __forceinline__ vec3 couple_body(const Ctx& c, const GpuBody& body, double* e, vec3 x, real m, vec3 v, vec3 g_dt,
                                            double share) {
    vec3 r = x - v3f(body.center);
    if (dot(r, r) > (real)body.bound * (real)body.bound) return v;
    mat3 R;
    for (int q = 0; q < 9; ++q) R.m[q] = body.rot[q];
    vec3 p = transpose(R) * r;
    if (shape_distance(c, body.shape, p) > 0) return v;
    vec3 n = normalize_or_y(R * shape_normal(c, body.shape, p));
    vec3 vb = v3f(body.velocity) + cross(v3f(body.omega), r);
    vec3 nv = vb + rule_apply(body.shape.cond, body.shape.friction, v - vb, n);
    vec3 dp = (nv - v + g_dt) * m;
    vec3 t = cross(r, dp);
    atomicAdd(e + 0, -(double)dp.x * share);
    atomicAdd(e + 1, -(double)dp.y * share);
    atomicAdd(e + 2, -(double)dp.z * share);
    atomicAdd(e + 3, -(double)t.x * share);
    atomicAdd(e + 4, -(double)t.y * share);
    atomicAdd(e + 5, -(double)t.z * share);
    return nv;
}

#ifdef RTMPM_BATCH
// couple_body for every body of world `world` of a batch (crate::batch::bodies): x in the
// world's own coordinates, its bodies at rows world * n_bodies .. of the per-world table (global
// memory: more than constant memory holds), summed into row world * n_bodies + b of
// worlds * n_bodies bodies per copy. One GPU: every node counts in full.
__device__ vec3 couple_world_bodies(const Ctx& c, unsigned world, vec3 x, real m, vec3 v, vec3 g_dt) {
    unsigned rows = c_batch.worlds * c.n_bodies;
    for (unsigned b = 0; b < c.n_bodies; ++b) {
        unsigned row = world * c.n_bodies + b;
        double* e = c.body_exchange + 6u * ((blockIdx.x % BODY_EXCHANGE_SLOTS) * rows + row);
        v = couple_body(c, c.bodies[row], e, x, m, v, g_dt, 1.0);
    }
    return v;
}
#else
// couple_body for every body of a single run (constant memory: body_at). Several GPUs: a node
// of a pblock that k GPUs hold has the same summed mass and momentum on each of them after the
// shared-block reduction, so each adds 1/k of its reaction (`share`) and the host's sum over
// the GPUs counts it once.
__device__ vec3 couple_bodies(const Ctx& c, vec3 x, real m, vec3 v, vec3 g_dt, double share) {
    for (unsigned b = 0; b < c.n_bodies; ++b) {
        double* e = c.body_exchange + 6u * ((blockIdx.x % BODY_EXCHANGE_SLOTS) * c.n_bodies + b);
        v = couple_body(c, body_at(c, b), e, x, m, v, g_dt, share);
    }
    return v;
}
#endif

// The gravity of node t: the scene's, or in a batch its world's.
__device__ __forceinline__ const real* node_gravity(const Ctx& c, unsigned t) {
#ifdef RTMPM_BATCH
    return c_batch.gravity + 3 * node_world(c.block_coords[3 * (t >> 6)] * 4);
#else
    return step_params(c).gravity;
#endif
}

// The end of every node update: settling damping, the boundary conditions at the node's B-spline
// grid position, the rigid bodies, and the new velocity stored in `node` (its 4 values).
__device__ __forceinline__ void grid_node_finish(const Ctx& c, real* node, unsigned t, real m, vec3 v, const real* gravity) {
    const StepParams& sp = step_params(c);
    v = v * (real)sp.damping;  // settling damping (1 = off)
    v = node_boundary(c, t, v);
#ifdef RTMPM_BATCH
    if (c.n_bodies) {
        // The node in its world's own coordinates, coupled to that world's bodies.
        const Scalars& sc = scalars(c);
        unsigned id = t >> 6, cell = t & 63u;
        int gx = c.block_coords[3 * id] * 4 + (int)(cell >> 4);
        unsigned world = node_world(gx);
        gx -= world_cells(world);
        vec3 x = node_position(sc, gx, c.block_coords[3 * id + 1] * 4 + (int)((cell >> 2) & 3u),
                               c.block_coords[3 * id + 2] * 4 + (int)(cell & 3u));
        vec3 g_dt = make_v3(gravity[0], gravity[1], gravity[2]) * (real)sp.dt;
        v = couple_world_bodies(c, world, x, m, v, g_dt);
    }
#else
    if (c.n_bodies) {
        const Scalars& sc = scalars(c);
        unsigned id = t >> 6, cell = t & 63u;
        vec3 x = node_position(sc, c.block_coords[3 * id] * 4 + (int)(cell >> 4), c.block_coords[3 * id + 1] * 4 + (int)((cell >> 2) & 3u),
                               c.block_coords[3 * id + 2] * 4 + (int)(cell & 3u));
        vec3 g_dt = make_v3(gravity[0], gravity[1], gravity[2]) * (real)sp.dt;
        // One GPU: shared_pblock is all zeros (only sb_boundary writes it).
        unsigned holders = c.shared_pblock ? c.shared_pblock[id] : 0u;
        double share = holders >= 2 ? 1.0 / (double)holders : 1.0;
        v = couple_bodies(c, x, m, v, g_dt, share);
    }
#endif
    node[1] = v.x; node[2] = v.y; node[3] = v.z;
}

// The MLS-MPM/APIC update of node t of one grid (`node`: its 4 values; cpu/grid_update.rs:
// update_apic): v = p / m + dt g, then grid_node_finish.
__device__ __forceinline__ void grid_update_apic(const Ctx& c, real* node, unsigned t) {
    real m = node[0];
    if (!(m > 0)) return;
    real dt = step_params(c).dt;
    const real* gravity = node_gravity(c, t);
    real inv_m = (real)1 / m;
    vec3 v = make_v3(node[1] * inv_m + dt * gravity[0], node[2] * inv_m + dt * gravity[1], node[3] * inv_m + dt * gravity[2]);
    grid_node_finish(c, node, t, m, v, gravity);
}

// MLS: grid_update_apic. CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point
// Method", ACM TOG 2025): grid_update_apic on each of its two grids (grid 0 in grid, grid 1 in
// grid_aux), both tested against the boundaries at node t's B-spline position, so that a boundary
// holds the nodes of both grids on either side of it (no rigid bodies: refused with CK-MPM).
// Classic MPM transfers: v = (p + dt f) / m + dt g with dt f from grid_aux, which then keeps
// v_old = p / m (no force, no boundary condition) for FLIP.
__device__ void grid_update_node(const Ctx& c, unsigned t) {
    if (c.transfer == TRANSFER_MLS) {
        grid_update_apic(c, c.grid + 4u * t, t);
        return;
    }
    if (c.transfer == TRANSFER_CK) {
        grid_update_apic(c, c.grid + 4u * t, t);
        grid_update_apic(c, c.grid_aux + 4u * t, t);
        return;
    }
    real* node = c.grid + 4u * t;
    real m = node[0];
    if (!(m > 0)) return;
    const real* gravity = node_gravity(c, t);
    real inv_m = (real)1 / m;
    real* aux = c.grid_aux + 4u * t;
    vec3 p = make_v3(node[1], node[2], node[3]);
    vec3 f = make_v3(aux[1], aux[2], aux[3]);
    vec3 v = (p + f) * inv_m + make_v3(gravity[0], gravity[1], gravity[2]) * (real)step_params(c).dt;
    vec3 v_old = p * inv_m;
    aux[1] = v_old.x; aux[2] = v_old.y; aux[3] = v_old.z;
    grid_node_finish(c, node, t, m, v, gravity);
}

// MUSL re-map (cpu/grid_update.rs: grid_update_musl): re-mapped momentum in grid_aux to
// velocity with the same boundary conditions (gravity is already in the particle velocities).
extern "C" __global__ void grid_update_musl(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_nodes = c.ctl[CTL_PBLOCKS] * 64u;
    for (unsigned t = thread_index(); t < n_nodes; t += gridDim.x * blockDim.x) {
        real m = c.grid[4u * t];
        if (!(m > 0)) continue;
        real* aux = c.grid_aux + 4u * t;
        real inv_m = (real)1 / m;
        vec3 v = node_boundary(c, t, make_v3(aux[1] * inv_m, aux[2] * inv_m, aux[3] * inv_m));
        aux[1] = v.x; aux[2] = v.y; aux[3] = v.z;
    }
}
