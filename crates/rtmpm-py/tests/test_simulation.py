"""Simulations on the CPU: stepping, agreement with the command line, arrays, setters,
checkpoints, frames, errors, Ctrl-C and the interpreter lock."""

import _thread
import math
import subprocess
import signal
import threading
import time

import numpy as np
import pytest

import rtmpm
from conftest import ROOT, SMALL

HOST_ARRAYS = {
    "x": ((3,), np.float32),
    "v": ((3,), np.float32),
    "F": ((3, 3), np.float32),
    "C": ((3, 3), np.float32),
    "J": ((), np.float32),
    "material": ((), np.int32),
    "id": ((), np.int32),
    "mass": ((), np.float32),
    "vol0": ((), np.float32),
    "plastic": ((), np.float32),
}


def all_arrays(sim):
    p = sim.particles
    return {name: getattr(p, name) for name in HOST_ARRAYS}


def assert_same_state(a, b):
    for name in HOST_ARRAYS:
        assert np.array_equal(a[name], b[name]), name


def test_arrays_have_the_documented_shapes_and_dtypes(jelly_path):
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    n = sim.num_particles
    assert len(sim.particles) == n > 100
    for name, (inner, dtype) in HOST_ARRAYS.items():
        a = getattr(sim.particles, name)
        assert a.shape == (n, *inner), name
        assert a.dtype == dtype, name
    p = sim.particles
    assert np.array_equal(p.id, np.arange(n))
    assert np.allclose(p.F, np.eye(3)) and np.all(p.C == 0) and np.all(p.J == 1)
    sim.run_frame()
    # J is det F, F[i] is row-major: check against NumPy on the deformed state.
    assert np.allclose(p.J, np.linalg.det(p.F.astype(np.float64)), rtol=1e-5)
    assert not np.allclose(p.F, np.eye(3))


def test_run_frame_matches_the_command_line_bit_for_bit(tmp_path, small_path, cli):
    """`rtmpm run` and run_frame() take the same steps: identical PLY frames and checkpoints."""
    out = tmp_path / "cli"
    subprocess.run(
        [cli, "run", str(small_path), "--backend", "cpu", "--frames", "3", "--out", str(out),
         "--checkpoint-every", "3"],
        check=True, capture_output=True,
    )
    sim = rtmpm.Simulation(small_path, backend="cpu")
    for _ in range(3):
        sim.run_frame()
    frame = rtmpm.read_ply(out / "frame_00003.ply")
    x = sim.particles.x
    v = sim.particles.v
    for k, c in enumerate("xyz"):
        assert np.array_equal(frame[c], x[:, k]), c
        assert np.array_equal(frame["v" + c], v[:, k]), "v" + c
    # Every field, bit for bit, through the CLI's checkpoint.
    cli_state = rtmpm.Simulation.resume(out / "checkpoint_00003.ckpt", backend="cpu")
    assert (cli_state.frame, cli_state.steps, cli_state.time) == (sim.frame, sim.steps, sim.time)
    assert_same_state(all_arrays(cli_state), all_arrays(sim))


def test_cfl_scene_matches_the_command_line(tmp_path, jelly_path, cli):
    out = tmp_path / "cli"
    subprocess.run(
        [cli, "run", str(jelly_path), "--backend", "cpu", "--frames", "2", "--out", str(out)],
        check=True, capture_output=True,
    )
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    sim.run_frame()
    sim.run_frame()
    frame = rtmpm.read_ply(out / "frame_00002.ply")
    assert np.array_equal(frame["y"], sim.particles.x[:, 1])


def test_step_counts_and_frames_land_on_their_times(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    assert (sim.time, sim.frame, sim.steps) == (0.0, 0, 0)
    assert sim.dt == pytest.approx(5e-4)
    assert sim.step() == 1 and sim.steps == 1
    assert sim.step(5) == 5 and sim.steps == 6
    assert sim.time == pytest.approx(6 * 5e-4)
    # 1/50 s per frame = 40 steps; the rest of frame 0.
    assert sim.run_frame() == 34
    assert (sim.frame, sim.steps) == (1, 40)
    assert sim.time == 1 / 50
    # step() crosses frame ends.
    sim.step(45)
    assert (sim.frame, sim.steps) == (2, 85)
    # 0.0425 s + 0.01 s: the end of frame 2 (0.06 s) is later, so 20 single steps.
    assert sim.advance(0.01) == 20
    assert sim.time == pytest.approx(0.0525)
    # A whole frame and a bit: frame 3 ends at 0.06 s, then 5 steps to 0.0625 s.
    assert sim.advance(0.01) == 20
    assert sim.frame == 3 and sim.time == pytest.approx(0.0625)
    with pytest.raises(ValueError):
        sim.advance(-1.0)


def test_stepping_in_pieces_equals_whole_frames(small_path):
    a = rtmpm.Simulation(small_path, backend="cpu")
    b = rtmpm.Simulation(small_path, backend="cpu", threads=1)
    a.run_frame()
    a.run_frame()
    b.step(7)
    b.step(33)
    b.advance(0.02)
    assert (a.steps, a.frame) == (b.steps, b.frame)
    assert_same_state(all_arrays(a), all_arrays(b))


def test_frames_iterator_and_run_callback(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    seen = [(f, sim.time) for f in sim.frames(2)]
    assert seen == [(1, 1 / 50), (2, 2 / 50)]
    # Default: to the end of the scene's duration (5 frames).
    assert list(sim.frames()) == [3, 4, 5]
    sim = rtmpm.Simulation(small_path, backend="cpu")
    calls = []
    assert sim.run(callback=lambda s: calls.append(s.frame)) == 5
    assert calls == [1, 2, 3, 4, 5]
    sim = rtmpm.Simulation(small_path, backend="cpu")
    assert sim.run(frames=4, callback=lambda s: s.frame < 2) == 2
    assert sim.frame == 2


def test_velocity_setter_takes_effect(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    p = sim.particles
    x = p.x
    v = np.zeros_like(x)
    v[:, 0] = 0.5 * np.sin(2 * np.pi * x[:, 1])
    p.v = v
    assert np.array_equal(p.v, v)
    assert np.array_equal(p.x, x)
    ref = rtmpm.Simulation(small_path, backend="cpu")
    sim.step(4)
    ref.step(4)
    # The velocity field moved the particles along x, where the reference only fell.
    dx = sim.particles.x[:, 0] - ref.particles.x[:, 0]
    assert np.corrcoef(dx, v[:, 0])[0, 1] > 0.99
    assert np.allclose(dx, v[:, 0] * 4 * 5e-4, atol=2e-4)


def test_position_setter_takes_effect(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    x = sim.particles.x
    x[:, 0] += 0.1  # move the cube along x
    sim.particles.x = x.astype(np.float64)  # float64 is accepted (rounded to float32)
    assert np.array_equal(sim.particles.x, x)
    sim.step(2)
    com = sim.particles.x.mean(0)
    assert 0.29 < com[0] < 0.31


def test_setters_check_shape_dtype_and_values(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    p = sim.particles
    n = len(p)
    with pytest.raises(ValueError, match=rf"shape \({n}, 3\)"):
        p.v = np.zeros((n, 2), np.float32)
    with pytest.raises(ValueError, match="shape"):
        p.x = np.zeros(3 * n, np.float32)
    with pytest.raises(TypeError, match="float"):
        p.v = np.zeros((n, 3), np.int64)
    with pytest.raises(TypeError, match="float"):
        p.v = [["a", "b", "c"]] * n
    v = np.zeros((n, 3), np.float32)
    v[5, 1] = np.nan
    with pytest.raises(ValueError, match="particle 5 is not finite"):
        p.v = v
    x = p.x
    x[7] = [2.0, 0.2, 0.2]
    with pytest.raises(ValueError, match="particle 7 .* outside the domain"):
        p.x = x
    # Nothing was changed by the refused assignments.
    assert np.all(p.v == 0)


def test_c_and_f_setters_check_shape_and_values(small_path, jelly_path):
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    p = sim.particles
    n = len(p)
    with pytest.raises(ValueError, match=rf"shape \({n}, 3, 3\)"):
        p.C = np.zeros((n, 3), np.float32)
    with pytest.raises(TypeError, match="float"):
        p.F = np.zeros((n, 3, 3), np.int32)
    c = np.zeros((n, 3, 3), np.float32)
    c[4, 2, 1] = np.inf
    with pytest.raises(ValueError, match="particle 4 is not finite"):
        p.C = c
    f = np.broadcast_to(np.eye(3, dtype=np.float32), (n, 3, 3)).copy()
    f[9] = np.diag([1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="particle 9 has det F = -1"):
        p.F = f
    f[9] = np.diag([1.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="positive determinant"):
        p.F = f
    # Nothing was changed by the refused assignments.
    assert np.all(p.C == 0) and np.all(p.F == np.eye(3, dtype=np.float32))
    # A solid keeps the F it is given, row by row ([i, row, col]); C as given.
    f[9] = [[1.1, 0.2, 0.0], [0.0, 0.95, 0.0], [0.05, 0.0, 1.0]]
    p.F = f
    assert np.array_equal(p.F, f)
    c[4] = [[0.0, -2.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 0.5]]
    p.C = c
    assert np.array_equal(p.C, c)
    # A fluid keeps only J = det F, as J^(1/3) I (what its step projects F to).
    water = rtmpm.Simulation(small_path, backend="cpu")
    m = len(water.particles)
    f = np.broadcast_to(np.diag([1.1, 1.0, 1.0]).astype(np.float32), (m, 3, 3))
    water.particles.F = f
    assert np.allclose(water.particles.F, np.cbrt(1.1) * np.eye(3), rtol=1e-6)


SPIN = """
name = "spin"
gravity = [0.0, 0.0, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.1
fps = 50
dt = 2e-4
[[material]]
name = "jelly"
type = "neo_hookean"
density = 1000.0
youngs_modulus = 1e5
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "sphere"
center = [0.25, 0.25, 0.25]
radius = 0.1
"""


def test_a_spin_set_from_python_with_its_c_keeps_its_angular_momentum(tmp_path):
    """A jelly ball in zero gravity, spun at 5 rad/s from Python: with C set to the velocity
    field's gradient ([w]x) the particles' angular momentum sum m (x - c) x v survives the first
    step (APIC carries an affine field exactly); with v alone, part of it goes into C."""
    path = tmp_path / "spin.toml"
    path.write_text(SPIN)
    w = np.array([0.0, 0.0, 5.0])

    def angular_momentum(sim):
        p = sim.particles
        x, v, m = p.x.astype(np.float64), p.v.astype(np.float64), p.mass.astype(np.float64)
        c = (m[:, None] * x).sum(0) / m.sum()
        return (m[:, None] * np.cross(x - c, v)).sum(0)[2]

    def first_step_loss(with_c):
        sim = rtmpm.Simulation(str(path), backend="cpu")
        p = sim.particles
        x, m = p.x.astype(np.float64), p.mass.astype(np.float64)
        c = (m[:, None] * x).sum(0) / m.sum()
        p.v = np.cross(w, x - c)
        if with_c:
            skew = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
            p.C = np.broadcast_to(skew, (len(p), 3, 3))
        before = angular_momentum(sim)
        sim.step(1)
        return 1.0 - angular_momentum(sim) / before

    with_c, without_c = first_step_loss(True), first_step_loss(False)
    print(f"angular momentum lost at the first step: {with_c:.2e} with C, {without_c:.2e} without")
    assert abs(with_c) < 1e-3, with_c
    assert without_c > 1e-2, without_c


def test_checkpoint_round_trip_is_bit_exact(tmp_path, jelly_path):
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    sim.run_frame()
    ckpt = tmp_path / "a.ckpt"
    sim.checkpoint(ckpt)
    sim.run_frame()
    resumed = rtmpm.Simulation.resume(ckpt, backend="cpu")
    assert (resumed.frame, resumed.time) == (1, pytest.approx(1 / 30))
    assert resumed.scene.name == "jelly"
    resumed.run_frame()
    assert (resumed.frame, resumed.steps, resumed.time) == (sim.frame, sim.steps, sim.time)
    assert_same_state(all_arrays(resumed), all_arrays(sim))


def test_checkpoint_of_a_dict_scene(tmp_path):
    from conftest import SMALL_DICT

    sim = rtmpm.Simulation(SMALL_DICT, backend="cpu")
    sim.step(3)
    sim.checkpoint(tmp_path / "d.ckpt")
    r = rtmpm.Simulation.resume(tmp_path / "d.ckpt", backend="cpu")
    assert r.steps == 3 and np.array_equal(r.particles.x, sim.particles.x)
    with pytest.raises(rtmpm.RtmpmError, match="cannot resume"):
        rtmpm.Simulation.resume(tmp_path / "missing.ckpt")


def test_rigid_bodies_fall_freely_or_need_the_rigid_feature():
    """A box above the water falls freely for 0.05 s: velocity -g t, drop g t^2 / 2, no spin
    (rapier3d integrates gravity exactly in velocity, to g t dt / 2 in position). A module built
    without the `rigid` feature refuses the scene and names the feature."""
    import copy

    from conftest import SMALL_DICT

    assert rtmpm.Simulation(SMALL_DICT, backend="cpu").rigid_bodies == []
    scene = copy.deepcopy(SMALL_DICT)
    scene["rigid_body"] = [
        {"shape": "box", "min": [0.32, 0.32, 0.32], "max": [0.38, 0.38, 0.38], "density": 500.0}
    ]
    if "rigid" not in rtmpm.features:
        with pytest.raises(rtmpm.RtmpmError, match="rigid"):
            rtmpm.Simulation(scene, backend="cpu")
        return
    sim = rtmpm.Simulation(scene, backend="cpu")
    (start,) = sim.rigid_bodies
    assert start["position"] == pytest.approx((0.35, 0.35, 0.35))
    assert start["rotation"] == pytest.approx((0.0, 0.0, 0.0, 1.0))
    sim.step(100)
    (b,) = sim.rigid_bodies
    t, g = sim.time, 9.81
    assert t == pytest.approx(0.05)
    assert b["velocity"][1] == pytest.approx(-g * t, rel=1e-4)
    assert start["position"][1] - b["position"][1] == pytest.approx(0.5 * g * t * t, abs=2e-4)
    assert b["position"][0] == pytest.approx(0.35, abs=1e-6)
    assert max(abs(w) for w in b["angular_velocity"]) < 1e-6


def test_set_rigid_body_moves_bodies_and_checks_values():
    """A script moves bodies between steps: a dynamic box given a position and a velocity goes
    on from them under gravity (velocity (0.5, -g t, 0), x = 0.35 + 0.5 t after t = 0.01 s); a
    kinematic sphere keeps the velocities it is given; a fixed box takes a pose but no
    velocity. Bodies by index (negative from the end) or name; bad values are refused."""
    import copy

    from conftest import SMALL_DICT

    if "rigid" not in rtmpm.features:
        pytest.skip("the module was built without the `rigid` feature")
    scene = copy.deepcopy(SMALL_DICT)
    scene["rigid_body"] = [
        {"name": "crate", "shape": "box", "min": [0.32] * 3, "max": [0.38] * 3, "density": 500.0},
        {"name": "paddle", "shape": "sphere", "center": [0.15, 0.35, 0.15], "radius": 0.03,
         "density": 500.0, "type": "kinematic"},
        {"name": "post", "shape": "box", "min": [0.32, 0.1, 0.1], "max": [0.38, 0.16, 0.16],
         "type": "fixed"},
    ]
    sim = rtmpm.Simulation(scene, backend="cpu")
    sim.set_rigid_body("crate", position=(0.35, 0.36, 0.35), velocity=np.array([0.5, 0.0, 0.0]))
    sim.set_rigid_body(1, velocity=(0.0, 0.0, 0.2), angular_velocity=[0.0, 1.0, 0.0])
    sim.set_rigid_body(-1, position=(0.35, 0.15, 0.15), rotation=(0.0, 0.0, 0.0, 2.0))
    crate, paddle, post = sim.rigid_bodies
    assert crate["position"] == pytest.approx((0.35, 0.36, 0.35))
    assert crate["velocity"] == pytest.approx((0.5, 0.0, 0.0))
    assert post["position"] == pytest.approx((0.35, 0.15, 0.15))
    assert post["rotation"] == pytest.approx((0.0, 0.0, 0.0, 1.0))
    sim.step(20)
    t, g = sim.time, 9.81
    assert t == pytest.approx(0.01)
    crate, paddle, post = sim.rigid_bodies
    assert crate["velocity"] == pytest.approx((0.5, -g * t, 0.0), abs=1e-5)
    assert crate["position"][0] == pytest.approx(0.35 + 0.5 * t, abs=1e-5)
    assert paddle["velocity"] == pytest.approx((0.0, 0.0, 0.2), abs=1e-6)
    assert paddle["angular_velocity"] == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
    assert paddle["position"] == pytest.approx((0.15, 0.35, 0.15 + 0.2 * t), abs=1e-5)
    assert post["position"] == pytest.approx((0.35, 0.15, 0.15))
    with pytest.raises(KeyError, match="no rigid body named `boat`"):
        sim.set_rigid_body("boat", position=(0.2, 0.2, 0.2))
    with pytest.raises(IndexError, match="3 rigid bodies"):
        sim.set_rigid_body(3, velocity=(0.0, 0.0, 0.0))
    with pytest.raises(TypeError, match="index"):
        sim.set_rigid_body(1.5, velocity=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="fixed"):
        sim.set_rigid_body("post", velocity=(1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="outside the domain"):
        sim.set_rigid_body("crate", position=(0.45, 0.3, 0.3))
    # The centre inside, the box (half-size 0.03) through the wall at 0.40625; turned by 45
    # degrees about y, a box that fits upright does not either.
    with pytest.raises(ValueError, match="outside the domain"):
        sim.set_rigid_body("crate", position=(0.39, 0.3, 0.3))
    sim.set_rigid_body("crate", position=(0.37, 0.3, 0.3))
    s = math.sin(math.pi / 8)
    with pytest.raises(ValueError, match="outside the domain"):
        sim.set_rigid_body("crate", rotation=(0.0, s, 0.0, math.cos(math.pi / 8)))
    sim.set_rigid_body("crate", position=crate["position"])
    with pytest.raises(ValueError, match="not finite"):
        sim.set_rigid_body("crate", velocity=(float("nan"), 0.0, 0.0))
    with pytest.raises(ValueError, match="not a rotation"):
        sim.set_rigid_body("crate", rotation=(0.0, 0.0, 0.0, 0.0))
    # Refused values change nothing.
    assert sim.rigid_bodies[0] == crate


def test_a_body_that_can_hang_in_the_water_is_warned_about():
    """A 6 cm box of density 1500 in water at dx = 3.125 cm weighs, beyond its buoyancy, as
    much as a water layer 0.16 cells thick over its surface: the coupling's buoyancy, counted
    in grid cells, can hold it (docs/scene-format.md, "Resolution of rigid bodies"). The scene
    lists the warning and a simulation issues it; at density 500 (it floats) there is none."""
    import copy

    from conftest import SMALL_DICT

    scene = copy.deepcopy(SMALL_DICT)
    scene["rigid_body"] = [
        {"shape": "box", "min": [0.32, 0.32, 0.32], "max": [0.38, 0.38, 0.38], "density": 500.0}
    ]
    assert rtmpm.Scene.from_dict(scene).warnings == []
    scene["rigid_body"][0]["density"] = 1500.0
    (w,) = rtmpm.Scene.from_dict(scene).warnings
    assert w.startswith("rigid_body[0]") and "can hang in `water`" in w and "0.16 cells" in w
    if "rigid" in rtmpm.features:
        with pytest.warns(UserWarning, match="can hang in `water`"):
            rtmpm.Simulation(scene, backend="cpu")


def test_material_touching_a_slip_ceiling_is_warned_about():
    """A water box up to the ceiling's node plane (0.5 - 3 cells = 0.40625) hangs from a slip
    ceiling (slip removes the normal velocity both ways): the scene warns and names the face to
    make separating. Under the default walls (separating), or 2 cells lower, it does not."""
    import copy

    from conftest import SMALL_DICT

    scene = copy.deepcopy(SMALL_DICT)
    del scene["walls"]["condition"]
    scene["body"][0]["max"] = [0.3, 0.40625, 0.3]
    assert rtmpm.Scene.from_dict(scene).warnings == []
    scene["walls"]["condition"] = "slip"
    (w,) = rtmpm.Scene.from_dict(scene).warnings
    assert w.startswith("body[0]") and 'the y_max wall (condition "slip")' in w, w
    assert "hangs from it" in w and "[walls.faces.y_max]" in w, w
    scene["body"][0]["max"] = [0.3, 0.40625 - 2 * 0.03125, 0.3]
    assert rtmpm.Scene.from_dict(scene).warnings == []


def test_write_frame_ply_and_vtu(tmp_path, jelly_path):
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    sim.run_frame()
    sim.write_frame(tmp_path / "f.ply", fields=["J", "stress"])
    d = rtmpm.read_ply(tmp_path / "f.ply")
    assert np.array_equal(d["x"], sim.particles.x[:, 0])
    assert np.allclose(d["J"], sim.particles.J)
    assert "sxx" in d
    sim.write_frame(tmp_path / "f.vtu")
    assert (tmp_path / "f.vtu").read_bytes().startswith(b"<?xml")
    with pytest.raises(ValueError, match="format"):
        sim.write_frame(tmp_path / "f.txt")


# The first bytes of a frame file of each format.
MAGIC = {
    "ply": b"ply\nformat binary_little_endian",
    "bgeo": b"BgeoV",
    "bgeo.gz": b"\x1f\x8b",
    "usda": b"#usda 1.0",
    "vtu": b"<?xml",
}


def test_write_frame_writes_every_format(tmp_path, jelly_path):
    # Every format a scene can name in [output] formats, by name and by file extension.
    assert set(rtmpm.frame_formats) == set(MAGIC)
    sim = rtmpm.Simulation(jelly_path, backend="cpu")
    sim.run_frame()
    for name in rtmpm.frame_formats:
        by_ext = tmp_path / f"a.{name}"
        by_name = tmp_path / f"b_{name.replace('.', '_')}.bin"
        sim.write_frame(by_ext, fields=["J"])
        sim.write_frame(by_name, format=name.upper(), fields=["J"])
        data = by_ext.read_bytes()
        assert data.startswith(MAGIC[name]), name
        assert data == by_name.read_bytes(), name
    with pytest.raises(ValueError, match="unknown frame format"):
        sim.write_frame(tmp_path / "c.ply", format="obj")


def test_render_returns_an_rgb_image(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    img = sim.render(size=(160, 90))
    assert img.shape == (90, 160, 3) and img.dtype == np.uint8
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20
    by_speed = sim.render(size=(64, 36), color_by="speed", camera=(1.5, 1.0, 1.5), shadows=False)
    assert by_speed.shape == (36, 64, 3)
    with pytest.raises(ValueError, match="colouring"):
        sim.render(color_by="temperature")


def test_render_gpu_is_render_where_the_backend_does_not_draw(small_path):
    """On the CPU backend render_gpu is the CPU renderer of the same request: the same picture
    as render, byte for byte, in every colour mode (given the same radius)."""
    sim = rtmpm.Simulation(small_path, backend="cpu")
    sim.run_frame()
    for color_by in ("material", "speed", "J", "stress", "plastic"):
        a = sim.render(size=(160, 90), color_by=color_by, radius=0.01)
        b = sim.render_gpu(size=(160, 90), color_by=color_by, radius=0.01)
        assert b.shape == (90, 160, 3) and b.dtype == np.uint8
        assert np.array_equal(a, b), color_by
    # The default radius comes from the scene (0.6 of the spacing): that of render here.
    assert np.array_equal(sim.render(size=(64, 36)), sim.render_gpu(size=(64, 36)))
    with pytest.raises(ValueError, match="colouring"):
        sim.render_gpu(color_by="temperature")
    with pytest.raises(ValueError, match="out of range"):
        sim.render_gpu(size=(8, 8))


def test_precision_f64(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu", precision="f64")
    assert sim.precision == "f64" and "f64" in sim.backend.name
    sim.step(3)
    assert sim.particles.x.dtype == np.float32
    v = sim.particles.v
    v[:, 1] = 0.25
    sim.particles.v = v
    assert np.array_equal(sim.particles.v[:, 1], v[:, 1])


def test_backend_choice_and_argument_errors(small_path):
    sim = rtmpm.Simulation(small_path)
    info = sim.backend
    assert info.kind in ("cpu", "cuda")
    assert info.reason.startswith("auto -> ")
    if info.kind == "cpu":
        assert "CUDA not usable" in str(info)
        with pytest.raises(rtmpm.BackendError, match="backend cpu"):
            rtmpm.Simulation(small_path, backend="cuda")
        with pytest.raises(rtmpm.BackendError, match="CUDA backend"):
            sim.particles.x_device
    with pytest.raises(ValueError, match="cpu"):
        rtmpm.Simulation(small_path, backend="gpu")
    with pytest.raises(ValueError):
        rtmpm.Simulation(small_path, gpus=0)
    with pytest.raises(ValueError, match="precision"):
        rtmpm.Simulation(small_path, precision="f16")
    with pytest.raises(TypeError):
        rtmpm.Simulation(42)


def test_blow_up_is_a_simulation_error_with_the_particle(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    # Particle 17 alone (3 cells above the cube) at 500 m/s: 500 * 5e-4 s = 8 cells per step.
    x, v = sim.particles.x, sim.particles.v
    x[17] = [0.25, 0.4, 0.25]
    v[17] = [500.0, 0.0, 0.0]
    sim.particles.x = x
    sim.particles.v = v
    with pytest.raises(rtmpm.SimulationError) as e:
        sim.step(10)
    err = e.value
    assert err.kind == "blowup"
    assert err.particle == 17
    assert err.material == "water"
    assert "cells per step" in err.reason
    assert "smaller time step" in err.advice
    assert err.step == 1


def test_ctrl_c_interrupts_a_long_step_and_the_simulation_goes_on(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    # Python's own Ctrl-C handler, whatever the process inherited: a process started in the
    # background by a non-interactive shell ignores SIGINT, and then interrupt_main() does
    # nothing (the step would run on).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            sim.step(10**9)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    assert time.perf_counter() - t0 < 5.0
    done = sim.steps
    assert 0 < done < 10**9
    assert sim.time == pytest.approx(done * 5e-4)
    sim.step(2)
    assert sim.steps == done + 2


def test_the_interpreter_runs_other_threads_while_stepping(small_path):
    sim = rtmpm.Simulation(small_path, backend="cpu")
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    try:
        t0 = time.perf_counter()
        sim.step(60)
        elapsed = time.perf_counter() - t0
    finally:
        stop.set()
        t.join()
    # The other thread ticked through the stepping (about once a millisecond when it can run).
    assert len(ticks) > 0.2 * elapsed * 1000, (len(ticks), elapsed)


def period_and_amplitude(t, y):
    """Period (twice the mean spacing of zero crossings) and mean peak |y| between crossings,
    as `rtmpm validate` measures them (crates/rtmpm-validate/src/measure.rs)."""
    t, y = np.asarray(t), np.asarray(y)
    cross = []
    for i in range(1, len(y)):
        a, b = y[i - 1], y[i]
        if (a > 0 >= b) or (a < 0 <= b):
            cross.append(t[i - 1] + a / (a - b) * (t[i] - t[i - 1]))
    bounds = [t[0] - 1.0] + cross
    peaks = [np.abs(y[(t > lo) & (t < hi)]).max() for lo, hi in zip(bounds, bounds[1:])]
    return 2 * (cross[-1] - cross[0]) / (len(cross) - 1), float(np.mean(peaks))


def test_vibrating_bar_with_a_sinusoidal_velocity_matches_the_exact_solution():
    """The validation bar (Bardenhagen 2002, validation/vibrating_bar.toml, 14 cells) started
    from v(x, 0) = v0 sin(pi x / 2L) set from Python: the centre-of-mass velocity follows
    (2 v0 / pi) cos(w1 t), period 10 s. Over the scene's 3 periods the period is within 2 % and
    the amplitude within 3 % (APIC loses 2.2 % of it at this resolution: validation/RESULTS.md)."""
    scene = rtmpm.Scene.load(ROOT / "validation" / "vibrating_bar.toml")
    sim = rtmpm.Simulation(scene, backend="cpu")
    L, v0 = 25.0, 0.1
    x = sim.particles.x
    v = np.zeros_like(x)
    v[:, 0] = v0 * np.sin(math.pi / (2 * L) * x[:, 0])
    sim.particles.v = v
    m = sim.particles.mass
    t, vcom = [0.0], [float((m * v[:, 0]).sum() / m.sum())]
    for _ in sim.frames():
        t.append(sim.time)
        vcom.append(float((m * sim.particles.v[:, 0]).sum() / m.sum()))
    period, amplitude = period_and_amplitude(t, vcom)
    w1 = math.pi / (2 * L) * 10.0
    assert abs(period - 2 * math.pi / w1) < 0.02 * 10.0, period
    assert abs(amplitude - 2 * v0 / math.pi) < 0.03 * 2 * v0 / math.pi, amplitude
    # Without the velocity field the bar stays at rest.
    still = rtmpm.Simulation(scene, backend="cpu")
    still.run_frame()
    assert np.abs(still.particles.v).max() < 1e-6
