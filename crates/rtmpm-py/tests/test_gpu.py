"""The CUDA backend from Python: zero-copy device arrays through DLPack (PyTorch) and the CUDA
Array Interface (CuPy), host arrays and setters on the GPU. Skipped without a usable GPU; run on
the GPU machine by scripts/gpu/python.sh."""

import time

import numpy as np
import pytest

import rtmpm
from conftest import ROOT

ok, why = rtmpm.cuda_available()
pytestmark = pytest.mark.skipif(not ok, reason=f"no usable GPU: {why}")


@pytest.fixture
def sim(jelly_path):
    s = rtmpm.Simulation(jelly_path, backend="cuda")
    s.run_frame()
    return s


def host_order(device_values, ids):
    """Device arrays are in storage order: row j is particle ids[j]."""
    out = np.empty_like(device_values)
    out[ids] = device_values
    return out


def test_cuda_backend_is_picked_and_steps(jelly_path):
    s = rtmpm.Simulation(jelly_path)
    assert s.backend.kind == "cuda"
    assert "a usable GPU" in s.backend.reason
    s.run_frame()
    assert s.frame == 1 and s.particles.x.shape == (s.num_particles, 3)


def test_torch_sees_device_memory_without_a_copy(sim):
    torch = pytest.importorskip("torch")
    xd = sim.particles.x_device
    assert xd.shape == [sim.num_particles, 3] and xd.dtype == "float32"
    x = torch.from_dlpack(xd)
    assert x.is_cuda and x.shape == (sim.num_particles, 3) and x.dtype == torch.float32
    assert x.data_ptr() == xd.ptr  # the simulation's own memory
    ids = torch.from_dlpack(sim.particles.id_device).cpu().numpy()
    assert sorted(ids.tolist()) == list(range(sim.num_particles))
    assert np.array_equal(host_order(x.cpu().numpy(), ids), sim.particles.x)
    # The tensor is a view: after a step it shows the new state.
    sim.run_frame()
    ids = torch.from_dlpack(sim.particles.id_device).cpu().numpy()
    assert np.array_equal(host_order(x.cpu().numpy(), ids), sim.particles.x)


def test_every_device_array_matches_the_host_arrays(sim):
    torch = pytest.importorskip("torch")
    p = sim.particles
    ids = torch.from_dlpack(p.id_device).cpu().numpy()
    for name in ("x", "v", "F", "C", "mass", "vol0", "plastic"):
        d = torch.from_dlpack(getattr(p, name + "_device")).cpu().numpy()
        assert np.array_equal(host_order(d, ids), getattr(p, name)), name
    mat = torch.from_dlpack(p.material_device).cpu().numpy()
    assert mat.dtype == np.int32 and np.array_equal(host_order(mat, ids), p.material)


def test_cupy_reads_the_cuda_array_interface(sim):
    cupy = pytest.importorskip("cupy")
    xd = sim.particles.x_device
    cai = xd.__cuda_array_interface__
    assert cai["version"] == 3 and cai["typestr"] == "<f4" and cai["shape"] == (sim.num_particles, 3)
    x = cupy.asarray(xd)
    assert x.data.ptr == xd.ptr
    ids = cupy.asnumpy(cupy.asarray(sim.particles.id_device))
    assert np.array_equal(host_order(cupy.asnumpy(x), ids), sim.particles.x)
    y = cupy.from_dlpack(sim.particles.v_device)
    assert np.array_equal(host_order(cupy.asnumpy(y), ids), sim.particles.v)


def test_device_arrays_keep_the_simulation_alive(jelly_path):
    torch = pytest.importorskip("torch")
    s = rtmpm.Simulation(jelly_path, backend="cuda")
    expect = s.particles.mass.sum()
    m = torch.from_dlpack(s.particles.mass_device)
    del s
    import gc

    gc.collect()
    assert float(m.sum()) == pytest.approx(float(expect), rel=1e-5)


def test_setters_on_the_gpu(sim):
    v = sim.particles.v
    v[:, 1] = 0.75
    sim.particles.v = v
    assert np.array_equal(sim.particles.v, v)
    x = sim.particles.x
    x[:, 0] += 0.05
    sim.particles.x = x
    assert np.array_equal(sim.particles.x, x)
    y0 = sim.particles.x[:, 1].mean()
    sim.step(5)
    # Moving up at 0.75 m/s against gravity for 5 small steps: the cube rose.
    assert sim.particles.x[:, 1].mean() > y0


def test_gpu_agrees_with_the_cpu(jelly_path):
    a = rtmpm.Simulation(jelly_path, backend="cuda")
    b = rtmpm.Simulation(jelly_path, backend="cpu")
    for s in (a, b):
        s.run_frame()
        s.run_frame()
    assert np.abs(a.particles.x - b.particles.x).max() < 1e-3


def test_f64_device_arrays_are_float64(jelly_path):
    torch = pytest.importorskip("torch")
    s = rtmpm.Simulation(jelly_path, backend="cuda", precision="f64")
    s.step(3)
    x = torch.from_dlpack(s.particles.x_device)
    assert x.dtype == torch.float64
    ids = torch.from_dlpack(s.particles.id_device).cpu().numpy()
    assert np.array_equal(host_order(x.cpu().numpy(), ids).astype(np.float32), s.particles.x)


def test_torch_reads_positions_every_frame_while_stepping(jelly_path):
    torch = pytest.importorskip("torch")
    s = rtmpm.Simulation(jelly_path, backend="cuda")
    heights = []
    for _ in s.frames(3):
        x = torch.from_dlpack(s.particles.x_device)
        heights.append(float(x[:, 1].mean()))
    assert heights[0] > heights[-1]  # falling


def test_large_arrays_cross_in_chunks():
    # 2M particles: x and v are 6M floats, several chunks of the ordered device-to-host copy.
    torch = pytest.importorskip("torch")
    s = rtmpm.Simulation(str(ROOT / "bench" / "fluid_dam_2m.toml"), backend="cuda")
    s.step(3)
    p = s.particles
    ids = torch.from_dlpack(p.id_device).cpu().numpy()
    assert not np.array_equal(ids, np.arange(s.num_particles))  # sorted storage differs
    for name in ("x", "v"):
        d = torch.from_dlpack(getattr(p, name + "_device")).cpu().numpy()
        assert np.array_equal(host_order(d, ids), getattr(p, name)), name


def test_host_arrays_are_independent_when_their_memory_is_reused(sim):
    # x and v from the GPU are backed by buffers that return to a pool when NumPy frees them.
    a = sim.particles.x
    b = sim.particles.x
    assert not np.shares_memory(a, b)
    a[:] = -1.0
    assert np.array_equal(b, sim.particles.x) and (b != -1.0).all()
    expect = b.copy()
    del a, b
    for _ in range(6):  # more reads than the pool keeps
        x, v = sim.particles.x, sim.particles.v
        assert np.array_equal(x, expect) and not np.shares_memory(x, v)
    sim.step(2)
    moved = sim.particles.x
    assert not np.array_equal(moved, expect)
    assert np.array_equal(moved, sim.particles.x)


def test_device_views_follow_the_state_layout(small_path):
    # Water: the 20-word fluid layout (F as the one word J^(1/3), no plastic word).
    torch = pytest.importorskip("torch")
    s = rtmpm.Simulation(small_path, backend="cuda")
    s.run_frame()
    p = s.particles
    ids = torch.from_dlpack(p.id_device).cpu().numpy()
    for name in ("x", "v", "C", "mass", "vol0"):
        d = torch.from_dlpack(getattr(p, name + "_device")).cpu().numpy()
        assert np.array_equal(host_order(d, ids), getattr(p, name)), name
    for name in ("F_device", "plastic_device"):
        with pytest.raises(rtmpm.BackendError, match="layout"):
            getattr(p, name)
    F = p.F
    assert np.array_equal(F[:, 0, 1], np.zeros(len(F)))
    assert np.array_equal(F[:, 0, 0], F[:, 2, 2])
    # The 29-word layout on request: every view.
    s29 = rtmpm.Simulation(small_path, backend="cuda", cuda_options="fluid_state=off")
    s29.run_frame()
    assert s29.particles.F_device is not None and s29.particles.plastic_device is not None
    # Compact: C only through the host arrays (v stays f32).
    text = small_path.read_text().replace("[output]", '[solver]\nparticle_state = "compact"\n[output]')
    compact = small_path.with_name("compact.toml")
    compact.write_text(text)
    sc = rtmpm.Simulation(compact, backend="cuda")
    sc.run_frame()
    for name in ("C_device", "F_device"):
        with pytest.raises(rtmpm.BackendError, match="layout"):
            getattr(sc.particles, name)
    assert np.isfinite(sc.particles.v).all()
    assert sc.particles.v_device is not None


def test_render_gpu_draws_on_the_gpu_what_render_draws(sim):
    """render_gpu on CUDA (kernels reading the state on the GPU) against render (the CPU renderer
    from the particles read back): the bound of crates/rtmpm-cuda/tests/render.rs, at most 1 %
    of the pixels off by more than 32 levels in a channel and a mean difference of at most 1.5
    levels, in every colour mode (each finds its own automatic range: the GPU's is within
    1/2048^2 of the field's span of the CPU's, crates/rtmpm-cuda/tests/render.rs checks it)."""
    for color_by in ("material", "speed", "J", "stress", "plastic"):
        g = sim.render_gpu(size=(320, 180), color_by=color_by, radius=0.006, label="")
        assert g.shape == (180, 320, 3) and g.dtype == np.uint8
        c = sim.render(size=(320, 180), color_by=color_by, radius=0.006, label="")
        d = np.abs(g.astype(np.int16) - c.astype(np.int16))
        mean, share = d.mean(), (d.max(axis=2) > 32).mean()
        print(f"{color_by}: mean {mean:.3f}, share {share:.4f}")
        assert mean <= 1.5 and share <= 0.01, (color_by, mean, share)
        assert len(np.unique(g.reshape(-1, 3), axis=0)) > 20


def test_view_draws_on_the_gpu(sim):
    """Simulation.view() on CUDA: the live session's copy runs on the GPU and its pictures are
    drawn there (the render stage); steering reaches it."""
    view = sim.view(serve="127.0.0.1:0", size=(320, 180), paused=True)
    try:
        t0 = time.monotonic()
        while view.status is None and time.monotonic() - t0 < 60:
            time.sleep(0.05)
        s = view.status
        assert s is not None and s["backend"].startswith("cuda"), s
        assert (s["width"], s["height"]) == (320, 180) and s["render_ms"] > 0
        # Drawn on the GPU: the particles were not read back for the picture.
        assert s["center_of_mass"] is None
        view.send({"cmd": "resume"})
        while view.status["frame"] < s["frame"] + 2 and time.monotonic() - t0 < 120:
            time.sleep(0.05)
        assert view.status["frame"] >= s["frame"] + 2
    finally:
        summary = view.stop()
    assert summary["error"] is None and summary["pictures"] >= 3


@pytest.mark.skipif("rigid" not in rtmpm.features, reason="module built without the rigid feature")
def test_a_single_gpu_run_reports_a_kinematic_tools_load_as_the_cpu():
    """A single CUDA Simulation reports the load on a kinematic tool (``rigid_bodies``' ``force``
    and ``torque``), as the CPU backend does: zero before a step, and the mean force on the tool
    pressed into sand at 0.4 m/s over the last 10 of 40 steps within 10 % of the CPU's (the
    tolerance of test_batch_gpu.py's tools). A few seconds on an H200."""
    from test_batch import TOOL_SCENE

    scene = rtmpm.Scene.from_toml(TOOL_SCENE)
    means = {}
    for backend in ("cuda", "cpu"):
        sim = rtmpm.Simulation(scene, backend=backend)
        assert sim.backend.kind == backend, sim.backend.reason
        body = sim.rigid_bodies[0]
        assert list(body["force"]) == [0.0] * 3 and list(body["torque"]) == [0.0] * 3, body
        sim.set_rigid_body("tool", position=[0.2, 0.19, 0.2], velocity=[0.0, -0.4, 0.0])
        sim.step(30)
        total = np.zeros(3)
        for _ in range(10):
            sim.step()
            total += sim.rigid_bodies[0]["force"]
        means[backend] = total / 10
    f, fc = means["cuda"], means["cpu"]
    print(f"mean force on the tool (N): GPU {f.tolist()}, CPU {fc.tolist()}")
    assert fc[1] > 0.0, f"the sand pushes the tool up: {fc}"
    assert np.linalg.norm(f - fc) <= 0.1 * np.linalg.norm(fc), f"GPU {f} vs CPU {fc}"
