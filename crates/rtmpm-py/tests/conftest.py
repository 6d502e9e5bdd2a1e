"""Shared fixtures of the rtmpm Python tests (run with pytest; see docs/python.md)."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]

# A small fluid scene: a 0.2 m cube of water in a 0.5 m box, ~2k particles, fixed dt.
SMALL = """
name = "small"
seed = 3
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.1
fps = 50
dt = 5e-4
[walls]
thickness = 3
condition = "separate"
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 2e4
gamma = 7.0
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.3, 0.3, 0.3]
particles_per_cell = 8
sampling = "jittered"
[output]
formats = ["ply"]
"""

# The same structure as a dict (Scene.from_dict).
SMALL_DICT = {
    "name": "small",
    "seed": 3,
    "domain": {"min": [0.0, 0.0, 0.0], "max": [0.5, 0.5, 0.5], "dx": 0.03125},
    "time": {"duration": 0.1, "fps": 50, "dt": 5e-4},
    "walls": {"thickness": 3, "condition": "separate"},
    "material": [
        {"name": "water", "type": "fluid", "density": 1000.0, "bulk_modulus": 2e4, "gamma": 7.0}
    ],
    "body": [
        {
            "material": "water",
            "shape": "box",
            "min": (0.1, 0.1, 0.1),
            "max": [0.1 + 0.2, 0.3, 0.3],
            "particles_per_cell": 8,
            "sampling": "jittered",
        }
    ],
    "output": {"formats": ["ply"]},
}

# An elastic cube under gravity with a CFL step (exercises F, C and the adaptive dt).
JELLY = """
name = "jelly"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.1
fps = 30
cfl = 0.4
max_dt = 1e-3
[[material]]
name = "jelly"
type = "neo_hookean"
density = 1000.0
youngs_modulus = 5e4
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "box"
min = [0.15, 0.2, 0.15]
max = [0.3, 0.35, 0.3]
particles_per_cell = 8
[output]
formats = ["ply"]
"""


@pytest.fixture
def small_path(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


@pytest.fixture
def jelly_path(tmp_path):
    p = tmp_path / "jelly.toml"
    p.write_text(JELLY)
    return p


def cli_binary():
    """The rtmpm command-line tool: $RTMPM_CLI, else the workspace's target/{release,debug}/rtmpm."""
    env = os.environ.get("RTMPM_CLI")
    if env:
        assert pathlib.Path(env).is_file(), f"RTMPM_CLI={env} does not exist"
        return env
    for profile in ("release", "debug"):
        p = ROOT / "target" / profile / "rtmpm"
        if p.is_file():
            return str(p)
    return shutil.which("rtmpm")


@pytest.fixture
def cli():
    b = cli_binary()
    if b is None:
        pytest.skip("no rtmpm binary (set RTMPM_CLI or cargo build)")
    return b
