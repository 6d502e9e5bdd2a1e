"""Taichi's mpm3d (the MLS-MPM fluid of Taichi's examples, Hu et al. 2018) on the scene of
`rtmpm bench` (the fluid block): n^3/4 particles at uniformly random positions in
[0.15, 0.55]^3 of the unit cube, dx = 1/n, walls 3 cells thick, linear weakly compressible fluid
(K = 400, density 1), gravity 9.8 down, rtmpm's fixed dt for n. The peer of the CPU backend:
run it with `--threads T` beside `rtmpm bench --backend cpu --n N --threads T`.

Needs taichi (tested with 1.7.4: `pip install taichi==1.7.4`). Prints one `throughput` line
in rtmpm bench's units (particle-steps/s).

    python3 bench/taichi_mpm3d.py --n 128 --steps 100 --threads 16 [--arch cpu|cuda]
"""

import argparse
import time

import numpy as np
import taichi as ti


def fluid_block_dt(n):
    """rtmpm bench's dt (crates/rtmpm/src/bench.rs, fluid_block_dt)."""
    return 2e-4 if n <= 64 else (8e-5 if n <= 128 else 4e-5)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--threads", type=int, default=0, help="CPU threads (0: all)")
    ap.add_argument("--arch", default="cpu", choices=["cpu", "cuda"])
    a = ap.parse_args()

    kw = {"cpu_max_num_threads": a.threads} if a.threads > 0 else {}
    ti.init(arch=ti.cpu if a.arch == "cpu" else ti.cuda, default_fp=ti.f32, random_seed=0, **kw)

    n_grid = a.n
    n_particles = n_grid**3 // 4
    dx = 1.0 / n_grid
    dt = fluid_block_dt(n_grid)
    p_rho = 1.0
    p_vol = 0.4**3 / n_particles  # the block's volume shared by its particles
    p_mass = p_vol * p_rho
    gravity = 9.8
    bound = 3
    E = 400.0  # bulk modulus K of the linear equation of state

    x = ti.Vector.field(3, float, n_particles)
    v = ti.Vector.field(3, float, n_particles)
    C = ti.Matrix.field(3, 3, float, n_particles)
    J = ti.field(float, n_particles)
    grid_v = ti.Vector.field(3, float, (n_grid,) * 3)
    grid_m = ti.field(float, (n_grid,) * 3)
    neighbour = (3,) * 3

    @ti.kernel
    def substep():
        for I in ti.grouped(grid_m):
            grid_v[I] = ti.zero(grid_v[I])
            grid_m[I] = 0
        ti.loop_config(block_dim=n_grid)
        for p in x:
            Xp = x[p] / dx
            base = int(Xp - 0.5)
            fx = Xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
            stress = -dt * 4 * E * p_vol * (J[p] - 1) / dx**2
            affine = ti.Matrix.identity(float, 3) * stress + p_mass * C[p]
            for offset in ti.static(ti.grouped(ti.ndrange(*neighbour))):
                dpos = (offset - fx) * dx
                weight = 1.0
                for d in ti.static(range(3)):
                    weight *= w[offset[d]][d]
                grid_v[base + offset] += weight * (p_mass * v[p] + affine @ dpos)
                grid_m[base + offset] += weight * p_mass
        for I in ti.grouped(grid_m):
            if grid_m[I] > 0:
                grid_v[I] /= grid_m[I]
            grid_v[I][1] -= dt * gravity
            cond = (I < bound) & (grid_v[I] < 0) | (I > n_grid - bound) & (grid_v[I] > 0)
            grid_v[I] = ti.select(cond, 0, grid_v[I])
        ti.loop_config(block_dim=n_grid)
        for p in x:
            Xp = x[p] / dx
            base = int(Xp - 0.5)
            fx = Xp - base
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
            new_v = ti.zero(v[p])
            new_C = ti.zero(C[p])
            for offset in ti.static(ti.grouped(ti.ndrange(*neighbour))):
                dpos = (offset - fx) * dx
                weight = 1.0
                for d in ti.static(range(3)):
                    weight *= w[offset[d]][d]
                g_v = grid_v[base + offset]
                new_v += weight * g_v
                new_C += 4 * weight * g_v.outer_product(dpos) / dx**2
            v[p] = new_v
            x[p] += dt * v[p]
            J[p] *= 1 + dt * new_C.trace()
            C[p] = new_C

    rng = np.random.default_rng(0)
    x.from_numpy((rng.random((n_particles, 3)) * 0.4 + 0.15).astype(np.float32))
    J.fill(1.0)

    for _ in range(a.warmup):
        substep()
    ti.sync()
    start = time.perf_counter()
    for _ in range(a.steps):
        substep()
    ti.sync()
    wall = time.perf_counter() - start
    rate = n_particles * a.steps / wall
    print(f"  backend      taichi {'.'.join(map(str, ti.__version__))} mpm3d ({a.arch}, threads {a.threads or 'all'})")
    print(f"  particles    {n_particles}")
    print(f"  wall time    {wall:.3f} s ({1e3 * wall / a.steps:.3f} ms/step)")
    print(f"  throughput   {rate / 1e6:.2f} M particle-steps/s ({rate:.4e} particle-steps/s)")


if __name__ == "__main__":
    main()
