"""What a Python step loop costs a batch on the GPU: per-world resets (and tool poses) between
calls, against the same steps with no Python work between them.

    python bench/python_batch_gpu.py [--worlds 256] [--steps 200] [--per-call 1,10]
                                     [--resets 4] [--repeats 5] [--json out.json]

A batch of ``--worlds`` small sand beds (1,024 particles each, dx = 0.025 m, fixed dt = 4e-4 s,
the scene of bench/batch_python_loop.py) as ``BatchSimulation(backend="cuda")``: every world in
the same CUDA kernels. Each mode takes ``--steps`` steps of every world on a fresh batch (set-up
not timed), ``--per-call`` steps per Python call:

  bare    ``sim.step(steps)``: one call, no Python between the steps (the reference)
  calls   ``sim.step(k)`` from Python, nothing else
  reset   before every call ``--resets`` worlds (a different few each call) put back to their
          initial state with ``sim.reset(worlds)``, then ``sim.step(k)``
  pose    before every call a kinematic tool posed in every world (``set_rigid_body``, one row
          per world), then ``sim.step(k)``; only where the GPU batch takes rigid bodies (the tool
          is then in every mode's worlds), otherwise reported as not measured
  loop    poses (when measured), resets, then ``sim.step(k)``: the issue's loop
  device  ``sim.step(k)`` with PyTorch reading ``x_device`` and ``v_device`` after every call (a
          learning loop's observation; the batch gathers them on the GPU after each call); needs
          PyTorch with CUDA

Every mode does the same physics work (a reset world starts again from time 0 with as many
particles), so time / bare is the Python loop's overhead: the calls, the resets' uploads, the
poses, and each driver call's rewind point (a device-to-device copy of the particle state as
the call begins; since that point is on the device, a call reads nothing back to the host:
``x`` / ``v`` read the worlds when asked for, which no mode here does). ``step`` remembers its
chunk of steps between calls, so ``bare``'s one call of ``--steps`` is a few driver calls and a
call of ``k`` steps is one, once learnt. Wall seconds (the GPU's work included: every call ends
by reading the control words, which waits for its steps), min / median / max over the repeats,
modes interleaved; the issue's bound is loop / bare at most 1.10. Prints a table; ``--json``
writes every timing.
"""

import argparse
import json
import statistics
import sys
import time

import numpy as np

import rtmpm

BED_TOP = 0.15  # m
HALF = 0.03  # m, the tool's half size
SPEED = 0.2  # m/s, downwards


def scene(worlds, tool):
    s = {
        "name": "python_batch_gpu",
        "seed": 1,
        "domain": {"min": [0.0, 0.0, 0.0], "max": [0.4, 0.35, 0.4], "dx": 0.025},
        "time": {"duration": 10.0, "fps": 50, "dt": 4e-4},
        "walls": {"thickness": 3, "condition": "sticky"},
        "material": [{"name": "sand", "type": "drucker_prager", "density": 1600.0, "youngs_modulus": 5e5,
                      "poisson_ratio": 0.3, "friction_angle": 35.0}],
        "body": [{"material": "sand", "shape": "box", "min": [0.1, 0.1, 0.1], "max": [0.3, BED_TOP, 0.3],
                  "particles_per_cell": 8}],
        "batch": {"count": worlds},
    }
    if tool:
        s["rigid_body"] = [{"name": "tool", "shape": "box", "type": "kinematic", "condition": "slip",
                            "density": 1000.0, "min": [0.2 - HALF, BED_TOP + 0.04, 0.2 - HALF],
                            "max": [0.2 + HALF, BED_TOP + 0.04 + 2 * HALF, 0.2 + HALF]}]
    return s


def make_batch(worlds):
    """The batch on the GPU, with the tool when the GPU batch takes rigid bodies: (scene, why
    there is no tool or None)."""
    if "rigid" in rtmpm.features:
        one = rtmpm.Scene.from_dict(scene(worlds, tool=True))
        try:
            sim = rtmpm.Simulation(one, backend="cuda")
            sim.set_rigid_body("tool", velocity=[0.0, -SPEED, 0.0])
            return one, None
        except rtmpm.BackendError as e:
            why = str(e).splitlines()[0]
    else:
        why = "rtmpm built without the `rigid` feature"
    return rtmpm.Scene.from_dict(scene(worlds, tool=False)), why


def pose(sim, pos, vel):
    t = sim.time  # (N,) each world's time: reset worlds run behind
    pos[:, 0] = 0.2
    pos[:, 1] = BED_TOP + 0.04 + HALF - SPEED * t
    pos[:, 2] = 0.2
    sim.set_rigid_body("tool", position=pos, velocity=vel)


def run_mode(mode, sim, steps, k, resets, torch):
    n = len(sim)
    if mode == "bare":
        sim.step(steps)
        return
    vel = np.tile(np.array([0.0, -SPEED, 0.0], np.float32), (n, 1))
    pos = np.empty((n, 3), np.float32)
    if mode == "device":
        x, v = torch.from_dlpack(sim.x_device), torch.from_dlpack(sim.v_device)
    for c in range(steps // k):
        if mode in ("pose", "loop"):
            pose(sim, pos, vel)
        if mode in ("reset", "loop"):
            sim.reset([(c * resets + j) % n for j in range(resets)])
        sim.step(k)
        if mode == "device":
            # An observation per world on the GPU: its centre of mass and mean speed.
            obs = torch.cat([x.mean(1), v.norm(dim=2).mean(1, keepdim=True)], 1)
            torch.cuda.synchronize()
    if mode == "device":
        del obs


def summary(xs):
    return f"{min(xs):.4f} / {statistics.median(xs):.4f} / {max(xs):.4f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", type=int, default=256)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--per-call", default="1,10", help="steps per Python call, a comma list (default 1,10)")
    ap.add_argument("--resets", type=int, default=4, help="worlds reset before every call (default 4)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    ok, why = rtmpm.cuda_available()
    if not ok:
        sys.exit(f"no usable GPU: {why}")
    per_call = [int(k) for k in a.per_call.split(",")]
    if any(k < 1 or a.steps % k for k in per_call):
        sys.exit(f"--per-call {a.per_call}: each must divide --steps {a.steps}")
    try:
        import torch

        torch = torch if torch.cuda.is_available() else None
    except ImportError:
        torch = None
    one, no_tool = make_batch(a.worlds)
    modes = ["bare", "calls", "reset"] + ([] if no_tool else ["pose"]) + ["loop"]
    modes += ["device"] if torch is not None else []
    runs = [("bare", a.steps)] + [(m, k) for k in per_call for m in modes if m != "bare"]
    times = {r: [] for r in runs}
    info = {}
    for rep in range(a.repeats + 1):  # the first round warms up (kernel cache, pools), not counted
        for run in runs if rep % 2 == 0 else runs[::-1]:
            sim = rtmpm.Simulation(one, backend="cuda")
            info = {"particles": int(sim.num_particles.sum()), "backend": sim.backend.name}
            sim.step(1)  # the first step's graph capture is set-up, not the loop
            t0 = time.perf_counter()
            run_mode(run[0], sim, a.steps, run[1], a.resets, torch)
            wall = time.perf_counter() - t0
            assert sim.running.all(), f"{run}: a world blew up: {sim.status}"
            if rep > 0:
                times[run].append(wall)
            del sim
    bare = statistics.median(times[("bare", a.steps)])
    print(f"{a.worlds} worlds, {info['particles']} particles, {a.steps} steps, {a.resets} resets a call, "
          f"{a.repeats} repeats, on {info['backend']}")
    if no_tool:
        print(f"pose: not measured (no tool in the worlds: {no_tool})")
    if torch is None:
        print("device: not measured (no PyTorch with CUDA)")
    print("| mode | steps a call | wall s min / median / max | ms a call (median) | / bare (medians) |")
    print("| --- | --- | --- | --- | --- |")
    rows = []
    for mode, k in runs:
        med = statistics.median(times[(mode, k)])
        calls = a.steps // k
        rows.append({"mode": mode, "steps_per_call": k, "wall_s": times[(mode, k)], "median_s": med,
                     "ratio_to_bare": med / bare})
        print(f"| {mode} | {k} | {summary(times[(mode, k)])} | {1e3 * med / calls:.3f} | {med / bare:.3f} |")
    print(f"bare: {1e3 * bare / a.steps:.3f} ms a step of the {a.worlds} worlds "
          f"({info['particles'] * a.steps / bare / 1e6:.1f} M particle-steps/s); bound: loop / bare <= 1.10")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"worlds": a.worlds, "steps": a.steps, "resets": a.resets, "repeats": a.repeats,
                       "per_call": per_call, "pose_not_measured": no_tool, "torch": torch is not None,
                       **info, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
