"""The device's timeline of the Python GPU batch loop: where the GPU idles in a call, and what each
mode of ``bench/python_batch_gpu.py`` adds to the device's work.

    python bench/python_batch_trace.py [--worlds 256] [--calls 6] [--per-call 10]
                                       [--overlap | --no-overlap]
                                       [--moving-tool] [--trace out.json] [--summary-of in.json]

PyTorch's profiler (CUPTI's activity records) sees every kernel, copy and memset of the process,
the batch's own launches (through cudarc, the driver API) as well as PyTorch's, so this needs
PyTorch with CUDA beside the ``rtmpm`` module, and no Nsight Systems. The script makes one fresh
batch a mode (the scene of ``python_batch_gpu.py``: ``--worlds`` sand beds of 1,024 particles and
a kinematic tool), warms each up, then records ``--calls`` calls of ``--per-call`` steps of each
mode (``bare``: one call of ``calls x per-call`` steps) under the profiler, with the host's parts
of a call (pose, reset, step) marked. It prints, per mode: the wall time a call (the profiler's
own cost included: compare modes with each other, not with ``python_batch_gpu.py``'s table), the
device's busy time and its idle gaps a call, and the device work a call by kernel, copy and
memset. ``--trace`` keeps the Chrome trace (open it in chrome://tracing or Perfetto);
``--summary-of`` prints the summary of a kept trace without a GPU. ``--overlap`` /
``--no-overlap`` set ``BatchSimulation.overlap`` on or off on every batch; neither: the module's
default (on for a GPU batch since session 16, unless ``RTMPM_BATCH_OVERLAP=0``).
"""

import argparse
import collections
import json
import os
import sys
import time

MODES = ("bare", "calls", "reset", "pose", "loop")
DEVICE_EVENTS = ("kernel", "gpu_memcpy", "gpu_memset")


def record(a):
    """Run the modes under PyTorch's profiler; the Chrome trace written to ``a.trace``."""
    import numpy as np
    import torch
    from torch.profiler import ProfilerActivity, profile, record_function

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import python_batch_gpu as b

    if not torch.cuda.is_available():
        sys.exit("no CUDA device for PyTorch: the timeline needs PyTorch with CUDA")
    torch.zeros(1, device="cuda")  # PyTorch's context first: the batch shares the primary context
    one, why = b.make_batch(a.worlds, moving=a.moving_tool)
    if why:
        print(f"no tool in the worlds ({why}): pose and loop not recorded", file=sys.stderr)
    b.OVERLAP = a.overlap  # None: the module's default
    n = a.worlds
    vel = np.tile(np.array([0.0, -b.SPEED, 0.0], np.float32), (n, 1))
    pos = np.empty((n, 3), np.float32)
    modes = [m for m in MODES if not (why and m in ("pose", "loop"))]

    def calls(sim, mode, count):
        for c in range(count):
            with record_function(f"{mode}:call"):
                if mode in ("pose", "loop"):
                    with record_function("pose"):
                        b.pose(sim, pos, vel)
                if mode in ("reset", "loop"):
                    with record_function("reset"):
                        sim.reset([(c * a.resets + j) % n for j in range(a.resets)])
                with record_function("step"):
                    sim.step(a.per_call)
        _ = sim.running  # the last call's check (with overlap: made here)

    sims = {m: b.fresh(one, []) for m in modes}
    for m, sim in sims.items():  # warm-up: kernels loaded, chunks learnt, buffers grown
        if m == "bare":
            sim.step(2 * a.per_call)
            _ = sim.running
        else:
            calls(sim, m, 3)
    torch.cuda.synchronize()
    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
        for m, sim in sims.items():
            with record_function(f"MODE {m}"):
                t0 = time.perf_counter()
                if m == "bare":
                    with record_function("bare:call"):
                        sim.step(a.calls * a.per_call)
                        _ = sim.running
                else:
                    calls(sim, m, a.calls)
                per = 1e3 * (time.perf_counter() - t0) / a.calls
                print(f"{m}: {per:.3f} ms a call of {a.per_call} steps (under the profiler)", file=sys.stderr)
            torch.cuda.synchronize()
    prof.export_chrome_trace(a.trace)
    print(f"trace written to {a.trace}", file=sys.stderr)


def summary(path, per_call):
    """The device's busy time, idle gaps and work a call of each mode recorded in trace ``path``."""
    with open(path) as f:
        events = [e for e in json.load(f)["traceEvents"] if e.get("ph") == "X"]
    device = sorted((e for e in events if e.get("cat") in DEVICE_EVENTS), key=lambda e: e["ts"])
    marks = [e for e in events if e.get("cat") == "user_annotation"]
    modes = sorted((e for e in marks if e["name"].startswith("MODE ")), key=lambda e: e["ts"])
    if not modes:
        sys.exit(f"{path}: no mode marked (not a trace of this script?)")
    for mode in modes:
        a, z = mode["ts"], mode["ts"] + mode["dur"]
        name = mode["name"][5:]
        work = [e for e in device if a <= e["ts"] < z]
        ncalls = max(1, sum(1 for e in marks if e["name"] == f"{name}:call" and a <= e["ts"] < z))
        # bare is one call of calls x per_call steps: counted a call of per_call steps, as the others
        scale = ncalls if name != "bare" else max(1, sum(1 for e in work if e["name"].startswith("g2p2g")) // per_call)
        if not work:
            print(f"\n== {name}: no device work recorded")
            continue
        busy, gaps, end = 0.0, [], work[0]["ts"]
        for e in work:
            if e["ts"] > end:
                gaps.append(e["ts"] - end)
            busy += e["dur"]
            end = max(end, e["ts"] + e["dur"])
        span = end - work[0]["ts"]
        print(f"\n== {name}: a call of {per_call} steps: wall {mode['dur'] / scale:.0f} us, device span "
              f"{span / scale:.0f} us, busy {busy / scale:.0f} us, idle {sum(gaps) / scale:.0f} us in "
              f"{len(gaps) / scale:.1f} gaps (gaps over 20 us: {sum(g for g in gaps if g > 20) / scale:.0f} us)")
        print("   largest gaps (us):", " ".join(f"{g:.0f}" for g in sorted(gaps, reverse=True)[:8]))
        by = collections.defaultdict(lambda: [0, 0.0])
        for e in work:
            key = (e["cat"], e["name"][:60])
            by[key][0] += 1
            by[key][1] += e["dur"]
        for (cat, what), (count, dur) in sorted(by.items(), key=lambda kv: -kv[1][1]):
            print(f"   {cat:10s} {count / scale:6.1f} a call {dur / scale:8.1f} us a call "
                  f"{dur / count:7.2f} us each  {what}")
        for part in ("pose", "reset", "step"):
            spans = [e["dur"] for e in marks if e["name"] == part and a <= e["ts"] < z]
            if spans:
                print(f"   host {part}: {sum(spans) / len(spans):.0f} us a call (mean of {len(spans)})")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", type=int, default=256)
    ap.add_argument("--calls", type=int, default=6, help="calls recorded a mode (default 6)")
    ap.add_argument("--per-call", type=int, default=10, help="steps a call (default 10)")
    ap.add_argument("--resets", type=int, default=4, help="worlds reset before every call (default 4)")
    ap.add_argument("--overlap", action="store_const", const=True, default=None,
                    help="BatchSimulation.overlap on every batch")
    ap.add_argument("--no-overlap", dest="overlap", action="store_const", const=False,
                    help="BatchSimulation.overlap off on every batch (the old behaviour)")
    ap.add_argument("--moving-tool", action="store_true", help="the tool moves in every mode, bare too")
    ap.add_argument("--trace", default="python_batch_trace.json", help="where the Chrome trace goes")
    ap.add_argument("--summary-of", default=None, help="summarise this kept trace; record nothing")
    a = ap.parse_args()
    if a.worlds < 1 or a.calls < 1 or a.per_call < 1 or a.resets < 0 or a.resets > a.worlds:
        sys.exit("--worlds, --calls and --per-call must be at least 1, --resets from 0 to --worlds")
    if a.summary_of:
        summary(a.summary_of, a.per_call)
        return
    record(a)
    summary(a.trace, a.per_call)


if __name__ == "__main__":
    main()
