"""Scenes: files, TOML text and dicts share the schema, the validation and the messages."""

import numpy as np
import pytest

import rtmpm
from conftest import ROOT, SMALL, SMALL_DICT


def test_load_from_toml_and_from_dict_give_the_same_scene(small_path):
    a = rtmpm.Scene.load(small_path)
    b = rtmpm.Scene.from_toml(SMALL)
    c = rtmpm.Scene.from_dict(SMALL_DICT)
    for s in (a, b, c):
        assert s.name == "small"
        assert s.dx == pytest.approx(0.03125)
        assert s.domain == ([0.0, 0.0, 0.0], [0.5, 0.5, 0.5])
        assert s.fixed_dt == pytest.approx(5e-4)
        assert s.fps == 50
        assert s.frames == 5
        assert s.materials == ["water"]
        assert s.precision == "f32"
    assert a.source == str(small_path)
    assert b.source == "<string>"
    assert c.source == "<dict>"
    # The same particles, hence the same simulation, from the three.
    xs = [rtmpm.Simulation(s, backend="cpu").particles.x for s in (a, b, c)]
    assert xs[0].shape[0] == a.count_particles() > 1000
    assert np.array_equal(xs[0], xs[1]) and np.array_equal(xs[0], xs[2])


def test_every_example_scene_loads():
    for path in sorted((ROOT / "scenes").glob("*.toml")):
        s = rtmpm.Scene.load(path)
        assert s.name and s.dx > 0, path


def test_toml_error_names_file_line_field_and_fix(tmp_path):
    bad = SMALL.replace('type = "fluid"', 'type = "neo_hookean"\nyoungs_modulus = 1e5\npoisson_ratio = 0.5').replace(
        "bulk_modulus = 2e4\ngamma = 7.0\n", ""
    )
    path = tmp_path / "bad.toml"
    path.write_text(bad)
    with pytest.raises(rtmpm.SceneError) as e:
        rtmpm.Scene.load(path)
    err = e.value
    assert isinstance(err, rtmpm.RtmpmError)
    assert err.file == str(path)
    assert err.field == "material[0].poisson_ratio"
    assert err.line == bad.splitlines().index("poisson_ratio = 0.5") + 1
    assert "0.5" in err.message
    assert err.fix and "0.45" in err.fix
    # str() is the command line's message: file:line:column: field `...`: message, then the fix.
    assert str(err).startswith(f"{path}:{err.line}:")
    assert "fix:" in str(err)


def test_dict_error_has_the_field_but_no_line():
    d = dict(SMALL_DICT, domain={"min": [0, 0, 0], "max": [0.5, 0.5, 0.5], "dx": -1.0})
    with pytest.raises(rtmpm.SceneError) as e:
        rtmpm.Scene.from_dict(d)
    assert e.value.file == "<dict>"
    assert e.value.line is None
    assert e.value.field == "domain.dx"
    assert str(e.value).startswith("<dict>: field `domain.dx`")


def test_unknown_field_and_bad_values_are_scene_errors():
    with pytest.raises(rtmpm.SceneError) as e:
        rtmpm.Scene.from_toml(SMALL.replace("dt = 5e-4", "dt = 5e-4\nfsp = 3"))
    assert "fsp" in str(e.value)
    with pytest.raises(rtmpm.SceneError):
        rtmpm.Scene.from_toml("this is not toml")
    with pytest.raises(rtmpm.SceneError) as e:
        rtmpm.Scene.load("/no/such/scene.toml")
    assert "cannot read" in str(e.value)


def test_dict_values_that_are_not_toml_are_type_errors():
    with pytest.raises(TypeError, match="time.fps"):
        rtmpm.Scene.from_dict(dict(SMALL_DICT, time={"duration": 0.1, "fps": object()}))
    with pytest.raises(TypeError, match="keys must be strings"):
        rtmpm.Scene.from_dict({1: 2})


def test_dict_accepts_numpy_values():
    d = dict(SMALL_DICT)
    d["domain"] = {"min": np.zeros(3), "max": np.full(3, 0.5), "dx": np.float64(0.03125)}
    s = rtmpm.Scene.from_dict(d)
    assert s.domain == ([0.0, 0.0, 0.0], [0.5, 0.5, 0.5])
