"""Session 14, call 1: the Python GPU batch loop of bench/python_batch_gpu.py in one mode for a
fixed time, to be sampled by py-spy --native (where the host's own time goes a call).
    python profile_loop.py MODE K SECONDS   (MODE: calls, reset, pose, loop)"""
import sys, time
sys.path.insert(0, "bench")
import numpy as np
import python_batch_gpu as b
import rtmpm

mode, k, secs = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
one, why = b.make_batch(256)
print("tool:", why or "yes", file=sys.stderr)
sim = b.fresh(one, [])
sim.overlap = "--overlap" in sys.argv
n = len(sim)
t0 = time.perf_counter(); calls = 0
vel = np.tile(np.array([0.0, -b.SPEED, 0.0], np.float32), (n, 1)); pos = np.empty((n, 3), np.float32)
while time.perf_counter() - t0 < secs:
    for c in range(20):
        if mode in ("pose", "loop"):
            b.pose(sim, pos, vel)
        if mode in ("reset", "loop"):
            sim.reset([(calls * 4 + j) % n for j in range(4)])
        sim.step(k)
        calls += 1
    if sim.time.max() > 8.0:
        sim.reset(list(range(n)))
_ = sim.running
dt = time.perf_counter() - t0
print(f"{mode} k={k}: {calls} calls in {dt:.2f} s = {1e3*dt/calls:.3f} ms a call", file=sys.stderr)
