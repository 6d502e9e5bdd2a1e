"""Batches of worlds on one GPU from Python (BatchSimulation(scene, backend="cuda"): every world
in the same CUDA kernels, rtmpm_cuda::batch::CudaBatch, stepped together by rtmpm-driver's
LockstepRun): each world agrees with its separate CUDA run (the agreement test's aggregate
tolerances: CUDA atomics are not bit-reproducible), resets and blow-ups leave the other worlds
as without them, what the GPU batch does not do raises an error naming it, and the particles
reach PyTorch and CuPy on the device (x_device / v_device equal to the host arrays, ragged worlds
by their offsets, storage views of the batch's own memory). Skipped without a usable GPU; run on
the GPU machine by scripts/gpu/python.sh."""

import csv
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import rtmpm
from test_batch import TOOL_SCENE, YIELDS, sweep_text, world_text

ok, why = rtmpm.cuda_available()
pytestmark = pytest.mark.skipif(not ok, reason=f"no usable GPU: {why}")

DX = 0.03125  # the slump's cell (test_batch.SLUMP)


def alone_cuda(text, frames):
    """x, v of a separate CUDA Simulation of `text` after `frames` frames."""
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    for _ in range(frames):
        sim.run_frame()
    return sim.particles.x.copy(), sim.particles.v.copy()


def agree(what, x, v, xa, va, dx=DX):
    """The agreement test's aggregate tolerances (crates/rtmpm-cuda/tests/agreement.rs, as
    crates/rtmpm-cuda/tests/common/batch.rs compares a batch's world with its separate run):
    centre of mass within 0.1 cell, kinetic energy (equal masses) within 2 %, bounding box within
    a cell."""
    assert x.shape == xa.shape, what
    com = np.linalg.norm(x.mean(0) - xa.mean(0))
    ke, kea = (v.astype(np.float64) ** 2).sum(), (va.astype(np.float64) ** 2).sum()
    box = max(np.abs(x.min(0) - xa.min(0)).max(), np.abs(x.max(0) - xa.max(0)).max())
    print(f"{what}: |d com| {com / dx:.4f} dx, KE {ke:.4e} vs {kea:.4e}, |d bbox| {box / dx:.3f} dx")
    assert com <= 0.1 * dx, f"{what}: centre of mass {com / dx:.3f} cells away"
    assert abs(ke - kea) <= 0.02 * max(kea, 1e-12), f"{what}: kinetic energy {ke} vs {kea}"
    assert box <= dx, f"{what}: bounding box {box / dx:.3f} cells away"


def test_the_worlds_run_in_the_same_kernels_and_agree_with_their_separate_runs():
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    sim = rtmpm.Simulation(scene, backend="cuda")
    assert isinstance(sim, rtmpm.BatchSimulation)
    assert sim.backend.kind == "cuda" and "same kernels" in sim.backend.reason, sim.backend.reason
    assert "3 worlds" in sim.backend.name
    auto = rtmpm.Simulation(scene)
    assert auto.backend.kind == "cuda" and auto.backend.reason.startswith("auto -> "), auto.backend.reason
    x0 = sim.x.copy()
    n = int(sim.num_particles[0])
    assert x0.shape == (3, n, 3) and sim.uniform and sim.material.shape == (3, n)
    assert sim.run(3) == []
    assert list(sim.frame) == [3, 3, 3] and list(sim.steps) == [150, 150, 150]
    np.testing.assert_allclose(sim.time, 0.15)
    x, v = sim.x, sim.v
    for w, y in enumerate(YIELDS):
        xa, va = alone_cuda(world_text(y), 3)
        agree(f"world {w}", x[w], v[w], xa, va)
    assert not np.allclose(x[0], x[2]), "the sweep reaches the worlds"
    assert sim.step(7) == [] and list(sim.steps) == [157] * 3


def test_a_reset_world_starts_again_and_the_others_go_on():
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    sim = rtmpm.Simulation(scene, backend="cuda")
    x0 = sim.x.copy()
    sim.run(2)
    sim.reset([1])
    assert list(sim.frame) == [2, 0, 2] and sim.time[1] == 0.0 and list(sim.steps) == [100, 0, 100]
    np.testing.assert_array_equal(sim.x[1], x0[1])
    sim.run(2)
    # The step after the reset redid the P2G of world 1 alone (1 of 3 worlds; the kernels do
    # nothing where that step rebuilds the mapping), or of every world with RTMPM_BATCH_REDO=old.
    alone, every = sim.p2g_redos
    if os.environ.get("RTMPM_BATCH_REDO") == "old":
        assert alone == 0 and every >= 1, sim.p2g_redos
    else:
        assert alone >= 1, sim.p2g_redos
    assert list(sim.frame) == [4, 2, 4]
    x, v = sim.x, sim.v
    for w, frames in [(0, 4), (1, 2), (2, 4)]:
        xa, va = alone_cuda(world_text(YIELDS[w]), frames)
        agree(f"world {w} after world 1's reset", x[w], v[w], xa, va)
    # A reset to given positions, then every world reset: the clock starts again.
    moved = x0[2].copy()
    moved[:, 0] += 0.05
    sim.reset([2], x=moved[None])
    np.testing.assert_array_equal(sim.x[2], moved)
    sim.reset()
    assert list(sim.steps) == [0, 0, 0]
    np.testing.assert_array_equal(sim.x, x0)


def test_a_world_that_blows_up_is_frozen_and_the_others_go_on():
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    x0 = sim.x.copy()
    assert sim.run(2) == [1]
    st = sim.status[1]
    assert st["state"] == "frozen" and st["frame"] == 0 and st["reason"], st
    assert list(sim.running) == [True, False, True]
    np.testing.assert_array_equal(sim.x[1], x0[1])
    x, v = sim.x, sim.v
    for w, vel in [(0, (0, 0, 0)), (2, (0, 0.5, 0))]:
        xa, va = alone_cuda(world_text(velocity=vel), 2)
        agree(f"world {w} beside a frozen one", x[w], v[w], xa, va)
    sim.reset([1], v=np.zeros_like(x0[1]))
    assert list(sim.running) == [True, True, True]
    assert sim.step(1) == []


def test_overlap_is_on_by_default_on_the_gpu_and_rtmpm_batch_overlap_0_turns_it_off(monkeypatch):
    """A GPU batch's ``overlap`` is on by default (``RTMPM_BATCH_OVERLAP`` unset or ``1``): world
    1's blow-up in the first ``step(10)`` is not returned by it, ``running`` (which waits for the
    check) then shows it frozen, and the next ``step`` returns it. ``RTMPM_BATCH_OVERLAP=0`` (or
    ``off``) as the batch is made turns the default off: the call returns it itself, as the CPU
    batch does (off there whatever the variable says). A few seconds on an H200."""
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')
    scene = rtmpm.Scene.from_toml(text)
    for var in (None, "1"):
        if var is None:
            monkeypatch.delenv("RTMPM_BATCH_OVERLAP", raising=False)
        else:
            monkeypatch.setenv("RTMPM_BATCH_OVERLAP", var)
        sim = rtmpm.Simulation(scene, backend="cuda")
        assert sim.backend.kind == "cuda" and sim.overlap is True, var
        assert sim.step(10) == [], var
        assert list(sim.running) == [True, False, True], var
        assert sim.step(5) == [1], var
        assert sim.step(1) == [] and list(sim.steps) == [16, 0, 16], var
    for var in ("0", "off"):
        monkeypatch.setenv("RTMPM_BATCH_OVERLAP", var)
        sim = rtmpm.Simulation(scene, backend="cuda")
        assert sim.overlap is False, var
        assert sim.step(10) == [1], var
        sim.overlap = True  # the way back on, per batch
        assert sim.overlap is True and sim.step(1) == [], var
    monkeypatch.setenv("RTMPM_BATCH_OVERLAP", "1")
    cpu = rtmpm.Simulation(scene, backend="cpu")
    assert cpu.overlap is False and cpu.step(10) == [1]


def test_with_overlap_a_blow_up_is_returned_a_call_later_and_ends_as_without_it():
    """``overlap``: a step call returns before its check; world 1's blow-up in the first call is
    found as the second begins (after a reset of world 2 made meanwhile, made again after the
    rewind) and returned by it; the statuses and clocks end as without overlap, the particles
    within the agreement tolerances (the rewind's steps are taken again: CUDA's atomic sums are
    not bit-reproducible)."""
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')

    def run(overlap):
        sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
        sim.overlap = overlap
        assert sim.overlap == overlap
        calls = [sim.step(10)]
        sim.reset([2])
        calls += [sim.step(10), sim.step(5)]
        return sim, calls

    plain, plain_calls = run(False)
    over, over_calls = run(True)
    assert plain_calls == [[1], [], []]
    assert over_calls == [[], [1], []]
    assert [s["state"] for s in over.status] == ["running", "frozen", "running"]
    # The reason names the bad particle the device saw first (which may differ between runs).
    brief = lambda sim: [(s["state"], s["frame"], s["steps"], bool(s["reason"])) for s in sim.status]  # noqa: E731
    assert brief(over) == brief(plain)
    assert list(over.steps) == list(plain.steps) == [25, 0, 15]
    np.testing.assert_array_equal(over.time, plain.time)
    x, v, xp, vp = over.x, over.v, plain.x, plain.v
    np.testing.assert_array_equal(x[1], xp[1])  # the frozen world's last good state: its start
    for w in (0, 2):
        agree(f"world {w} with overlap", x[w], v[w], xp[w], vp[w])
    over.overlap = False
    assert over.step(1) == [] and list(over.steps) == [26, 0, 16]


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
@pytest.mark.skipif(os.environ.get("RTMPM_BATCH_WAITS") == "old",
                    reason="RTMPM_BATCH_WAITS=old: the waits counted are the new paths'")
def test_a_loop_with_overlap_waits_only_for_its_checks():
    """The issue's loop (16 worlds; every call poses every world's tool, resets 2 worlds, steps
    10) waits for the GPU only for its checks (``host_waits``): one a call and one a frame end
    inside a call (with ``overlap`` each made as the next call begins, waiting for its copy of
    the control words alone), no read of control words or sums, no copy from pageable memory, no
    synchronisation, no wait for page-locked memory in use, at most 4 buffers allocated after
    the warm-up (the rings grow while the host gets further ahead than before); the same without ``overlap`` (each call's checks made at once). A few seconds on
    an H200."""
    scene = rtmpm.Scene.from_toml(TOOL_SCENE)
    n, calls, per_frame = 16, 12, 40  # TOOL_SCENE: dt = 5e-4 s, 50 frames a second
    vel = np.tile(np.array([0.0, -0.2, 0.0], np.float32), (n, 1))
    for overlap in (True, False):
        sim = rtmpm.Simulation(scene, batch=n, backend="cuda")
        assert sim.backend.kind == "cuda", sim.backend.reason
        sim.overlap = overlap
        pos = np.tile(np.array([0.2, 0.27, 0.2], np.float32), (n, 1))

        def call(c):
            pos[:, 1] -= 1e-4
            sim.set_rigid_body("tool", position=pos, velocity=vel)
            sim.reset([(2 * c) % n, (2 * c + 1) % n])
            assert sim.step(10) == [], f"call {c}"

        assert sim.step(1) == []  # frame ends (every 40 steps) then fall inside calls
        for c in range(5):
            call(c)
        assert sim.running.all()  # the pending check made
        before = sim.host_waits
        first = 1 + 10 * 5
        for c in range(5, 5 + calls):
            call(c)
        assert sim.running.all()
        after = sim.host_waits
        waits = {k: after[k] - before[k] for k in after}
        frames = sum(1 for s in range(first + 1, first + 10 * calls + 1) if s % per_frame == 0)
        print(f"overlap {overlap}: {calls} calls, {frames} frame ends inside them: waits {waits}")
        assert waits["check"] == calls + frames, waits
        for k in ("control", "read", "sums", "staging", "pageable", "sync"):
            assert waits[k] == 0, f"overlap {overlap}: {k} waits: {waits}"
        assert waits["alloc"] <= 4, waits
    cpu = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cpu")
    assert cpu.host_waits is None and cpu.host_wait_seconds is None


def test_calls_of_one_step_give_one_calls_worlds_and_x_is_read_when_asked_for():
    """A step loop reads nothing back (the rewind point is on the device, docs/batch.md): 60
    calls of step(1) give the worlds of one step(60) call, bit for bit when the GPU repeats
    itself (two step(60) runs bit-identical), else within the agreement tolerances; x and v,
    read when asked for, are the state after the last call (they move between calls)."""
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))

    def run(calls):
        sim = rtmpm.Simulation(scene, backend="cuda")
        for k in calls:
            assert sim.step(k) == []
        assert list(sim.steps) == [sum(calls)] * 3
        return sim

    ones, whole, again = run([1] * 60), run([60]), run([60])
    repeats = np.array_equal(whole.x, again.x) and np.array_equal(whole.v, again.v)
    print(f"two runs of step(60) bit-identical: {repeats}")
    x, v, xw, vw = ones.x, ones.v, whole.x, whole.v
    for w in range(3):
        if repeats:
            np.testing.assert_array_equal(x[w], xw[w], err_msg=f"world {w}")
            np.testing.assert_array_equal(v[w], vw[w], err_msg=f"world {w}")
        else:
            agree(f"world {w}: 60 calls of step(1) vs step(60)", x[w], v[w], xw[w], vw[w])
    before = ones.x.copy()
    ones.step(5)
    assert not np.array_equal(ones.x, before), "x is the state after the last call"


def test_what_the_gpu_batch_does_not_do_raises_naming_it_and_the_cpu(tmp_path):
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cuda")
    # Without rigid bodies there is no body 0 to pose or read, as on the CPU.
    for call in (lambda: sim.set_rigid_body(0, velocity=[0, 0, 0]), lambda: sim.rigid_force(0)):
        with pytest.raises(IndexError, match="rigid body 0 does not exist"):
            call()
    assert sim.rigid_bodies(0) == []
    emitting = world_text() + (
        "[[emitter]]\nmaterial = \"mud\"\nshape = \"box\"\nmin = [0.2, 0.35, 0.2]\n"
        "max = [0.25, 0.37, 0.25]\nvelocity = [0.0, -1.0, 0.0]\nvolume_rate = 1e-4\n")
    with pytest.raises(rtmpm.BackendError, match="cannot run on the GPU: world 0 has emitters"):
        rtmpm.Simulation(rtmpm.Scene.from_toml(emitting), batch=2, backend="cuda")
    # Worlds of different sizes (the same domain): flat arrays, as on the CPU.
    text = sweep_text('"body[0].max" = [[0.3, 0.25, 0.3], [0.3, 0.3, 0.3], [0.35, 0.25, 0.3]]')
    ragged = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    assert not ragged.uniform and ragged.x.shape == (int(ragged.num_particles.sum()), 3)
    # A collider moving with the shared clock: only every world at once is reset.
    moving = world_text() + (
        "[[collider]]\nshape = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [0.1, 0.5, 0.5]\n"
        "velocity = [0.1, 0.0, 0.0]\n")
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(moving), batch=2, backend="cuda")
    sim.run(1)
    with pytest.raises(rtmpm.SimulationError, match="collider 0 moves"):
        sim.reset([0])
    assert list(sim.frame) == [1, 1]
    sim.reset()
    assert list(sim.steps) == [0, 0]


def test_a_resumed_gpu_batch_goes_on_as_the_uninterrupted_one(tmp_path):
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    sim = rtmpm.Simulation(scene, backend="cuda")
    sim.run(2)
    sim.checkpoint(tmp_path / "ckpt")
    saved = sim.x.copy(), sim.v.copy()
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == [
        "batch.toml", "world_000.ckpt", "world_001.ckpt", "world_002.ckpt"]
    sim.run(2)
    again = rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, backend="cuda")
    assert again.backend.kind == "cuda" and list(again.frame) == [2, 2, 2] and list(again.steps) == [100] * 3
    # The state put back is the state saved, exactly (the same floats up and down).
    np.testing.assert_array_equal(again.x, saved[0])
    np.testing.assert_array_equal(again.v, saved[1])
    again.run(2)
    assert list(again.frame) == list(sim.frame) == [4, 4, 4]
    x, v, xs, vs = again.x, again.v, sim.x, sim.v
    for w in range(3):
        agree(f"world {w} resumed vs uninterrupted", x[w], v[w], xs[w], vs[w])
    # The same checkpoint on the CPU: each world at its own clock, as saved.
    cpu = rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, backend="cpu")
    np.testing.assert_array_equal(cpu.x, saved[0])
    # Worlds reset at different times cannot share one clock again.
    sim.reset([1])
    sim.checkpoint(tmp_path / "odd")
    with pytest.raises(rtmpm.RtmpmError, match="different times"):
        rtmpm.BatchSimulation.resume(tmp_path / "odd", scene, backend="cuda")


# ---- Device arrays of a GPU batch (x_device, v_device: gathered; storage_device: no copy) ----

def torch_or_skip():
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("PyTorch without CUDA")
    return torch


def test_gathered_device_arrays_are_the_host_arrays_and_follow_the_batch():
    torch = torch_or_skip()
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    sim = rtmpm.Simulation(scene, backend="cuda")
    n = int(sim.num_particles[0])
    xd = sim.x_device
    assert xd.shape == [3, n, 3] and xd.dtype == "float32" and xd.strides == [12 * n, 12, 4]
    x = torch.from_dlpack(xd)
    v = torch.from_dlpack(sim.v_device)
    assert x.is_cuda and x.shape == (3, n, 3) and x.is_contiguous() and x.data_ptr() == xd.ptr
    np.testing.assert_array_equal(x.cpu().numpy(), sim.x)
    np.testing.assert_array_equal(v.cpu().numpy(), sim.v)
    # Tensors made once follow the batch: after steps and a reset they hold the new host arrays,
    # in the same memory.
    sim.run(2)
    assert sim.x_device.ptr == xd.ptr
    np.testing.assert_array_equal(x.cpu().numpy(), sim.x)
    np.testing.assert_array_equal(v.cpu().numpy(), sim.v)
    assert not np.array_equal(x[0].cpu().numpy(), x[2].cpu().numpy()), "the worlds differ"
    x0 = x.clone()
    sim.step(3)
    np.testing.assert_array_equal(x.cpu().numpy(), sim.x)
    assert not torch.equal(x, x0), "the view moved on with the steps"
    sim.reset([1])
    np.testing.assert_array_equal(x.cpu().numpy(), sim.x)
    np.testing.assert_array_equal(v.cpu().numpy(), sim.v)
    # Each world in its own coordinates: inside its own domain (the scene's, [0, 0.5]^3).
    assert float(x.min()) >= 0.0 and float(x.max()) <= 0.5


def test_gathered_device_arrays_of_ragged_worlds_are_cut_by_the_offsets():
    torch = torch_or_skip()
    text = sweep_text('"body[0].max" = [[0.3, 0.25, 0.3], [0.3, 0.3, 0.3], [0.35, 0.25, 0.3]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    assert not sim.uniform
    off = sim.offsets
    total = int(off[-1])
    counts = sim.num_particles
    assert len(set(int(c) for c in counts)) == 3, "three different sizes"
    x = torch.from_dlpack(sim.x_device)
    v = torch.from_dlpack(sim.v_device)
    assert x.shape == (total, 3) and v.shape == (total, 3)
    # At time 0 each world's rows are its own body in its own coordinates: world 1's is the
    # tall one (to y = 0.3 m), world 2's the wide one (to x = 0.35 m).
    for w in range(3):
        rows = slice(int(off[w]), int(off[w + 1]))
        top = x[rows].max(0).values.cpu().numpy()
        assert (top[1] > 0.26) == (w == 1) and (top[0] > 0.31) == (w == 2), f"world {w}: {top}"
        assert float(x[rows, 0].min()) >= 0.19, f"world {w} lies in its own coordinates"
    sim.run(1)
    host_x, host_v = sim.x, sim.v
    np.testing.assert_array_equal(x.cpu().numpy(), host_x)
    for w in range(3):
        rows = slice(int(off[w]), int(off[w + 1]))
        np.testing.assert_array_equal(x[rows].cpu().numpy(), host_x[rows], err_msg=f"world {w}")
        np.testing.assert_array_equal(v[rows].cpu().numpy(), host_v[rows], err_msg=f"world {w}")


def test_a_reset_puts_back_exactly_the_worlds_listed_on_the_device():
    """reset(worlds) on the GPU puts the worlds back from the image of their initial particles
    that the batch keeps on the device (no packing, no upload; RTMPM_BATCH_RESET=old: packed and
    uploaded as before): read on the device right after (x_device / v_device, gathered after the
    call), the worlds listed (out of order) hold exactly their own initial particles
    (ragged worlds: another world's range, or an offset one, would not fit), the other world
    exactly as before the reset."""
    torch = torch_or_skip()
    text = sweep_text('"body[0].max" = [[0.3, 0.25, 0.3], [0.3, 0.3, 0.3], [0.35, 0.25, 0.3]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    off = sim.offsets
    rows = [slice(int(off[w]), int(off[w + 1])) for w in range(3)]
    x0, v0 = sim.x.copy(), sim.v.copy()
    xd, vd = torch.from_dlpack(sim.x_device), torch.from_dlpack(sim.v_device)
    sim.run(1)
    before_x, before_v = xd.cpu().numpy().copy(), vd.cpu().numpy().copy()
    for w in (0, 2):
        assert not np.array_equal(before_x[rows[w]], x0[rows[w]]), f"world {w} did not move"
    sim.reset([2, 0])  # a world listed twice is refused (test_batch.py)
    x, v = xd.cpu().numpy(), vd.cpu().numpy()
    for w, (want_x, want_v) in enumerate([(x0, v0), (before_x, before_v), (x0, v0)]):
        np.testing.assert_array_equal(x[rows[w]], want_x[rows[w]], err_msg=f"world {w}'s x")
        np.testing.assert_array_equal(v[rows[w]], want_v[rows[w]], err_msg=f"world {w}'s v")
    assert sim.step(5) == [] and list(sim.steps) == [5, 55, 5]


def test_storage_views_are_the_batchs_own_memory_and_map_to_worlds():
    torch = torch_or_skip()
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    sim = rtmpm.Simulation(scene, backend="cuda")
    sim.run(1)
    n = int(sim.num_particles[0])
    total = 3 * n
    xs = sim.storage_device("x")
    assert xs.shape == [total, 3]
    x = torch.from_dlpack(xs)
    assert x.data_ptr() == xs.ptr  # no copy: the batch's state buffer
    ids = torch.from_dlpack(sim.storage_device("id")).cpu().numpy()
    assert sorted(ids.tolist()) == list(range(total))
    # Every world shares one buffer: the x rows of id's original order are the flat host x.
    flat_x = sim.x.reshape(-1, 3)
    out = np.empty_like(flat_x)
    out[ids] = x.cpu().numpy()
    np.testing.assert_array_equal(out, flat_x)
    vs = torch.from_dlpack(sim.storage_device("v")).cpu().numpy()
    out[ids] = vs
    np.testing.assert_array_equal(out, sim.v.reshape(-1, 3))
    # The per-world offsets: slot j's world from its id and from its material row agree.
    m = len(scene.materials)
    mat = torch.from_dlpack(sim.storage_device("material")).cpu().numpy()
    world_of_id = np.searchsorted(sim.offsets, ids, side="right") - 1
    np.testing.assert_array_equal(world_of_id, mat // m)
    np.testing.assert_array_equal(mat % m, sim.material.reshape(-1)[ids])
    # The worlds interleave in storage (sorted by grid block): why x_device is a gather.
    print("storage order's world changes:", int((np.diff(world_of_id) != 0).sum()))
    mass = torch.from_dlpack(sim.storage_device("mass")).cpu().numpy()
    np.testing.assert_array_equal(mass, sim.mass.reshape(-1)[ids])
    with pytest.raises(ValueError, match="no such field"):
        sim.storage_device("pressure")


def test_device_arrays_keep_the_batch_alive_and_cupy_reads_them():
    torch = torch_or_skip()
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cuda")
    sim.step(2)
    expect = sim.x.copy()
    x = torch.from_dlpack(sim.x_device)
    del sim
    import gc

    gc.collect()
    np.testing.assert_array_equal(x.cpu().numpy(), expect)
    cupy = pytest.importorskip("cupy")
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cuda")
    xd = sim.x_device
    cai = xd.__cuda_array_interface__
    assert cai["version"] == 3 and cai["typestr"] == "<f4" and cai["shape"] == tuple(xd.shape)
    c = cupy.asarray(xd)
    assert c.data.ptr == xd.ptr
    np.testing.assert_array_equal(cupy.asnumpy(c), sim.x)


def test_a_frozen_worlds_device_rows_are_its_host_rows():
    torch = torch_or_skip()
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cuda")
    x = torch.from_dlpack(sim.x_device)
    v = torch.from_dlpack(sim.v_device)
    assert sim.run(2) == [1]
    # World 1 froze at its start: the GPU holds it parked (at rest), the arrays its last good
    # state, as the host arrays.
    np.testing.assert_array_equal(v.cpu().numpy(), sim.v)
    np.testing.assert_array_equal(x.cpu().numpy(), sim.x)
    assert float(v[1, :, 0].max()) > 1e4
def tool_loads(sim, steps, window):
    """`steps` steps; the mean force on the tool per world over the last `window`."""
    sim.step(steps - window)
    total = np.zeros((len(sim), 3))
    for _ in range(window):
        sim.step()
        total += sim.rigid_force("tool")
    return total / window


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_a_tool_posed_per_world_on_the_gpu_feels_what_the_cpu_batch_feels():
    """Per-world tool poses on the GPU (every world's tool in the same kernels): world 0 keeps its
    tool in the air, 1 and 2 press it into the sand at 0.2 and 0.4 m/s. Each world's particles
    agree with its separate CUDA run posed the same way (the aggregate tolerances; the run's
    bodies moved by each step before the next, rigid_overlap=off, as the batch moves them), its
    tool is where that run's is, and the mean force on it over the last 10 of 40 steps is within
    10 % of the CPU batch's (the sand's load). A few
    seconds on an H200."""
    scene = rtmpm.Scene.from_toml(TOOL_SCENE)
    poses = [[0.2, 0.27, 0.2], [0.2, 0.19, 0.2], [0.2, 0.19, 0.2]]
    speeds = np.array([[0, 0, 0], [0, -0.2, 0], [0, -0.4, 0]], np.float32)
    loads = {}
    for backend in ("cuda", "cpu"):
        sim = rtmpm.Simulation(scene, batch=3, backend=backend)
        assert sim.backend.kind == backend, sim.backend.reason
        assert np.all(sim.rigid_force("tool") == 0.0)  # before a step
        sim.set_rigid_body("tool", position=poses)
        sim.set_rigid_body("tool", worlds=[1, 2], velocity=speeds[1:])
        loads[backend] = tool_loads(sim, 40, 10)
        if backend == "cuda":
            gpu = sim
    f, fc = loads["cuda"], loads["cpu"]
    print(f"mean force on the tool (N): GPU {f.tolist()}, CPU {fc.tolist()}")
    assert np.all(f[0] == 0.0), "a tool in the air feels nothing"
    assert f[1, 1] > 0.0 and f[2, 1] > f[1, 1], f"the sand pushes back, harder on the faster tool: {f}"
    for w in (1, 2):
        assert np.linalg.norm(f[w] - fc[w]) <= 0.1 * np.linalg.norm(fc[w]), f"world {w}: {f[w]} vs CPU {fc[w]}"
    assert gpu.rigid_torque("tool").shape == (3, 3)
    states = [gpu.rigid_bodies(w)[0] for w in range(3)]
    assert "force" in states[1] and states[0]["position"][1] == pytest.approx(0.27)
    x, v = gpu.x, gpu.v
    for w in range(3):
        alone = rtmpm.Simulation(scene, backend="cuda", cuda_options="rigid_overlap=off")
        alone.set_rigid_body("tool", position=poses[w], velocity=speeds[w].tolist())
        alone.step(40)
        agree(f"world {w} with its tool", x[w], v[w], alone.particles.x, alone.particles.v, dx=0.025)
        mine, theirs = states[w]["position"], alone.rigid_bodies[0]["position"]
        assert np.allclose(mine, theirs, atol=1e-6), f"world {w}: tool at {mine}, its run's at {theirs}"
    # Bad poses are refused naming the world, as on the CPU.
    with pytest.raises(ValueError, match="world 1: rigid body `tool`"):
        gpu.set_rigid_body("tool", worlds=[0, 1], position=[[0.2, 0.27, 0.2], [0.2, 5.0, 0.2]])
    # A reset world's tool goes back to its pose at time 0 (the scene's); the others' stay.
    before = gpu.rigid_bodies(2)[0]["position"]
    gpu.reset([1])
    assert gpu.rigid_bodies(1)[0]["position"] == pytest.approx([0.2, 0.28, 0.2])
    assert gpu.rigid_bodies(2)[0]["position"] == pytest.approx(before)


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_a_tool_posed_in_every_world_at_once_is_posed_as_world_by_world():
    """One set_rigid_body call for every world (the GPU batch checks every world's pose, then
    sets them on every core) leaves each world's tool bit for bit as one call a world does, by
    name or by index, and the steps after go on alike (each world's rapier world on the host);
    a refused row names its world, the worlds before it posed and the others not; a tool posed
    mid-run after a reset is where it was put. synchronize() returns, rebuilds counts. A few
    seconds on an H200."""
    scene = rtmpm.Scene.from_toml(TOOL_SCENE)
    n = 4
    pos = np.array([[0.2, 0.27 - 0.01 * w, 0.2] for w in range(n)], np.float32)
    vel = np.array([[0.0, -0.1 * w, 0.02] for w in range(n)], np.float32)
    spin = np.array([0.0, 0.5, 0.0], np.float32)
    at_once = rtmpm.Simulation(scene, batch=n, backend="cuda")
    one_by_one = rtmpm.Simulation(scene, batch=n, backend="cuda")
    assert at_once.backend.kind == "cuda", at_once.backend.reason

    def bodies(sim):
        return [{k: list(v) for k, v in sim.rigid_bodies(w)[0].items() if k != "force" and k != "torque"}
                for w in range(n)]

    for step in range(3):
        at_once.set_rigid_body("tool", position=pos + 0.001 * step, velocity=vel, angular_velocity=spin)
        for w in range(n):
            one_by_one.set_rigid_body(0, worlds=[w], position=pos[w] + 0.001 * step, velocity=vel[w],
                                      angular_velocity=spin)
        assert bodies(at_once) == bodies(one_by_one), f"call {step}"
        at_once.step(5)
        one_by_one.step(5)
        assert bodies(at_once) == bodies(one_by_one), f"after call {step}'s steps"
    before = bodies(at_once)
    bad = pos.copy()
    bad[2, 1] = 5.0  # outside the domain
    moved = pos + np.float32(0.01)
    with pytest.raises(ValueError, match="world 2: rigid body `tool`"):
        at_once.set_rigid_body("tool", position=np.where(np.arange(n)[:, None] == 2, bad, moved))
    after = bodies(at_once)
    for w in (0, 1):
        assert after[w]["position"] == pytest.approx(moved[w].tolist(), abs=1e-7), f"world {w} posed"
    for w in (2, 3):
        assert after[w] == before[w], f"world {w} untouched"
    with pytest.raises(KeyError, match="no rigid body named `spoon`"):
        at_once.set_rigid_body("spoon", position=pos)
    with pytest.raises(IndexError, match="rigid body 1 does not exist"):
        at_once.set_rigid_body(1, position=pos)
    at_once.reset([1])
    at_once.set_rigid_body("tool", worlds=[1], position=[0.2, 0.22, 0.2])
    assert at_once.rigid_bodies(1)[0]["position"] == pytest.approx([0.2, 0.22, 0.2])
    at_once.synchronize()
    built = at_once.rebuilds
    assert isinstance(built, int) and built >= 1, built
    at_once.step(1)
    assert at_once.rebuilds >= built


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_the_batch_push_example_runs_on_the_gpu(tmp_path):
    """examples/python/batch_push.py with --backend cuda: 3 sand beds for 2 frames (100 steps, the
    tool posed in every world each step), a CSV row per world and frame; the drag grows with
    the friction angle once the tool is in the sand is the example's point, not checked here.
    About 10 s on an H200."""
    example = pathlib.Path(__file__).resolve().parents[3] / "examples" / "python" / "batch_push.py"
    out = tmp_path / "push.csv"
    r = subprocess.run([sys.executable, str(example), "--worlds", "3", "--frames", "2", "--backend", "cuda",
                        "--out", str(out)], capture_output=True, text=True, timeout=300)
    print(r.stdout, r.stderr)
    assert r.returncode == 0, r.stderr
    assert "same kernels" in r.stdout, r.stdout  # the backend line: every bed in the GPU's kernels
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 6 and {int(row["world"]) for row in rows} == {0, 1, 2}
    assert all(np.isfinite(float(row["fy"])) for row in rows)
