"""What a Python step loop costs a batch on the GPU: per-world resets (and tool poses) between
calls, against the same steps with no Python work between them.

    python bench/python_batch_gpu.py [--worlds 256] [--steps 200] [--per-call 1,10]
                                     [--resets 4] [--repeats 5] [--budget S] [--breakdown]
                                     [--moving-tool] [--cuda-options S] [--overlap [on|off] | --no-overlap]
                                     [--json out.json]

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
writes every timing. Each round's progress (and the seconds a fresh batch takes to set up, not
timed) goes to stderr as it ends; ``--budget S`` starts no round after S seconds (the warm-up,
with its kernel compiles, and the first timed round always run; the table then says how many
timed rounds it has), so that a GPU call with a time limit gets a table.

The tool is static in the scene, so only pose and loop (which pose it moving down at 0.2 m/s)
move it: their steps also pay the rigid-body engine's work for a moving body, which bare's do
not (the H200's breakdown of 9cb5bac had pose's steps 0.22 ms a call slower than calls' in
calls of 10 steps, which this would explain: not checked). ``--moving-tool`` gives the scene's tool that velocity, so that every mode, bare
included, moves it and the ratios count only the loop's own cost (not the default, so that the
default figures stay comparable with earlier ones).

``BatchSimulation.overlap`` (on by default for a GPU batch since session 16; before, off unless
set): a step call returns with its steps queued, its health check made as the next call begins,
so that the loop's resets and poses run on the host while the device steps. ``--overlap`` (or
``--overlap on``) sets it on every batch, ``--no-overlap`` (or ``--overlap off``) sets it off
(the old behaviour: each call checks before it returns); neither leaves the module's default
(which ``RTMPM_BATCH_OVERLAP=0`` in the environment turns off). Run the script with
``--overlap`` and ``--no-overlap`` for the A/B; the table's first line says which mode ran (read
back from the batch) and how it was chosen. With overlap on, the timed part of a mode ends with
that check of the last call (reading ``running``), which waits for its steps.

After the table, the host's waits a call of each mode (the last round's,
``BatchSimulation.host_waits``: where the host blocked until the GPU had done queued work, by
reason: the checks, other control words, reads, rigid-body sums, page-locked upload memory in
use, copies from pageable memory, allocations, synchronisations); ``RTMPM_SYNC_TRACE=1`` in the
environment also times them (ms a call). ``RTMPM_BATCH_WAITS=old`` runs the batch's paths as
before those waits were cut (the A/B in one wheel); ``RTMPM_BATCH_PAGEABLE_PUT=1`` uploads from
pageable memory; ``RTMPM_BATCH_RESET=old`` packs and uploads a reset's initial particles every
call as before the image of them kept on the device (the A/B of the resets in one wheel);
``RTMPM_BATCH_REST=old`` steps every world's rapier world at every step, also a world whose tool
stands still (which the batch no longer steps). ``RTMPM_KINEMATIC=eager`` moves the rapier bodies of
such a world at every step as before their rows went ahead of them (docs/batch.md; the same state
bit for bit). ``RTMPM_KINEMATIC=rapier`` steps a world with no
dynamic body (here every world: one kinematic tool) through rapier's whole pipeline as before,
where by default ``RigidWorld::advance`` moves its kinematic bodies by their velocities itself
(the A/B of the moving tool's cost on the host: run pose / loop, or ``--moving-tool``, with and
without it). ``RTMPM_BATCH_FAN`` chooses how the host's advance of the worlds' bodies is spread over
the cores (``serial``: on the calling thread; ``cores``: every core, a world or more a task, as
before; a number ``n``: every core, ``n`` or more worlds a task; unset: on the calling thread for up
to 512 worlds without a dynamic body, every core otherwise). ``RTMPM_BATCH_REDO=old`` redoes the
P2G of every world at the step after a reset, as before the redo of the reset worlds' P2G alone
(with G2P2G; docs/batch.md, "The P2G after a put"); the table of the redos a call of reset and
loop (``BatchSimulation.p2g_redos``: of the worlds put alone, of every world) says which ran;
``RTMPM_BATCH_REDO=wave`` redoes the reset worlds' P2G alone with the kernels of a warp an item
over a full wave, as before ``redo_clear_lanes`` / ``redo_p2g_lanes``. ``RTMPM_BATCH_PUT=old``
puts a reset's particles with ``batch_put_world`` over every slot of the batch, as before the put
over the reset worlds' gblocks (``batch_put_gblocks``; docs/batch.md, "The reset's device work").
``RTMPM_BATCH_UPLOAD=old`` uploads the rigid bodies' table on the batch's stream before each step
whose bodies changed, serial with the kernels, as before the two tables taken in turn whose copies
run on a stream of their own while the step before runs (docs/batch.md, "Rigid bodies in a GPU
batch"; the A/B of a moving tool's cost on the device: run pose / loop, or ``--moving-tool``).

``--breakdown`` then runs the modes calls, reset, pose and loop once more (``--repeats`` rounds
after a warm-up, fresh batches) and times each part of a call on its own: the poses, the resets
and the steps, with the device synchronised after each part (``BatchSimulation.synchronize``;
PyTorch's where the module has none), so that a part's time includes the device work it queued.
These timings perturb what they measure (the waits keep the host from queueing the next part
while the device works, which the plain modes allow), so they say where a call's time goes, not
what the plain modes cost; the plain table above them is the measurement. The breakdown's step
part of reset / loop against calls' is what a reset costs the steps after it (the mapping
rebuilt, the P2G done again); ``rebuilds a call`` counts the mapping's rebuilds
(``BatchSimulation.rebuilds``, where the module has it).
"""

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

import rtmpm

CUDA_OPTIONS = None  # --cuda-options: every batch's (an A/B switch, e.g. "body_sums=step")
BED_TOP = 0.15  # m
HALF = 0.03  # m, the tool's half size
SPEED = 0.2  # m/s, downwards


def scene(worlds, tool, moving=False):
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
        if moving:
            s["rigid_body"][0]["velocity"] = [0.0, -SPEED, 0.0]
    return s


def make_batch(worlds, moving=False):
    """The batch on the GPU, with the tool when the GPU batch takes rigid bodies (moving down at
    SPEED from the start in every mode with ``moving``): (scene, why there is no tool or
    None)."""
    if "rigid" in rtmpm.features:
        one = rtmpm.Scene.from_dict(scene(worlds, tool=True, moving=moving))
        try:
            sim = rtmpm.Simulation(one, backend="cuda", cuda_options=CUDA_OPTIONS)
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


def device_sync(sim, torch):
    """A wait for the device (the breakdown's, between a call's parts): the batch's own
    ``synchronize`` (the whole device), else PyTorch's, else None (the parts then time the host
    only, said in the output)."""
    if hasattr(sim, "synchronize"):
        return sim.synchronize
    if torch is not None:
        return torch.cuda.synchronize
    return None


def rebuilds(sim):
    """The mapping's rebuilds so far (``BatchSimulation.rebuilds``), None where the module has no
    such counter."""
    return getattr(sim, "rebuilds", None)


def run_parts(mode, sim, steps, k, resets, sync):
    """``run_mode`` of calls / reset / pose / loop with each part of a call timed on its own, the
    device synchronised after each part: {part: [seconds a call]}, and the rebuilds over the run
    (None where not counted)."""
    n = len(sim)
    vel = np.tile(np.array([0.0, -SPEED, 0.0], np.float32), (n, 1))
    pos = np.empty((n, 3), np.float32)
    parts = {"pose": [], "reset": [], "step": []}
    before = rebuilds(sim)
    for c in range(steps // k):
        if mode in ("pose", "loop"):
            t0 = time.perf_counter()
            pose(sim, pos, vel)
            sync()
            parts["pose"].append(time.perf_counter() - t0)
        if mode in ("reset", "loop"):
            t0 = time.perf_counter()
            sim.reset([(c * resets + j) % n for j in range(resets)])
            sync()
            parts["reset"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        sim.step(k)
        sync()
        parts["step"].append(time.perf_counter() - t0)
    after = rebuilds(sim)
    built = None if before is None or after is None else after - before
    return parts, built


class Clock:
    """Seconds since the start, for the progress lines and the budget."""

    def __init__(self, budget):
        self.t0 = time.perf_counter()
        self.budget = budget

    def now(self):
        return time.perf_counter() - self.t0

    def over(self):
        return self.budget is not None and self.now() > self.budget

    def say(self, what):
        print(f"[{self.now():6.1f} s] {what}", file=sys.stderr, flush=True)


OVERLAP = None  # --overlap / --no-overlap: BatchSimulation.overlap set on every batch (None: default)


def fresh(one, setups):
    """A fresh batch of ``one`` on the GPU, its set-up seconds kept in ``setups`` (not timed)."""
    t0 = time.perf_counter()
    sim = rtmpm.Simulation(one, backend="cuda", cuda_options=CUDA_OPTIONS)
    if OVERLAP is not None:
        sim.overlap = OVERLAP
    sim.step(1)  # the first step's graph capture is set-up, not the loop
    setups.append(time.perf_counter() - t0)
    return sim


def host_waits(sim):
    """The batch's host waits so far: ({reason: count}, {reason: seconds}), or None where the
    module has no such counter (``BatchSimulation.host_waits``; the seconds are zeros without
    ``RTMPM_SYNC_TRACE=1``)."""
    counts = getattr(sim, "host_waits", None)
    if counts is None:
        return None
    return counts, sim.host_wait_seconds


def p2g_redos(sim):
    """The P2G redos after resets so far, (worlds put alone, every world)
    (``BatchSimulation.p2g_redos``), or None where the module has no such counter."""
    return getattr(sim, "p2g_redos", None)


def redos_per_call(before, after, calls):
    """(redos of the worlds put alone, of every world) a call between two ``p2g_redos``."""
    if before is None or after is None:
        return None
    return ((after[0] - before[0]) / calls, (after[1] - before[1]) / calls)


def waits_per_call(before, after, calls):
    """{reason: (waits a call, ms waited a call)} between two ``host_waits`` readings."""
    if before is None or after is None:
        return None
    return {k: ((after[0][k] - before[0][k]) / calls, 1e3 * (after[1][k] - before[1][k]) / calls)
            for k in after[0]}


def plain_rounds(a, one, runs, torch, clock, setups):
    """The modes' rounds (the first a warm-up): {run: [wall s]}, the batch's info, the timed
    rounds done, and {run: host waits a call} and {run: P2G redos a call} of the last round
    (None where not counted)."""
    times = {r: [] for r in runs}
    waits = {r: None for r in runs}
    redos = {r: None for r in runs}
    info = {}
    done = 0
    for rep in range(a.repeats + 1):  # the first round warms up (kernel cache, pools), not counted
        if rep > 1 and clock.over():
            clock.say(f"budget of {a.budget} s spent: {done} timed rounds of {a.repeats}")
            break
        for run in runs if rep % 2 == 0 else runs[::-1]:
            sim = fresh(one, setups)
            over = bool(getattr(sim, "overlap", False))  # the mode this batch runs
            info = {"particles": int(sim.num_particles.sum()), "backend": sim.backend.name,
                    "overlap": over}
            w0, r0 = host_waits(sim), p2g_redos(sim)
            t0 = time.perf_counter()
            run_mode(run[0], sim, a.steps, run[1], a.resets, torch)
            if over:
                # The last call returned before its steps and check: both are timed (reading
                # `running` makes the check, waiting for the steps).
                ok_all = sim.running.all()
            wall = time.perf_counter() - t0
            if not over:
                ok_all = sim.running.all()
            assert ok_all, f"{run}: a world blew up: {sim.status}"
            waits[run] = waits_per_call(w0, host_waits(sim), a.steps // run[1])
            redos[run] = redos_per_call(r0, p2g_redos(sim), a.steps // run[1])
            if rep > 0:
                times[run].append(wall)
            del sim
        done = rep
        clock.say(f"round {rep} of {a.repeats} ({'warm-up' if rep == 0 else 'timed'}) done; a batch's "
                  f"set-up (not timed) {statistics.median(setups):.3f} s (median of {len(setups)})")
    return times, info, done, waits, redos


def print_redos(redos, runs):
    """The P2G redos a call of the modes that reset (the last round's;
    ``BatchSimulation.p2g_redos``)."""
    rows = [(run, redos[run]) for run in runs if redos[run] is not None and run[0] in ("reset", "loop")]
    if not rows:
        return
    print()
    print("P2G redos after the resets a call (the last round; RTMPM_BATCH_REDO=old: every world):")
    print("| mode | steps a call | worlds put alone | every world |")
    print("| --- | --- | --- | --- |")
    for (mode, k), (alone, every) in rows:
        print(f"| {mode} | {k} | {alone:.2f} | {every:.2f} |")


def print_waits(waits, runs):
    """The host's waits a call of each mode (the last round's; ``BatchSimulation.host_waits``:
    where the host blocked until the GPU had done queued work, by reason), and the ms they took
    where ``RTMPM_SYNC_TRACE=1`` timed them."""
    rows = [(run, waits[run]) for run in runs if waits[run] is not None]
    if not rows:
        print("host waits: not counted (the module has no BatchSimulation.host_waits)")
        return
    names = list(rows[0][1])
    traced = any(ms for _, w in rows for _, ms in w.values())
    print()
    print("host waits a call (the last round; counted where the host blocks until the GPU has done "
          "queued work" + (", ms waited a call in brackets" if traced else "; RTMPM_SYNC_TRACE=1 "
                           "also times them") + "):")
    print("| mode | steps a call | " + " | ".join(names) + " |")
    print("| --- | --- | " + " | ".join("---" for _ in names) + " |")
    for (mode, k), w in rows:
        cells = [f"{w[n][0]:.2f}" + (f" ({w[n][1]:.3f})" if traced and w[n][0] else "") for n in names]
        print(f"| {mode} | {k} | " + " | ".join(cells) + " |")


def breakdown_rounds(a, one, modes, per_call, torch, clock, setups):
    """``--breakdown``: {(mode, k): {part: [seconds a call]}, "rebuilds": [...]}, how the device was
    synchronised, the timed rounds done."""
    runs = [(m, k) for k in per_call for m in modes]
    got = {r: {"pose": [], "reset": [], "step": [], "rebuilds": []} for r in runs}
    how = None
    done = 0
    for rep in range(a.repeats + 1):
        if rep > 1 and clock.over():
            clock.say(f"budget of {a.budget} s spent: breakdown of {done} timed rounds of {a.repeats}")
            break
        for run in runs if rep % 2 == 0 else runs[::-1]:
            sim = fresh(one, setups)
            sync = device_sync(sim, torch)
            how = ("BatchSimulation.synchronize" if hasattr(sim, "synchronize")
                   else "torch.cuda.synchronize" if sync else "none (host time only)")
            parts, built = run_parts(run[0], sim, a.steps, run[1], a.resets, sync or (lambda: None))
            assert sim.running.all(), f"breakdown {run}: a world blew up: {sim.status}"
            if rep > 0:
                for part, xs in parts.items():
                    got[run][part].extend(xs)
                if built is not None:
                    got[run]["rebuilds"].append(built / (a.steps // run[1]))
            del sim
        done = rep
        clock.say(f"breakdown round {rep} of {a.repeats} ({'warm-up' if rep == 0 else 'timed'}) done")
    return got, how, done


def print_breakdown(got, how, done):
    """The breakdown's table: ms a call of each part (medians over every call of the timed
    rounds)."""
    print()
    print(f"breakdown ({done} timed rounds; the device synchronised after each part by {how}: these "
          "waits perturb the timings, which say where a call's time goes; the plain table is the "
          "measurement):")
    print("| mode | steps a call | poses ms | resets ms | steps ms | sum ms | step part - calls' ms "
          "| rebuilds a call |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    med = lambda xs: 1e3 * statistics.median(xs) if xs else 0.0  # noqa: E731
    for (mode, k), parts in got.items():
        if not parts["step"]:
            continue
        base = got.get(("calls", k), {}).get("step")
        extra = f"{med(parts['step']) - med(base):+.3f}" if base else "-"
        rb = f"{statistics.mean(parts['rebuilds']):.2f}" if parts["rebuilds"] else "not counted"
        pose_ms = f"{med(parts['pose']):.3f}" if parts["pose"] else "-"
        reset_ms = f"{med(parts['reset']):.3f}" if parts["reset"] else "-"
        total = med(parts["pose"]) + med(parts["reset"]) + med(parts["step"])
        print(f"| {mode} | {k} | {pose_ms} | {reset_ms} | {med(parts['step']):.3f} | {total:.3f} | {extra} | {rb} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", type=int, default=256)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--per-call", default="1,10", help="steps per Python call, a comma list (default 1,10)")
    ap.add_argument("--resets", type=int, default=4, help="worlds reset before every call (default 4)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--budget", type=float, default=None,
                    help="seconds after which no further round starts (default: no limit)")
    ap.add_argument("--breakdown", action="store_true",
                    help="also time a call's poses, resets and steps on their own (perturbing)")
    ap.add_argument("--moving-tool", action="store_true",
                    help="the scene's tool moves down at 0.2 m/s in every mode (default: static "
                         "but where posed, as the figures in bench/RESULTS.md)")
    ap.add_argument("--cuda-options", default=None,
                    help="the CUDA backend's options for every batch (rtmpm --cuda-options), e.g. "
                         "body_sums=step for the sums copied after every step")
    ap.add_argument("--overlap", nargs="?", const="on", default=None, choices=["on", "off"],
                    help="BatchSimulation.overlap on (bare --overlap, or --overlap on: step calls "
                         "return before their check) or off (--overlap off); default: the "
                         "module's (on for a GPU batch unless RTMPM_BATCH_OVERLAP=0)")
    ap.add_argument("--no-overlap", dest="overlap", action="store_const", const="off",
                    help="BatchSimulation.overlap off: each step call checks before it returns "
                         "(the old behaviour; same as --overlap off)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    global CUDA_OPTIONS, OVERLAP
    CUDA_OPTIONS = a.cuda_options
    OVERLAP = None if a.overlap is None else a.overlap == "on"
    clock = Clock(a.budget)
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
    one, no_tool = make_batch(a.worlds, a.moving_tool)
    clock.say("scene made; the first batch compiles the kernels (or takes them from the cache)")
    modes = ["bare", "calls", "reset"] + ([] if no_tool else ["pose"]) + ["loop"]
    modes += ["device"] if torch is not None else []
    runs = [("bare", a.steps)] + [(m, k) for k in per_call for m in modes if m != "bare"]
    setups = []
    times, info, done, waits, redos = plain_rounds(a, one, runs, torch, clock, setups)
    bare = statistics.median(times[("bare", a.steps)])
    print(f"{a.worlds} worlds, {info['particles']} particles, {a.steps} steps, {a.resets} resets a call, "
          f"{done} repeats, on {info['backend']}; overlap {'on' if info['overlap'] else 'off'} "
          f"({'default' if a.overlap is None else ('--overlap' if OVERLAP else '--no-overlap')})")
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
                     "ratio_to_bare": med / bare, "host_waits_per_call": waits[(mode, k)],
                     "p2g_redos_per_call": redos[(mode, k)]})
        print(f"| {mode} | {k} | {summary(times[(mode, k)])} | {1e3 * med / calls:.3f} | {med / bare:.3f} |")
    print(f"bare: {1e3 * bare / a.steps:.3f} ms a step of the {a.worlds} worlds "
          f"({info['particles'] * a.steps / bare / 1e6:.1f} M particle-steps/s); bound: loop / bare <= 1.10")
    print(f"a fresh batch's set-up (not timed): median {statistics.median(setups):.3f} s of {len(setups)}; "
          f"{clock.now():.1f} s so far", flush=True)
    print_waits(waits, runs)
    print_redos(redos, runs)
    names = ("RTMPM_BATCH_WAITS", "RTMPM_BATCH_PAGEABLE_PUT", "RTMPM_BATCH_RESET", "RTMPM_BATCH_REST",
             "RTMPM_KINEMATIC", "RTMPM_BATCH_FAN", "RTMPM_BATCH_REDO", "RTMPM_BATCH_UPLOAD",
             "RTMPM_BATCH_PUT", "RTMPM_SYNC_TRACE")
    switches = {k: os.environ[k] for k in names if k in os.environ}
    if switches:
        print(f"environment: {switches}")
    if a.moving_tool:
        print("the tool moves down at 0.2 m/s in every mode (--moving-tool)")
    if a.cuda_options:
        print(f"cuda_options: {a.cuda_options}")
    out = {"worlds": a.worlds, "steps": a.steps, "resets": a.resets, "repeats": done, "per_call": per_call,
           "moving_tool": a.moving_tool, "cuda_options": a.cuda_options, "overlap_asked": a.overlap,
           "pose_not_measured": no_tool, "torch": torch is not None, **info, "rows": rows,
           "setup_s": setups}
    if a.breakdown:
        parts_modes = [m for m in ("calls", "reset", "pose", "loop") if m in modes]
        got, how, bdone = breakdown_rounds(a, one, parts_modes, per_call, torch, clock, setups)
        print_breakdown(got, how, bdone)
        out["breakdown"] = {"synchronised_by": how, "repeats": bdone,
                            "rows": [{"mode": m, "steps_per_call": k, **parts} for (m, k), parts in got.items()]}
    print(f"{clock.now():.1f} s in all", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
