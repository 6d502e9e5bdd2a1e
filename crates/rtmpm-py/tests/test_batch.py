"""Batches of worlds from Python (rtmpm.Simulation(scene, batch=N), rtmpm.BatchSimulation):
every world bit for bit its own separate Simulation on the CPU, resets and blow-ups that leave
the other worlds bit-identical, per-world rigid-body poses and loads, and clear errors."""

import _thread
import pathlib
import signal
import threading
import time

import numpy as np
import pytest

import rtmpm

# A small slump: a column of Herschel-Bulkley mud on a sticky floor (~500 particles), fixed dt.
SLUMP = """
name = "slump"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.15
fps = 20
dt = 1e-3
[walls]
thickness = 3
faces.y_min = { condition = "sticky" }
[[material]]
name = "mud"
type = "herschel_bulkley"
density = 1600.0
bulk_modulus = 1e5
shear_modulus = 1e4
yield_stress = YIELD
consistency = 10.0
[[body]]
material = "mud"
shape = "box"
min = [0.2, 0.1, 0.2]
max = [0.3, 0.25, 0.3]
particles_per_cell = 8
velocity = VELOCITY
"""

YIELDS = [100.0, 250.0, 600.0]


def world_text(yield_stress=250.0, velocity=(0.0, 0.0, 0.0)):
    v = "[" + ", ".join(repr(float(c)) for c in velocity) + "]"
    return SLUMP.replace("YIELD", repr(float(yield_stress))).replace("VELOCITY", v)


def sweep_text(sweep):
    return world_text() + "[batch]\ncount = 3\n[batch.sweep]\n" + sweep + "\n"


def alone(text, frames, x=None):
    """The particles (x, v) of a separate Simulation of `text` after `frames` frames."""
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cpu")
    if x is not None:
        sim.particles.x = x
    for _ in range(frames):
        sim.run_frame()
    return sim.particles.x.copy(), sim.particles.v.copy()


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_a_scene_with_batch_is_a_batch_and_each_world_is_its_separate_run_bit_for_bit():
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    assert scene.batch == 3
    assert scene.batch_labels[1] == "material[0].yield_stress = 250"
    sim = rtmpm.Simulation(scene, backend="cpu")
    assert isinstance(sim, rtmpm.BatchSimulation)
    assert len(sim) == 3 and sim.uniform
    sim.run(3)
    assert list(sim.frame) == [3, 3, 3]
    x, v = sim.x, sim.v
    n = int(sim.num_particles[0])
    assert x.shape == (3, n, 3) and x.dtype == np.float32
    for w, y in enumerate(YIELDS):
        xa, va = alone(world_text(y), 3)
        assert same_bits(x[w], xa), f"world {w} differs from its separate run"
        assert same_bits(v[w], va)
    # The worlds differ (the sweep reaches them): softer mud slumps further.
    assert not np.array_equal(x[0], x[2])


def test_batch_n_copies_a_plain_scene_and_steps_every_world():
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=4, backend="cpu")
    assert isinstance(sim, rtmpm.BatchSimulation)
    assert sim.labels == ["world 0", "world 1", "world 2", "world 3"]
    assert sim.backend.kind == "cpu" and sim.backend.reason == "cpu (asked for)"
    assert sim.step(5) == []
    assert list(sim.steps) == [5] * 4
    np.testing.assert_allclose(sim.time, 5e-3)
    assert all(s["state"] == "running" and s["reason"] is None for s in sim.status)
    # Copies of one scene stay equal.
    x = sim.x
    assert all(same_bits(x[0], x[w]) for w in range(1, 4))
    assert sim.mass.shape == x.shape[:2] and sim.material.dtype == np.int32
    # The GPU's diagnostics: nothing to wait for on the CPU, no mapping to count.
    sim.synchronize()
    assert sim.rebuilds is None and sim.p2g_redos is None


def test_a_plain_simulation_and_a_resumed_one_are_simulations(tmp_path):
    one = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), backend="cpu")
    assert not isinstance(one, rtmpm.BatchSimulation)
    one.step(2)
    one.checkpoint(tmp_path / "one.ckpt")
    back = rtmpm.Simulation.resume(tmp_path / "one.ckpt", backend="cpu")
    assert isinstance(back, rtmpm.Simulation) and back.steps == 2


def test_steps_are_the_separate_runs_steps():
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cpu")
    sim.step(7)
    one = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), backend="cpu")
    one.step(7)
    assert same_bits(sim.x[1], one.particles.x)
    assert same_bits(sim.v[1], one.particles.v)


def test_a_reset_world_starts_again_and_the_others_are_untouched():
    text = sweep_text('"material[0].yield_stress" = [100, 250, 600]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cpu")
    x0 = sim.x.copy()
    sim.run(2)
    sim.reset([1])
    assert list(sim.frame) == [2, 0, 2]
    assert sim.time[1] == 0.0
    assert same_bits(sim.x[1], x0[1])
    sim.run(2)
    for w, frames in [(0, 4), (1, 2), (2, 4)]:
        xa, va = alone(world_text(YIELDS[w]), frames)
        assert same_bits(sim.x[w], xa), f"world {w}"
        assert same_bits(sim.v[w], va), f"world {w}"


def test_a_reset_to_given_positions_is_a_run_from_them():
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=3, backend="cpu")
    sim.run(1)
    moved = sim.x[2] * 0 + rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), backend="cpu").particles.x
    moved[:, 0] += 0.05
    sim.reset([2], x=moved[None])
    assert same_bits(sim.x[2], moved)
    sim.run(1)
    xa, va = alone(world_text(), 1, x=moved)
    assert same_bits(sim.x[2], xa) and same_bits(sim.v[2], va)
    xb, _ = alone(world_text(), 2)
    assert same_bits(sim.x[0], xb), "world 0 was touched by world 2's reset"


def test_a_world_that_blows_up_is_frozen_and_the_others_go_on_bit_identical():
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cpu")
    x0 = sim.x.copy()
    frozen = sim.run(2)
    assert frozen == [1]
    st = sim.status[1]
    assert st["state"] == "frozen" and st["frame"] == 0 and st["reason"]
    assert list(sim.running) == [True, False, True]
    # Frozen at its last good state (its initial one); the others as their separate runs.
    assert same_bits(sim.x[1], x0[1])
    for w, vel in [(0, (0, 0, 0)), (2, (0, 0.5, 0))]:
        xa, _ = alone(world_text(velocity=vel), 2)
        assert same_bits(sim.x[w], xa), f"world {w}"
    assert "frozen=1" in repr(sim)
    # A reset world runs again.
    sim.reset([1], v=np.zeros_like(x0[1]))
    assert list(sim.running) == [True, True, True]
    assert sim.step(1) == []


def test_overlap_is_off_on_the_cpu_batch_and_true_is_refused(monkeypatch):
    """``overlap`` (on by default for a GPU batch: tests/test_batch_gpu.py) is off on the CPU
    batch whatever ``RTMPM_BATCH_OVERLAP`` says, ``True`` is refused naming the GPU, and a
    blow-up is returned by the call whose steps failed."""
    monkeypatch.setenv("RTMPM_BATCH_OVERLAP", "1")
    text = sweep_text('"body[0].velocity" = [[0, 0, 0], [1e5, 0, 0], [0, 0.5, 0]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cpu")
    assert sim.backend.kind == "cpu" and sim.overlap is False
    with pytest.raises(rtmpm.SimulationError, match="overlap is for a batch on the GPU"):
        sim.overlap = True
    assert sim.overlap is False
    sim.overlap = False
    assert sim.step(10) == [1]
    assert list(sim.running) == [True, False, True]
    assert sim.step(1) == []


def test_ragged_worlds_are_flat_arrays_with_offsets():
    text = sweep_text('"body[0].max" = [[0.3, 0.25, 0.3], [0.3, 0.3, 0.3], [0.35, 0.25, 0.3]]')
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(text), backend="cpu")
    counts = list(sim.num_particles)
    assert len(set(counts)) == 3 and not sim.uniform
    off = sim.offsets
    assert list(off) == [0, counts[0], counts[0] + counts[1], sum(counts)]
    assert sim.x.shape == (sum(counts), 3) and sim.mass.shape == (sum(counts),)
    sim.step(2)
    # Reset world 2 with its own rows (flat): the others' rows are untouched.
    before = sim.x.copy()
    rows = before[off[2]:off[3]] + np.float32(0.01)
    sim.reset([2], x=rows)
    after = sim.x
    assert same_bits(after[: off[2]], before[: off[2]])
    assert same_bits(after[off[2]:], rows)


def test_bad_input_gives_clear_errors():
    scene = rtmpm.Scene.from_toml(world_text())
    for n in (0, -2):
        with pytest.raises(ValueError, match="a batch has from 1 to 65536 worlds"):
            rtmpm.Simulation(scene, batch=n, backend="cpu")
    with pytest.raises(ValueError, match="from 1 to 65536"):
        rtmpm.Simulation(scene, batch=70000, backend="cpu")
    with pytest.raises(ValueError, match="count = 3"):
        rtmpm.Simulation(rtmpm.Scene.from_toml(sweep_text('"gravity[1]" = [-9.81, -5, -1]')), batch=2)
    with pytest.raises(rtmpm.BackendError, match="gpus=2: a batch runs on one GPU"):
        rtmpm.Simulation(scene, batch=2, backend="cuda", gpus=2)
    with pytest.raises(ValueError, match="threads"):
        rtmpm.Simulation(scene, batch=2, backend="cpu", threads=2)
    sim = rtmpm.Simulation(scene, batch=2, backend="cpu")
    n = int(sim.num_particles[0])
    with pytest.raises(IndexError, match="world 5 does not exist: the batch has 2 worlds"):
        sim.reset([5])
    with pytest.raises(ValueError, match="listed twice"):
        sim.reset([0, 0])
    with pytest.raises(ValueError, match=r"x has shape \[2, 3\]"):
        sim.reset([0], x=np.zeros((2, 3), np.float32))
    with pytest.raises(ValueError, match=r"\(1, n, 3\)"):
        sim.reset([1], x=np.zeros((1, n + 1, 3), np.float32))
    bad = np.zeros((1, n, 3), np.float32)
    bad[0, 7, 1] = np.nan
    with pytest.raises(ValueError, match="particle 7"):
        sim.reset([1], v=bad)
    with pytest.raises(IndexError, match="rigid body"):
        sim.set_rigid_body(0, velocity=[0, 0, 0])
    with pytest.raises(rtmpm.RtmpmError, match="holds files but no batch checkpoint"):
        sim.checkpoint(pathlib.Path(__file__).parent)
    # Nothing was changed by the refused calls.
    assert list(sim.steps) == [0, 0]


def test_hostile_batch_input_is_refused_and_changes_nothing():
    scene = rtmpm.Scene.from_toml(world_text())
    sim = rtmpm.Simulation(scene, batch=2, backend="cpu")
    n = int(sim.num_particles[0])
    # A reset to positions outside the domain names the world and the particle.
    far = np.full((2, n, 3), 0.25, np.float32)
    far[1, 3] = [0.25, 7.0, 0.25]
    with pytest.raises(ValueError, match=r"x of world 1, particle 3: .* is outside the domain"):
        sim.reset(x=far)
    with pytest.raises(IndexError, match="world -3 does not exist"):
        sim.reset([-3])
    with pytest.raises(ValueError, match="x: not an array of numbers"):
        sim.reset([0], x="garbage")
    with pytest.raises(ValueError, match=r"v has shape \[2, 1, 3, 3\]"):
        sim.reset(v=np.zeros((2, 1, 3, 3), np.float32))
    # Step counts that are not a count of steps.
    with pytest.raises(OverflowError):
        sim.step(-1)
    with pytest.raises(OverflowError):
        sim.step(2**64)
    with pytest.raises(TypeError):
        sim.step(1.5)
    assert list(sim.steps) == [0, 0]
    # A batch file sweeping what the worlds share (the frame rate) is refused, naming it.
    with pytest.raises(rtmpm.SceneError, match=r"`time.fps` is the same in every world"):
        rtmpm.Scene.from_toml(sweep_text('"time.fps" = [10, 20, 40]'))
    with pytest.raises(rtmpm.SceneError, match="sets the same field"):
        rtmpm.Scene.from_toml(sweep_text('"gravity[1]" = [-1, -2, -3]\ngravity = [[0, -1, 0], [0, -2, 0], [0, -3, 0]]'))


# A sand bed and a kinematic box (the tool) above it.
TOOL_SCENE = """
name = "push"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.4, 0.4]
dx = 0.025
[time]
duration = 0.2
fps = 50
dt = 5e-4
[walls]
thickness = 3
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 1e6
poisson_ratio = 0.3
friction_angle = 35.0
[[body]]
material = "sand"
shape = "box"
min = [0.1, 0.075, 0.1]
max = [0.3, 0.175, 0.3]
particles_per_cell = 8
[[rigid_body]]
name = "tool"
shape = "box"
min = [0.17, 0.25, 0.17]
max = [0.23, 0.31, 0.23]
density = 1000.0
type = "kinematic"
condition = "sticky"
"""


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_a_tool_posed_per_world_feels_the_sand_it_pushes():
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(TOOL_SCENE), batch=3, backend="cpu")
    # World 0 keeps the tool in the air; 1 and 2 press it into the sand at 0.2 and 0.4 m/s.
    depth = [[0.2, 0.27, 0.2], [0.2, 0.19, 0.2], [0.2, 0.19, 0.2]]  # lists are arrays too
    sim.set_rigid_body("tool", position=depth)
    sim.set_rigid_body("tool", worlds=[1, 2], velocity=np.array([[0, -0.2, 0], [0, -0.4, 0]], np.float32))
    assert np.all(sim.rigid_force("tool") == 0.0)  # before a step
    sim.step(40)
    f = sim.rigid_force("tool")
    assert f.shape == (3, 3)
    assert f[0, 1] == 0.0, "a tool in the air feels nothing"
    assert f[1, 1] > 0.0 and f[2, 1] > f[1, 1], f"the sand pushes back, harder on the faster tool: {f}"
    assert sim.rigid_torque("tool").shape == (3, 3)
    pos = [b["position"][1] for w in range(3) for b in sim.rigid_bodies(w)]
    assert pos[0] == pytest.approx(0.27) and pos[2] < pos[1] < 0.19
    with pytest.raises(ValueError, match="world 1: rigid body `tool`"):
        sim.set_rigid_body("tool", worlds=[0, 1], position=[[0.2, 0.27, 0.2], [0.2, 5.0, 0.2]])
    with pytest.raises(ValueError, match=r"velocity has shape \[2\]"):
        sim.set_rigid_body("tool", velocity=[0.0, 1.0])
    with pytest.raises(KeyError, match="no rigid body named `spoon`"):
        sim.rigid_force("spoon")
    # Hostile poses: NaN, a huge angular velocity, a world index past the end.
    with pytest.raises(ValueError, match="world 0: rigid body `tool`: rotation .* is not finite"):
        sim.set_rigid_body("tool", worlds=[0], rotation=[np.nan, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="world 2: rigid body `tool`: angular_velocity"):
        sim.set_rigid_body("tool", worlds=[2], angular_velocity=[0.0, np.inf, 0.0])
    with pytest.raises(IndexError, match="world 3 does not exist: the batch has 3 worlds"):
        sim.set_rigid_body("tool", worlds=[3], position=[0.2, 0.27, 0.2])
    with pytest.raises(IndexError, match="world 9 does not exist"):
        sim.rigid_bodies(9)


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_a_resumed_batch_goes_on_bit_for_bit(tmp_path):
    scene = rtmpm.Scene.from_toml(TOOL_SCENE)
    sim = rtmpm.Simulation(scene, batch=3, backend="cpu")
    # Each world's tool at its own height and speed: the poses are part of the checkpoint.
    sim.set_rigid_body("tool", position=[[0.2, 0.27, 0.2], [0.2, 0.19, 0.2], [0.2, 0.2, 0.2]],
                       velocity=[[0, 0, 0], [0, -0.2, 0], [0, -0.4, 0]])
    sim.step(13)
    sim.reset([2])
    sim.step(5)
    sim.checkpoint(tmp_path / "ckpt")
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == [
        "batch.toml", "world_000.ckpt", "world_001.ckpt", "world_002.ckpt"]
    sim.step(20)
    again = rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, batch=3, backend="cpu")
    assert list(again.steps) == [18, 18, 5]
    again.step(20)
    assert list(again.steps) == list(sim.steps)
    assert again.x.tobytes() == sim.x.tobytes()
    assert again.v.tobytes() == sim.v.tobytes()
    assert again.rigid_force("tool").tobytes() == sim.rigid_force("tool").tobytes()
    assert np.any(again.rigid_force("tool")[1] != 0.0), "the tool pressed into the sand"
    with pytest.raises(rtmpm.RtmpmError, match="it holds 3 worlds, the batch has 2"):
        rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, batch=2, backend="cpu")


GPU_OK, GPU_WHY = rtmpm.cuda_available()


@pytest.mark.skipif(GPU_OK, reason="a usable GPU is here: tests/test_batch_gpu.py runs the batch on it")
def test_without_a_gpu_auto_runs_a_batch_on_the_cpu_and_cuda_says_why_not():
    scene = rtmpm.Scene.from_toml(world_text())
    sim = rtmpm.Simulation(scene, batch=2)
    assert sim.backend.kind == "cpu"
    assert sim.backend.reason.startswith("auto -> cpu (CUDA not usable: "), sim.backend.reason
    with pytest.raises(rtmpm.BackendError, match=r"the CUDA backend is not usable here: (.|\n)*backend=\"cpu\""):
        rtmpm.Simulation(scene, batch=2, backend="cuda")
    # Whatever the batch holds, the missing GPU is the reason given.
    if "rigid" in rtmpm.features:
        tool = rtmpm.Simulation(rtmpm.Scene.from_toml(TOOL_SCENE), batch=2)
        assert "CUDA not usable" in tool.backend.reason


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_auto_runs_on_the_cpu_what_the_gpu_batch_does_not_do(tmp_path):
    # Emitters: the GPU batch does not run them, so auto runs the CPU on any machine.
    emitting = rtmpm.Scene.from_toml(world_text() + (
        "[[emitter]]\nmaterial = \"mud\"\nshape = \"box\"\nmin = [0.2, 0.35, 0.2]\n"
        "max = [0.25, 0.37, 0.25]\nvelocity = [0.0, -1.0, 0.0]\nvolume_rate = 1e-4\n"))
    sim = rtmpm.Simulation(emitting, batch=2)
    assert sim.backend.kind == "cpu"
    if GPU_OK:
        assert "the GPU batch cannot run it: world 0 has emitters" in sim.backend.reason
        with pytest.raises(rtmpm.BackendError, match="cannot run on the GPU: world 0 has emitters"):
            rtmpm.Simulation(emitting, batch=2, backend="cuda")
    # Rigid bodies (a tool in every world) run on the GPU batch: auto picks it when there is one.
    tool = rtmpm.Simulation(rtmpm.Scene.from_toml(TOOL_SCENE), batch=2)
    assert tool.backend.kind == ("cuda" if GPU_OK else "cpu"), tool.backend.reason
    # A resume: auto resumes a CPU batch's checkpoint on the GPU when there is one.
    scene = rtmpm.Scene.from_toml(world_text())
    first = rtmpm.Simulation(scene, batch=2, backend="cpu")
    first.step(3)
    first.checkpoint(tmp_path / "ckpt")
    again = rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, batch=2)
    assert again.backend.kind == ("cuda" if GPU_OK else "cpu"), again.backend.reason
    assert list(again.steps) == [3, 3]
    assert again.x.tobytes() == first.x.tobytes(), "the saved state, as it was"
    if not GPU_OK:
        with pytest.raises(rtmpm.BackendError, match="not usable here"):
            rtmpm.BatchSimulation.resume(tmp_path / "ckpt", scene, batch=2, backend="cuda")


def test_device_arrays_of_a_cpu_batch_are_refused_naming_the_cuda_backend():
    sim = rtmpm.Simulation(rtmpm.Scene.from_toml(world_text()), batch=2, backend="cpu")
    for call in (lambda: sim.x_device, lambda: sim.v_device, lambda: sim.storage_device("x")):
        with pytest.raises(rtmpm.BackendError, match=r"CPU backend: create it with backend=\"cuda\""):
            call()
    # Nothing changed: the batch still steps and reads.
    assert sim.step(1) == [] and sim.x.shape[0] == 2


def test_calls_of_one_step_are_one_call_of_as_many_and_ctrl_c_interrupts_a_long_step():
    """step(n) runs in driver calls of a chunk it learns and keeps between calls: 30 calls of
    step(1) give bit for bit one call of step(30), and a huge step is still interrupted by
    Ctrl-C (between two of its calls) once the chunk was learnt, the batch going on after it."""
    scene = rtmpm.Scene.from_toml(sweep_text('"material[0].yield_stress" = [100, 250, 600]'))
    ones = rtmpm.Simulation(scene, backend="cpu")
    for _ in range(30):
        assert ones.step(1) == []
    whole = rtmpm.Simulation(scene, backend="cpu")
    assert whole.step(30) == []
    np.testing.assert_array_equal(ones.x, whole.x)
    np.testing.assert_array_equal(ones.v, whole.v)
    assert list(ones.steps) == [30] * 3
    for _ in range(5):
        whole.step(10)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            whole.step(10**9)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    assert time.perf_counter() - t0 < 5.0
    done = int(whole.steps[0])
    assert 80 < done < 10**9 and list(whole.steps) == [done] * 3
    whole.step(2)
    assert list(whole.steps) == [done + 2] * 3
