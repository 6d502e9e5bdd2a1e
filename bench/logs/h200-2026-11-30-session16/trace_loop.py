"""Session 16, call 1: a timeline of the Python GPU batch loop (bench/python_batch_gpu.py's modes)
from PyTorch's profiler (CUPTI: every kernel, copy and memset of the process, the batch's too),
to see where the device idles in a call and what a moving tool adds to a step.
    python trace_loop.py OUT_JSON [--overlap] [--moving-tool]"""
import sys, os, time
sys.path.insert(0, "bench")
import numpy as np
import torch
from torch.profiler import profile, ProfilerActivity, record_function
import python_batch_gpu as b

out = sys.argv[1]
overlap = "--overlap" in sys.argv
moving = "--moving-tool" in sys.argv
torch.zeros(1, device="cuda")
one, why = b.make_batch(256, moving=moving)
print("tool:", why or "yes", file=sys.stderr)
b.OVERLAP = overlap
n = 256
vel = np.tile(np.array([0.0, -b.SPEED, 0.0], np.float32), (n, 1))
pos = np.empty((n, 3), np.float32)

def mode(sim, m, calls, k):
    for c in range(calls):
        with record_function(f"{m}:call"):
            if m in ("pose", "loop"):
                with record_function("pose"):
                    b.pose(sim, pos, vel)
            if m in ("reset", "loop"):
                with record_function("reset"):
                    sim.reset([(c * 4 + j) % n for j in range(4)])
            with record_function("step"):
                sim.step(k)
    _ = sim.running

sims = {m: b.fresh(one, []) for m in ("bare", "calls", "reset", "pose", "loop")}
for m, sim in sims.items():  # warm-up
    if m == "bare":
        sim.step(20)
    else:
        mode(sim, m, 3, 10)
    _ = sim.running
torch.cuda.synchronize()
with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
    for m, sim in sims.items():
        with record_function(f"MODE {m}"):
            t0 = time.perf_counter()
            if m == "bare":
                with record_function("bare:call"):
                    sim.step(60)
                    _ = sim.running
            else:
                mode(sim, m, 6, 10)
            print(f"{m}: {1e3 * (time.perf_counter() - t0) / 6:.3f} ms a call of 10 (traced)", file=sys.stderr)
        torch.cuda.synchronize()
prof.export_chrome_trace(out)
print("trace written", out, file=sys.stderr)
