"""Speed of rtmpm from Python on a GPU, run by scripts/gpu/python.sh.

1. Stepping overhead: the 2M-particle dam break (bench/fluid_dam_2m.toml), one run_frame() call
   per frame, against `rtmpm run --no-output` on the same frames (its summary's wall time, which
   like ours starts after the backend is built and includes the first frame's graph capture).
   Best of --repeat runs each. Target: at most 2 % slower.
2. Reading x of the 2M particles into NumPy (sim.particles.x: three rows and the ids copied to
   pinned memory, scattered to original order), against PyTorch copying the same 24 MB from the
   GPU into pinned and into pageable host memory. Target: near the PCIe bandwidth.

    python bench/python_gpu.py --cli .device/rtmpm [--frames 20] [--repeat 3] [--json out.json]
"""

import argparse
import json
import re
import subprocess
import time

import numpy as np

import rtmpm


def cli_wall(cli, scene, frames):
    r = subprocess.run(
        [cli, "run", scene, "--backend", "cuda", "--no-output", "--frames", str(frames)],
        check=True, capture_output=True, text=True,
    )
    # The summary's wall time has 2 decimals (1 % of a second-long run): take the wall time from
    # its throughput (3 significant digits) and its particle and step counts instead.
    n = re.search(r"particles\s+([0-9]+)", r.stdout)
    steps = re.search(r"steps\s+([0-9]+)", r.stdout)
    rate = re.search(r"throughput\s+([0-9.]+) ([GMk]) particle-steps/s", r.stdout)
    if not (n and steps and rate):
        raise RuntimeError("no summary in:\n" + r.stdout + r.stderr)
    scale = {"G": 1e9, "M": 1e6, "k": 1e3}[rate.group(2)]
    return int(n.group(1)) * int(steps.group(1)) / (float(rate.group(1)) * scale)


def python_wall(scene, frames):
    sim = rtmpm.Simulation(scene, backend="cuda")
    t0 = time.perf_counter()
    for _ in range(frames):
        sim.run_frame()
    wall = time.perf_counter() - t0
    return wall, sim


def best_of(fn, k):
    best = float("inf")
    for _ in range(k):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", required=True)
    ap.add_argument("--scene", default="bench/fluid_dam_2m.toml")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    res = {"scene": args.scene, "frames": args.frames, "repeat": args.repeat}

    cli_times, py_times = [], []
    for _ in range(args.repeat):  # interleaved, so drifts of the clock affect both
        cli_times.append(cli_wall(args.cli, args.scene, args.frames))
        wall, sim = python_wall(args.scene, args.frames)
        py_times.append(wall)
    n, steps = sim.num_particles, sim.steps
    res.update(
        particles=n, steps=steps, backend=sim.backend.name,
        cli_wall_s=cli_times, python_wall_s=py_times,
        overhead_pct=100.0 * (min(py_times) / min(cli_times) - 1.0),
        python_particle_steps_per_s=n * steps / min(py_times),
    )
    print(f"{n} particles, {args.frames} frames ({steps} steps) on {sim.backend.name}")
    print(f"  rtmpm run --no-output : best {min(cli_times):.4f} s of {['%.4f' % t for t in cli_times]}")
    print(f"  Python run_frame()    : best {min(py_times):.4f} s of {['%.4f' % t for t in py_times]}")
    print(f"  overhead              : {res['overhead_pct']:+.2f} % (target <= 2 %)")

    # Reading x: every access copies from the device (nothing is cached after a step).
    # The arrays' memory returns to a pool when NumPy frees them: a read into reused memory (the
    # usual loop, one array a frame) and reads that keep every array (fresh memory each time).
    sim.step(1)
    t0 = time.perf_counter()
    x = sim.particles.x
    t_first = time.perf_counter() - t0
    assert x.shape == (n, 3) and x.dtype == np.float32
    del x
    t_x = best_of(lambda: sim.particles.x, 10)
    held = []
    t_fresh = best_of(lambda: held.append(sim.particles.x), 5)
    del held
    t_all = best_of(lambda: sim.particles.F, 3)  # the whole state (29 words a particle) + F
    mb = 12 * n / 1e6
    res.update(read_x_s=t_x, read_x_GBps=mb / 1e3 / t_x, read_F_full_state_s=t_all,
               read_x_first_s=t_first, read_x_fresh_s=t_fresh)
    print(f"  sim.particles.x       : {1e3 * t_x:.2f} ms for {mb:.1f} MB = {mb / 1e3 / t_x:.2f} GB/s")
    print(f"    fresh memory        : {1e3 * t_fresh:.2f} ms = {mb / 1e3 / t_fresh:.2f} GB/s (every array kept)")
    print(f"    first read          : {1e3 * t_first:.2f} ms")
    print(f"  sim.particles.F       : {1e3 * t_all:.2f} ms (reads the whole state)")
    try:
        import torch

        xd = torch.from_dlpack(sim.particles.x_device)
        t_view = best_of(lambda: torch.from_dlpack(sim.particles.x_device), 10)
        src = torch.empty((n, 3), dtype=torch.float32, device="cuda")
        pinned = torch.empty((n, 3), dtype=torch.float32, pin_memory=True)

        def pinned_copy():
            pinned.copy_(src)
            torch.cuda.synchronize()

        def pageable_copy():
            src.cpu()
            torch.cuda.synchronize()

        t_pin = best_of(pinned_copy, 10)
        t_page = best_of(pageable_copy, 10)
        res.update(
            dlpack_view_s=t_view, torch_pinned_GBps=mb / 1e3 / t_pin,
            torch_pageable_GBps=mb / 1e3 / t_page,
            read_x_vs_pinned=t_pin / t_x, zero_copy_ptr_match=xd.data_ptr() == sim.particles.x_device.ptr,
        )
        print(f"  torch.from_dlpack     : {1e6 * t_view:.1f} us (no copy)")
        print(f"  torch D2H pinned      : {1e3 * t_pin:.2f} ms = {mb / 1e3 / t_pin:.2f} GB/s")
        print(f"  torch D2H pageable    : {1e3 * t_page:.2f} ms = {mb / 1e3 / t_page:.2f} GB/s")
        print(f"  x read / pinned copy  : {100 * t_pin / t_x:.0f} % of the PCIe (pinned) rate")
    except ImportError:
        print("  (no torch: PCIe reference skipped)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
