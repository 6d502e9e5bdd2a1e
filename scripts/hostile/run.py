#!/usr/bin/env python3
"""Hostile-input corpus for the rtmpm command line, and a tally of the outcomes.

    python3 scripts/hostile/run.py [--rtmpm target/release/rtmpm] [--work DIR] [--timeout 60]
                                   [--report FILE.md] [--only SUBSTRING]

Every case is built here (scene files, meshes, PLY files, checkpoints with valid checksums
around bad values, used output folders, bad flags), run with closed stdin, a time limit and an
address-space limit (ulimit -v 8 GiB: a huge allocation aborts), and classified:

  clear     non-zero exit, an `error:` message that names what the case expects (a field, a
            file, a particle, the fix), no panic
  unclear   non-zero exit without the expected words
  accepted  exit 0 for an input the case allows to run (e.g. a large but valid value)
  warned    exit 0 for an input that is legal but probably wrong, with a `warning:` line that
            names what the case expects
  silent    exit 0 for such an input without that warning
  crash     a panic, an abort, a signal
  hang      killed at the time limit
  lost      files that must survive (another run's frames, a collection) changed or vanished

Exit status 1 when any case crashed, hung, lost data or gave an unclear message.
"""

import argparse
import hashlib
import os
import re
import resource
import shutil
import struct
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MEM_LIMIT = 8 << 30

GOOD_SCENE = """name = "h"
seed = 1
gravity = [0.0, -9.81, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [0.5, 0.5, 0.5]
dx = 0.03125
[time]
duration = 0.05
fps = 40
cfl = 0.4
max_dt = 2e-3
[walls]
thickness = 3
friction = 0.1
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 2.0e4
poisson_ratio = 0.3
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 2.0e4
[[body]]
material = "jelly"
shape = "box"
min = [0.125, 0.2, 0.125]
max = [0.25, 0.325, 0.25]
particles_per_cell = 8
velocity = [0.5, 0.0, 0.0]
angular_velocity = [0.0, 1.0, 0.0]
[[body]]
material = "water"
shape = "sphere"
center = [0.33, 0.2, 0.3]
radius = 0.06
[[collider]]
shape = "half_space"
point = [0.0, 0.1, 0.0]
normal = [0.0, 1.0, 0.0]
[output]
formats = ["ply", "vtu"]
[render]
fov = 40
"""

# (field path, the line of GOOD_SCENE that sets it); each is replaced by hostile values.
SLOTS = [
    ("seed", "seed = 1"),
    ("gravity", "gravity = [0.0, -9.81, 0.0]"),
    ("domain.min", "min = [0.0, 0.0, 0.0]"),
    ("domain.max", "max = [0.5, 0.5, 0.5]"),
    ("domain.dx", "dx = 0.03125"),
    ("time.duration", "duration = 0.05"),
    ("time.fps", "fps = 40"),
    ("time.cfl", "cfl = 0.4"),
    ("time.max_dt", "max_dt = 2e-3"),
    ("walls.thickness", "thickness = 3"),
    ("walls.friction", "friction = 0.1"),
    ("material[0].density", "density = 1000.0\nyoungs"),
    ("material[0].youngs_modulus", "youngs_modulus = 2.0e4"),
    ("material[0].poisson_ratio", "poisson_ratio = 0.3"),
    ("material[1].bulk_modulus", "bulk_modulus = 2.0e4"),
    ("body[0].min", "min = [0.125, 0.2, 0.125]"),
    ("body[0].particles_per_cell", "particles_per_cell = 8"),
    ("body[0].velocity", "velocity = [0.5, 0.0, 0.0]"),
    ("body[0].angular_velocity", "angular_velocity = [0.0, 1.0, 0.0]"),
    ("body[1].radius", "radius = 0.06"),
    ("collider[0].normal", "normal = [0.0, 1.0, 0.0]"),
    ("render.fov", "fov = 40"),
]
HOSTILE = ["nan", "-inf", "-1", "0", "1e38", "99999999999999999999", '"text"', "[]", "[nan, 0, 0]"]


def scene_with(slot_line, value):
    key = slot_line.split("=")[0].strip()
    rest = slot_line.split("\n", 1)[1] if "\n" in slot_line else None
    new = f"{key} = {value}" + (f"\n{rest}" if rest else "")
    assert slot_line in GOOD_SCENE, slot_line
    return GOOD_SCENE.replace(slot_line, new, 1)


class Case:
    def __init__(self, name, args, expect, may_accept=False, setup=None, keep=(), stdin=None,
                 warn=False):
        self.name = name          # short id
        self.args = args          # argv after the binary; "{W}" is the case's work folder
        self.expect = expect      # words a clear error must contain (any one of each tuple)
        self.may_accept = may_accept
        # Legal but probably wrong: exit 0 with a `warning:` line holding the expected words.
        self.warn = warn
        self.setup = setup        # fn(work_dir) run first
        self.keep = keep          # paths (relative to work) that must not change
        # fn(argv, work_dir, env, timeout) -> (rc, text, timed_out, verdict or None): runs the
        # case itself (a client talking to a live server); a verdict given overrides judge().
        self.runner = None
        # Too big for the CPU machine's budget but a valid scene for an 80 GB GPU: with a GPU
        # backend `check` may accept it, and its run (minutes of set-up) is not started.
        self.gpu_valid = any(k in name for k in GPU_VALID)


# Scenes that fit a GPU: 43M and 200M particles, a 40M-particle random body; 65,536 worlds of
# the small scene (more than the CPU machine's 24 GiB, less than the GPU machine's memory).
GPU_VALID = ("45M-particle body", "five 40M-particle bodies", "random thin shape",
             "batch: more worlds than memory")
# Refused without a GPU (the CUDA backend not usable, the fix `--backend cpu`), valid with one:
# a batch run on the CUDA backend (all its worlds in the same kernels).
GPU_RUNS = ("batch run: --backend cuda",)


def rigid_body_tail(tables):
    """`[[rigid_body]]` tables appended to GOOD_SCENE (after its [render] table)."""
    return "\n" + tables


def write(p, data):
    p.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    p.write_bytes(data)


# ---------------------------------------------------------------- files made here

def ply_bytes(header_lines, body=b""):
    h = "ply\nformat binary_little_endian 1.0\n" + "".join(l + "\n" for l in header_lines)
    return (h + "end_header\n").encode() + body


def good_ply(n=4):
    body = b"".join(struct.pack("<6fif", i * 0.1, 0.2, 0.3, 0, 0, 0, 0, 0) for i in range(n))
    return ply_bytes([f"element vertex {n}"] + [f"property float {c}" for c in
                     ["x", "y", "z", "vx", "vy", "vz"]] + ["property int material",
                     "property float plastic"], body)


def fnv1a(b):
    h = 0xcbf29ce484222325
    for c in b:
        h ^= c
        h = (h * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h


def checkpoint(scene_text, particles, time_=0.025, step=10, frame=1, origin="/x/h.toml",
               version=1, payload_len=None, n_override=None):
    """A checkpoint with a valid checksum. particles: list of dicts with x, v, mass, vol, mat."""
    p = b""
    for s in (scene_text.encode(), origin.encode()):
        p += struct.pack("<Q", len(s)) + s
    p += struct.pack("<dQQQ", time_, step, frame,
                     len(particles) if n_override is None else n_override)
    cols = {k: b"" for k in "xvcfpmwt"}
    for q in particles:
        cols["x"] += struct.pack("<3f", *q.get("x", (0.3, 0.3, 0.3)))
        cols["v"] += struct.pack("<3f", *q.get("v", (0, 0, 0)))
        cols["c"] += struct.pack("<9f", *([0.0] * 9))
        cols["f"] += struct.pack("<9f", *q.get("f", (1, 0, 0, 0, 1, 0, 0, 0, 1)))
        cols["p"] += struct.pack("<f", q.get("plastic", 0.0))
        cols["m"] += struct.pack("<f", q.get("mass", 1e-3))
        cols["w"] += struct.pack("<f", q.get("vol", 1e-6))
        cols["t"] += struct.pack("<I", q.get("mat", 0))
    p += b"".join(cols[k] for k in "xvcfpmwt")
    head = b"RTMPMCKP" + struct.pack("<II", version, 0)
    head += struct.pack("<Q", len(p) if payload_len is None else payload_len)
    body = head + p
    return body + struct.pack("<Q", fnv1a(body))


def tree_hash(d):
    h = hashlib.sha256()
    if not d.exists():
        return "missing"
    for f in sorted(d.rglob("*")):
        if f.is_file() and not f.name.startswith(".rtmpm.lock"):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


# ---------------------------------------------------------------- the corpus

def cases():
    out = []
    S = "{W}/scene.toml"
    run = ["run", S, "--backend", "cpu", "--frames", "1", "--out", "{W}/out"]

    # 1. every slot of a valid scene with each hostile value: check, then a short run.
    for field, line in SLOTS:
        for v in HOSTILE:
            text = scene_with(line, v)
            last = field.split(".")[-1]
            parent = field.rsplit(".", 1)[0] + "." if "." in field else field
            out.append(Case(f"value {field} = {v}", ["check", S], [(field, last, parent)], may_accept=True,
                            setup=lambda w, t=text: write(w / "scene.toml", t)))
    # ... and a run of those values that a check accepts is done by the 'run' cases below.
    for field, line, v, words in [
        ("body[0].velocity", "velocity = [0.5, 0.0, 0.0]", "[1e6, 0, 0]", ("time step collapsed", "min_dt")),
        ("body[0].velocity", "velocity = [0.5, 0.0, 0.0]", "[1e30, 0, 0]", ("time step collapsed", "blew up", "initial speed", "lower `body[0].velocity`")),
        ("body[0].angular_velocity", "angular_velocity = [0.0, 1.0, 0.0]", "[0, 1e7, 0]", ("time step collapsed", "blew up", "lower `body[0].angular_velocity`")),
        ("gravity", "gravity = [0.0, -9.81, 0.0]", "[0, -1e30, 0]", ("blew up", "time step collapsed", "lower `gravity`")),
        ("material[0].youngs_modulus", "youngs_modulus = 2.0e4", "1e38", ("time step collapsed", "blew up", "min_dt", "does not fit")),
        ("time.max_dt", "max_dt = 2e-3", "1e-12", ("steps",)),
    ]:
        text = scene_with(line, v)
        out.append(Case(f"run {field} = {v}", run + ["--no-output"], [words], may_accept=True,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))

    # 2. scene files that are not scenes.
    structural = {
        "empty file": ("", [("domain",)]),
        "missing [domain]": ("name = 'x'\n[time]\nduration = 1\n", [("field `domain`",)]),
        "missing [time]": (GOOD_SCENE.replace("[time]\nduration = 0.05\nfps = 40\ncfl = 0.4\nmax_dt = 2e-3\n", ""), [("time",)]),
        "missing domain.dx": (GOOD_SCENE.replace("dx = 0.03125\n", ""), [("domain.dx",)]),
        "unknown field": (GOOD_SCENE.replace("seed = 1", "sed = 1"), [("sed",)]),
        "unknown table": (GOOD_SCENE + "[solvr]\nx = 1\n", [("solvr",)]),
        "unknown material type": (GOOD_SCENE.replace('"fixed_corotated"', '"steel"'), [("type", "material[0]")]),
        "unknown body material": (GOOD_SCENE.replace('material = "jelly"', 'material = "jely"'), [("body[0].material",)]),
        "syntax error": (GOOD_SCENE.replace("[time]", "[time"), [(":8:6",)]),
        "toml_edit panic input": ("==\n.=", [("h.toml", "scene.toml")]),
        "binary garbage": (bytes(range(256)) * 64, [("not UTF-8",)]),
        "utf-16 text": (GOOD_SCENE.encode("utf-16"), [("not UTF-8",)]),
        "20 MB of comments": ("#" * (20 << 20), [("more than 16.00 MiB",)]),
        "name climbs out": (GOOD_SCENE.replace('name = "h"', 'name = "../../evil"'), [("name",)]),
        "name is a path": (GOOD_SCENE.replace('name = "h"', 'name = "/etc/x"'), [("name",)]),
        "hidden name": (GOOD_SCENE.replace('name = "h"', 'name = ".."'), [("name",)]),
        "output dir climbs": (GOOD_SCENE + '', [("output.dir",)]),
        "duplicate key": (GOOD_SCENE.replace("seed = 1", "seed = 1\nseed = 2"), [("seed", "duplicate")]),
        "body outside": (GOOD_SCENE.replace("radius = 0.06", "radius = 6"), [("outside",)]),
        "body inside walls": (GOOD_SCENE.replace("min = [0.125, 0.2, 0.125]", "min = [0.01, 0.2, 0.125]"), [("walls",)]),
        "dt and cfl": (GOOD_SCENE.replace("cfl = 0.4", "cfl = 0.4\ndt = 1e-4"), [("time.cfl", "time.dt")]),
        "min_dt above max_dt": (GOOD_SCENE.replace("cfl = 0.4", "cfl = 0.4\nmin_dt = 1"), [("min_dt",)]),
        "walls fill domain": (GOOD_SCENE.replace("thickness = 3", "thickness = 10"), [("walls.thickness",)]),
        # No per-body particle limit: the memory check refuses it, naming the body.
        "4096 cells, body too fine": (GOOD_SCENE.replace("dx = 0.03125", "dx = 0.0001220703125"), [("lattice points", "does not fit"), ("body[0]",)]),
        "dx above the domain": (GOOD_SCENE.replace("dx = 0.03125", "dx = 1.0"), [("domain.dx", "domain.max")]),
        "random thin shape": (GOOD_SCENE.replace("radius = 0.06", 'radius = 0.06\nsampling = "random"\ncount = 40000000'), [("body[1]",)]),
        "count without random": (GOOD_SCENE.replace("radius = 0.06", "radius = 0.06\ncount = 5"), [("count",)]),
        "ppc 2^32": (GOOD_SCENE.replace("particles_per_cell = 8", "particles_per_cell = 4294967296"), [("particles_per_cell",)]),
        "seed 2^64": (GOOD_SCENE.replace("seed = 1", "seed = 18446744073709551616"), [("seed",)]),
        "negative seed": (GOOD_SCENE.replace("seed = 1", "seed = -1"), [("seed",)]),
        "zero-volume body": (GOOD_SCENE.replace("max = [0.25, 0.325, 0.25]", "max = [0.125, 0.325, 0.25]"), [("body[0]",)]),
        "vector of 2": (GOOD_SCENE.replace("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, -9.81]"), [("gravity",)]),
        "nested arrays": (GOOD_SCENE.replace("gravity = [0.0, -9.81, 0.0]", "gravity = [[0.0], -9.81, 0.0]"), [("gravity",)]),
        "10k materials": (GOOD_SCENE + "".join(f'[[material]]\nname = "m{i}"\ntype = "fluid"\ndensity = 1\nbulk_modulus = 1\n' for i in range(10000)), [],),
    }
    # Rigid bodies: checked by `rtmpm check` whatever the build's features.
    rigid = '[[rigid_body]]\nshape = "box"\nmin = [0.3, 0.3, 0.3]\nmax = [0.36, 0.36, 0.36]\ndensity = 500.0\n'
    for name, text, words in [
        ("zero mass", rigid.replace("density = 500.0", "mass = 0.0"), ("rigid_body[0].mass",)),
        ("negative density", rigid.replace("500.0", "-500.0"), ("rigid_body[0].density",)),
        ("nan mass", rigid.replace("density = 500.0", "mass = nan"), ("rigid_body[0].mass",)),
        ("density and mass", rigid.replace("500.0", "500.0\nmass = 1.0"), ("rigid_body[0].mass",)),
        ("overlapping bodies", rigid + rigid.replace("0.3, 0.3, 0.3", "0.33, 0.33, 0.33").replace("0.36, 0.36, 0.36", "0.39, 0.39, 0.39"),
         ("overlaps",)),
        ("in the walls", rigid.replace("min = [0.3, 0.3, 0.3]", "min = [0.05, 0.3, 0.3]"), ("rigid_body[0].shape",)),
        ("turned into the walls", rigid.replace("min = [0.3, 0.3, 0.3]", "min = [0.1, 0.3, 0.3]").replace(
            "max = [0.36, 0.36, 0.36]", "max = [0.4, 0.36, 0.36]\nrotation = [0.0, 0.0, 1.0]"), ("rigid_body[0].shape",)),
        ("cylinder without height", rigid.replace('"box"\nmin = [0.3, 0.3, 0.3]\nmax = [0.36, 0.36, 0.36]',
                                                  '"cylinder"\ncenter = [0.3, 0.3, 0.3]\nradius = 0.03'), ("rigid_body[0].height",)),
        ("mesh body without its file", rigid.replace('"box"\nmin = [0.3, 0.3, 0.3]\nmax = [0.36, 0.36, 0.36]', '"mesh"\nfile = "m.obj"'),
         ("rigid_body[0].file",)),
        ("fixed body with a velocity", rigid.replace("density = 500.0", 'type = "fixed"\nvelocity = [1.0, 0.0, 0.0]'),
         ("rigid_body[0].velocity",)),
        ("joint to an unknown body", rigid + '[[joint]]\ntype = "spherical"\nbody = "nope"\nanchor = [0.3, 0.4, 0.3]\n',
         ("joint[0].body",)),
        ("joint to itself", rigid + '[[joint]]\ntype = "spherical"\nbody = 0\nto = 0\nanchor = [0.3, 0.4, 0.3]\n',
         ("joint[0].to",)),
        ("hinge without an axis", rigid + '[[joint]]\ntype = "revolute"\nbody = 0\nanchor = [0.3, 0.4, 0.3]\n',
         ("joint[0].axis",)),
        ("joint anchor outside", rigid + '[[joint]]\ntype = "spherical"\nbody = 0\nanchor = [0.3, 9.0, 0.3]\n',
         ("joint[0].anchor",)),
    ]:
        structural[f"rigid body: {name}"] = (GOOD_SCENE + rigid_body_tail(text), [words])
    # Batches of worlds ([batch]): counts, sweeps of unknown or non-numeric fields, lists of
    # the wrong length, values the scene refuses, more worlds than memory holds.
    for name, tail, words in [
        ("count 0", "[batch]\ncount = 0\n", ("batch.count", "at least one world")),
        ("count negative", "[batch]\ncount = -4\n", ("batch.count", "at least one world")),
        ("count not whole", "[batch]\ncount = 2.5\n", ("batch.count", "whole number")),
        ("count text", '[batch]\ncount = "16"\n', ("batch.count", "whole number")),
        ("count missing", "[batch]\n", ("batch.count", "needs `count`")),
        ("count 10^12", "[batch]\ncount = 1000000000000\n", ("1000000000000",)),
        ("more worlds than memory", "[batch]\ncount = 65536\n", ("worlds fit", "does not fit")),
        ("unknown table", '[batch]\ncount = 2\n[batch.sweep]\n"materal[0].density" = [1, 2]\n',
         ("unknown field", "materal")),
        ("index past the end", '[batch]\ncount = 2\n[batch.sweep]\n"material[5].density" = [1, 2]\n',
         ("has 2 entries",)),
        ("misspelt field", '[batch]\ncount = 2\n[batch.sweep]\n"material[0].youngs_modulos" = [1e4, 2e4]\n',
         ("youngs_modulos",)),
        ("non-numeric field", '[batch]\ncount = 2\n[batch.sweep]\n"material[0].type" = [1, 2]\n',
         ("only numbers",)),
        ("list of the wrong length", '[batch]\ncount = 3\n[batch.sweep]\n"gravity[1]" = [-9.81, -1.62]\n',
         ("2 values and the batch 3 worlds",)),
        ("nan in a sweep", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = [-9.81, nan]\n', ("finite",)),
        ("value the scene refuses", '[batch]\ncount = 3\n[batch.sweep]\n"material[0].poisson_ratio" = { from = 0.1, to = 0.7 }\n',
         ("world 2", "poisson_ratio")),
        ("scalar for a vector", '[batch]\ncount = 2\n[batch.sweep]\n"gravity" = [1, 2]\n', ("vector of 3",)),
        ("one field swept twice", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = [-1, -2]\n'
         'gravity = [[0, -1, 0], [0, -2, 0]]\n', ("sets the same field",)),
        ("sweep of the frame rate", '[batch]\ncount = 2\n[batch.sweep]\n"time.fps" = [40, 80]\n',
         ("`time.fps` is the same in every world",)),
        ("sweep of the duration", '[batch]\ncount = 2\n[batch.sweep]\n"time.duration" = [0.05, 0.5]\n',
         ("`time.duration` is the same in every world",)),
        ("whole number past f64", '[batch]\ncount = 2\n[batch.sweep]\n"seed" = [1, 1e21]\n',
         ("world 1 would get 1e21",)),
        ("range past f32", '[batch]\ncount = 2\n[batch.sweep]\n"material[0].density" = { from = 1, to = 1e40 }\n',
         ("density = 1e40",)),
        ("range from NaN", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = { from = nan, to = 1 }\n',
         ("finite",)),
        ("log range through 0", '[batch]\ncount = 3\n[batch.sweep]\n"material[0].density" = { from = 0, to = 10, spacing = "log" }\n',
         ("above 0",)),
        ("unknown spacing", '[batch]\ncount = 3\n[batch.sweep]\n"material[0].density" = { from = 1, to = 10, spacing = "cubic" }\n',
         ("spacing",)),
        ("range with a step", '[batch]\ncount = 3\n[batch.sweep]\n"material[0].density" = { from = 1, to = 10, step = 2 }\n',
         ("unknown field `step`",)),
        ("negative index", '[batch]\ncount = 2\n[batch.sweep]\n"material[-1].density" = [1, 2]\n', ("not an index",)),
        ("index past u64", '[batch]\ncount = 2\n[batch.sweep]\n"material[99999999999999999999].density" = [1, 2]\n',
         ("not an index",)),
        ("empty path", '[batch]\ncount = 2\n[batch.sweep]\n"" = [1, 2]\n', ("the path is empty",)),
        ("component of a component", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1][0]" = [1, 2]\n',
         ("is not a list",)),
        ("text field", '[batch]\ncount = 2\n[batch.sweep]\n"name" = [1, 2]\n', ("only numbers",)),
        ("sweep of [batch]", '[batch]\ncount = 2\n[batch.sweep]\n"batch.count" = [1, 2]\n', ("cannot be swept",)),
        ("array of [[batch]]", '[[batch]]\ncount = 2\n', ("must be a table",)),
        ("count 65537", '[batch]\ncount = 65537\n', ("65536",)),
        ("a sweep that is a boolean", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = true\n', ("a list or a range",)),
        ("vectors of two lengths", '[batch]\ncount = 2\n[batch.sweep]\n"gravity" = [[0, -9.8, 0], [0, 1]]\n',
         ("same shape",)),
        ("gravity of 1e30 in one world", '[batch]\ncount = 2\n[batch.sweep]\n"gravity" = [[0, -9.8, 0], [0, 1e30, 0]]\n',
         ("world 1 of 2, gravity = [0, 1e30, 0]",)),
        ("a time step of 1e-12 in one world", '[batch]\ncount = 2\n[batch.sweep]\n"time.max_dt" = [1e-3, 1e-12]\n',
         ("world 1 of 2, time.max_dt = 1e-12",)),
        ("a world's domain that loses its body", '[batch]\ncount = 2\n[batch.sweep]\n"domain.dx" = [0.03125, 0.0625]\n',
         ("world 1 (domain.dx = 0.0625)",)),
        ("a world's domain inverted", '[batch]\ncount = 2\n[batch.sweep]\n"domain.max[0]" = [0.5, -1]\n',
         ("world 1", "domain.max")),
        ("60000 copies of a long file", '[batch]\ncount = 60000\n' + "#" * 8000 + "\n", ("of scene text",)),
    ]:
        structural[f"batch: {name}"] = (GOOD_SCENE + "\n" + tail, [words])
    structural["output dir climbs"] = (GOOD_SCENE + '', [("output.dir",)])
    for name, (text, words) in structural.items():
        if name == "output dir climbs":
            text = GOOD_SCENE.replace('formats = ["ply", "vtu"]', 'formats = ["ply", "vtu"]\ndir = "out/../../x"')
        out.append(Case(f"scene: {name}", ["check", S], words or [()], may_accept=not words,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))
    for name, path, words in [
        ("scene is /dev/zero", "/dev/zero", ("not a regular file",)),
        ("scene is /dev/urandom", "/dev/urandom", ("not a regular file",)),
        ("scene is a folder", "{W}", ("is a folder",)),
        ("scene missing", "{W}/nope.toml", ("No such file", "check the path")),
        ("scene is a fifo", "{W}/fifo.toml", ("not a regular file",)),
    ]:
        def mk(w, path=path):
            if "fifo" in path:
                os.mkfifo(w / "fifo.toml")
        out.append(Case(name, ["check", path], [words], setup=mk))
        out.append(Case(name + " (run)", ["run", path, "--backend", "cpu", "--no-output"], [words], setup=mk))

    # 3. sizes: huge bodies, absurd steps and frames.
    big = GOOD_SCENE.replace("max = [0.5, 0.5, 0.5]\ndx = 0.03125", "max = [4.0, 4.0, 4.0]\ndx = 0.01")
    one_45m = big.replace("radius = 0.06", "radius = 0.06").replace(
        "min = [0.125, 0.2, 0.125]\nmax = [0.25, 0.325, 0.25]", "min = [0.05, 0.05, 0.05]\nmax = [1.8, 1.8, 1.8]")
    five = big + "".join(
        f'[[body]]\nmaterial = "water"\nshape = "box"\nmin = [0.05, 0.05, {0.05 + 0.75 * i}]\nmax = [3.9, 3.9, {0.39 + 0.75 * i}]\n'
        for i in range(5))
    for name, text, words in [
        ("45M-particle body (check)", one_45m, ("does not fit", "ok")),
        ("five 40M-particle bodies (check)", five, ("does not fit",)),
        ("dt = 1e-12", GOOD_SCENE.replace("cfl = 0.4\nmax_dt = 2e-3", "dt = 1e-12"), ("steps",)),
        ("fps = 1e12", GOOD_SCENE.replace("fps = 40\ncfl = 0.4\nmax_dt = 2e-3", "fps = 1e12\ndt = 1e-13"), ("frames",)),
        ("duration = 1e30", GOOD_SCENE.replace("duration = 0.05", "duration = 1e30"), ("frames",)),
    ]:
        out.append(Case(f"size: {name}", ["check", S], [words], may_accept="45M" in name,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))
        out.append(Case(f"size: {name} (run)", run[:4] + run[6:], [words],
                        setup=lambda w, t=text: write(w / "scene.toml", t)))

    # 4. meshes.
    cube = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n" \
           "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n"
    mesh_body = GOOD_SCENE.replace('shape = "sphere"\ncenter = [0.33, 0.2, 0.3]\nradius = 0.06',
                                   'shape = "mesh"\nfile = "MESH"\nscale = 0.1\ntranslate = [0.3, 0.15, 0.3]')
    for name, mesh, words in [
        ("mesh is /dev/zero", "/dev/zero", ("not a regular file",)),
        ("mesh missing", "nope.obj", ("nope.obj",)),
        ("mesh is a folder", ".", ("folder",)),
        ("mesh garbage", "g.obj", ("g.obj",)),
        ("mesh NaN vertex", "nan.obj", ("non-finite",)),
        ("mesh bad face index", "idx.obj", ("vertex",)),
        ("mesh no triangles", "empty.obj", ("no triangles",)),
        ("mesh huge coordinates", "huge.obj", ("body[1]",)),
        ("mesh non-UTF-8", "bin.obj", ("body[1]",)),
    ]:
        def mk(w, mesh=mesh, name=name):
            write(w / "scene.toml", mesh_body.replace("MESH", mesh))
            if mesh == "g.obj":
                write(w / mesh, os.urandom(4096))
            if mesh == "nan.obj":
                write(w / mesh, cube.replace("v 1 1 1", "v nan 1 1"))
            if mesh == "idx.obj":
                write(w / mesh, cube + "f 1 2 99\n")
            if mesh == "empty.obj":
                write(w / mesh, "v 0 0 0\n")
            if mesh == "huge.obj":
                write(w / mesh, cube.replace("v 1 1 1", "v 1e30 1 1"))
            if mesh == "bin.obj":
                write(w / mesh, b"\xff\xfe" + cube.encode("utf-16-le"))
        out.append(Case(f"mesh: {name}", ["check", S], [words], setup=mk))

    # 4a. mesh rigid bodies (`[[rigid_body]] shape = "mesh"`): a body needs a closed,
    # outward-wound mesh with a volume (and a convex one for convex = true), of a bounded size.
    rigid_mesh = GOOD_SCENE + rigid_body_tail(
        '[[rigid_body]]\nshape = "mesh"\nfile = "MESH"\nscale = 0.06\ntranslate = [0.3, 0.3, 0.3]\n'
        'density = 500.0\nCONVEX\n')
    faces = [l for l in cube.splitlines() if l.startswith("f ")]
    verts = "".join(l + "\n" for l in cube.splitlines() if l.startswith("v "))
    flipped = "".join("f " + " ".join(reversed(l.split()[1:])) + "\n" for l in faces)
    dented = verts + "v 0.5 0.6 0.5\n" + "".join(l + "\n" for l in faces if l not in ("f 3 4 8", "f 3 8 7")) \
        + "f 4 9 3\nf 3 9 7\nf 7 9 8\nf 8 9 4\n"
    for name, mesh, text, convex, words in [
        ("missing", "nope.obj", None, "", ("nope.obj",)),
        ("open", "open.obj", verts + "".join(l + "\n" for l in faces[:-2]), "", ("not closed",)),
        ("inverted normals", "inv.obj", verts + flipped, "", ("inverted",)),
        ("zero volume", "flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n", "", ("no volume",)),
        ("non-manifold", "twice.obj", cube + faces[0] + "\n", "", ("not a manifold",)),
        ("convex = true, not convex", "dent.obj", dented, "convex = true", ("not convex",)),
        ("too many triangles", "big.obj", verts + "f 1 2 3\n" * 200_001, "", ("more than the",)),
        ("huge coordinates", "huge.obj", cube.replace("v 1 1 1", "v 1e30 1 1"), "", ("rigid_body[0]",)),
    ]:
        def mk(w, mesh=mesh, text=text, convex=convex):
            write(w / "scene.toml", rigid_mesh.replace("MESH", mesh).replace("CONVEX", convex))
            if text is not None:
                write(w / mesh, text)
        out.append(Case(f"mesh rigid body: {name}", ["check", S], [("rigid_body[0]",), words], setup=mk))

    # 4b. particle files (`shape = "particles"`): PLY, VTU, BGEO readers.
    pts_body = GOOD_SCENE.replace('shape = "sphere"\ncenter = [0.33, 0.2, 0.3]\nradius = 0.06',
                                  'shape = "particles"\nfile = "PTS"')

    def xyz_ply(points, volume=None):
        props = ["x", "y", "z"] + (["volume"] if volume is not None else [])
        body = b"".join(struct.pack(f"<{len(props)}f", *p, *([volume] if volume is not None else []))
                        for p in points)
        return ply_bytes([f"element vertex {len(points)}"] + [f"property float {c}" for c in props], body)

    inside = [(0.3, 0.2, 0.3), (0.32, 0.2, 0.3)]
    for name, pts, words, files, how in [
        ("no extension (/dev/zero)", "/dev/zero", ("unknown particle file type",), {}, "check"),
        ("symlink to /dev/zero", "zero.ply", ("not a regular file",), {"zero.ply": "->/dev/zero"}, "check"),
        ("named pipe", "pipe.vtu", ("a pipe",), {"pipe.vtu": "fifo"}, "check"),
        ("folder", "d.bgeo", ("folder",), {"d.bgeo": "dir"}, "check"),
        ("missing", "nope.ply", ("nope.ply",), {}, "check"),
        ("garbage BGEO.gz", "g.bgeo.gz", ("g.bgeo.gz",), {"g.bgeo.gz": os.urandom(4096)}, "check"),
        ("garbage VTU", "g.vtu", ("g.vtu",), {"g.vtu": os.urandom(4096)}, "check"),
        ("gzip of 64 MB of zeros", "z.bgeo.gz", ("z.bgeo.gz",), {"z.bgeo.gz": "zeros.gz"}, "check"),
        ("PLY header of 1e9 points", "h.ply", ("truncated",),
         {"h.ply": ply_bytes(["element vertex 1000000000", "property float x", "property float y",
                              "property float z"])}, "check"),
        ("PLY NaN position", "nan.ply", ("non-finite",), {"nan.ply": xyz_ply([inside[0], (float("nan"), 0.2, 0.3)])}, "check"),
        ("PLY no points", "none.ply", ("no points",), {"none.ply": xyz_ply([])}, "check"),
        ("PLY point outside the domain", "far.ply", ("outside the domain",), {"far.ply": xyz_ply(inside + [(5.0, 0.2, 0.3)])}, "check"),
        ("PLY volume 1e37 (infinite mass)", "heavy.ply", ("mass",), {"heavy.ply": xyz_ply(inside, 1e37)}, "run"),
    ]:
        def mk(w, pts=pts, files=files):
            write(w / "scene.toml", pts_body.replace("PTS", pts))
            for f, data in files.items():
                if data == "fifo":
                    os.mkfifo(w / f)
                elif data == "dir":
                    (w / f).mkdir()
                elif data == "zeros.gz":
                    import gzip
                    write(w / f, gzip.compress(bytes(64 << 20), compresslevel=1))
                elif isinstance(data, str) and data.startswith("->"):
                    os.symlink(data[2:], w / f)
                else:
                    write(w / f, data)
        args = ["check", S] if how == "check" else run
        out.append(Case(f"particles file: {name}", args, [words, ("body[1]",)], setup=mk))

    # 5. checkpoints with valid checksums around bad values, and broken files.
    ok_particles = [dict(x=(0.2, 0.2, 0.2)), dict(x=(0.3, 0.25, 0.2), mat=1)]
    for name, kw, plist, words in [
        ("material index 7", {}, [dict(mat=7)], ("material index 7",)),
        ("particle 1e9 m away", {}, [dict(x=(1e9, 0.2, 0.2))], ("outside the domain",)),
        ("particle at -1", {}, [dict(x=(-1, 0.2, 0.2))], ("outside the domain",)),
        ("NaN mass", {}, [dict(mass=float("nan"))], ("mass",)),
        ("negative mass", {}, [dict(mass=-1.0)], ("mass",)),
        ("zero volume", {}, [dict(vol=0.0)], ("volume",)),
        ("inf velocity", {}, [dict(v=(float("inf"), 0, 0))], ("velocity",)),
        ("NaN position", {}, [dict(x=(float("nan"), 0, 0))], ("position",)),
        ("NaN F", {}, [dict(f=(float("nan"),) * 9)], ("deformation gradient",)),
        ("inf plastic", {}, [dict(plastic=float("inf"))], ("plastic",)),
        ("NaN time", dict(time_=float("nan")), ok_particles, ("time",)),
        ("negative time", dict(time_=-1.0), ok_particles, ("time",)),
        ("inf time", dict(time_=float("inf")), ok_particles, ("time",)),
        ("frame after step", dict(frame=99, step=3), ok_particles, ("frame",)),
        ("count mismatch", dict(n_override=5), ok_particles, ("particles do not match",)),
        ("count 2^63", dict(n_override=1 << 63), ok_particles, ("particles do not match",)),
        ("version 99", dict(version=99), ok_particles, ("version 99",)),
        ("payload length huge", dict(payload_len=(1 << 64) - 1), ok_particles, ("truncated",)),
    ]:
        def mk(w, kw=kw, plist=plist):
            write(w / "c.ckpt", checkpoint(GOOD_SCENE, plist, **kw))
        out.append(Case(f"checkpoint: {name}", ["run", "--resume", "{W}/c.ckpt", "--backend", "cpu",
                        "--out", "{W}/out", "--frames", "3"], [words], setup=mk))
    for name, content, words in [
        ("scene in checkpoint invalid", checkpoint(GOOD_SCENE.replace("dx = 0.03125", "dx = -1"), ok_particles), ("domain.dx",)),
        ("scene in checkpoint not UTF-8", None, ("not UTF-8",)),
        ("empty file", b"", ("not an rtmpm checkpoint",)),
        ("a PLY file", good_ply(), ("not an rtmpm checkpoint",)),
        ("one bit flipped", None, ("corrupt",)),
        ("truncated", None, ("truncated",)),
    ]:
        def mk(w, content=content, name=name):
            if content is None:
                good = bytearray(checkpoint(GOOD_SCENE, ok_particles))
                if "flipped" in name:
                    good[100] ^= 4
                    content = bytes(good)
                elif "truncated" in name:
                    content = bytes(good[:-50])
                else:
                    bad = GOOD_SCENE.encode()[:50] + b"\xff" + GOOD_SCENE.encode()[51:]
                    raw = checkpoint("X" * len(bad), ok_particles)
                    i = raw.index(b"X" * len(bad))
                    raw = raw[:i] + bad + raw[i + len(bad):-8]
                    content = raw + struct.pack("<Q", fnv1a(raw))
            write(w / "c.ckpt", content)
        out.append(Case(f"checkpoint: {name}", ["run", "--resume", "{W}/c.ckpt", "--backend", "cpu",
                        "--out", "{W}/out"], [words], setup=mk))
    for name, path, words in [("checkpoint is /dev/zero", "/dev/zero", ("not a regular file",)),
                              ("checkpoint is a folder", "{W}", ("folder",)),
                              ("checkpoint missing", "{W}/none.ckpt", ("No such file",))]:
        out.append(Case(name, ["run", "--resume", path, "--backend", "cpu"], [words]))

    # 6. PLY frames given to render.
    xyz = [f"property float {c}" for c in "xyz"]
    for name, data, words in [
        ("1e12 vertices", ply_bytes(["element vertex 1000000000000"] + xyz, b"\0" * 64), ("truncated",)),
        ("2^64-1 vertices", ply_bytes(["element vertex 18446744073709551615"] + xyz), ("truncated", "count")),
        ("count beyond u64", ply_bytes(["element vertex 99999999999999999999999"] + xyz), ("element count",)),
        ("vertex without properties", ply_bytes(["element vertex 1000000000000"]), ("no properties",)),
        ("1e12 empty faces", ply_bytes(["element face 1000000000000", "element vertex 1"] + xyz, b"\0" * 12), ()),
        ("1e12 faces with lists", ply_bytes(["element face 1000000000000", "property list uchar int v", "element vertex 1"] + xyz, b"\0" * 12), ("truncated",)),
        ("list length 2^32-1", ply_bytes(["element face 1", "property list uint int v", "element vertex 0"] + xyz, b"\xff\xff\xff\xff"), ("truncated",)),
        ("ascii ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", ("binary_little_endian",)),
        ("big endian", b"ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n", ("binary_little_endian",)),
        ("no end_header", b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n", ("end_header",)),
        ("no x column", ply_bytes(["element vertex 1", "property float y"], b"\0" * 4), ("`x`",)),
        ("double x column", ply_bytes(["element vertex 1", "property double x", "property double y", "property double z"], b"\0" * 24), ("`x`",)),
        ("truncated body", good_ply()[:-7], ("truncated",)),
        ("NaN positions", good_ply().replace(struct.pack("<f", 0.2), struct.pack("<f", float("nan"))), ()),
        ("not a ply", b"hello", ("not a PLY",)),
        ("header of 2 MB", b"ply\n" + b"comment " + b"x" * (2 << 20) + b"\n", ("header",)),
        ("100k header lines", b"ply\nformat binary_little_endian 1.0\n" + b"comment x\n" * 100000, ("header",)),
    ]:
        def mk(w, data=data):
            write(w / "frames" / "frame_00000.ply", data)
        out.append(Case(f"ply: {name}", ["render", "{W}/frames", "--size", "64x36", "--no-movie"],
                        [words] if words else [()], may_accept=not words, setup=mk))
    # A radius wider than the particles' extent: each sphere would cover the picture (hours).
    for r in ["1e30", "50"]:
        out.append(Case(f"ply: render --radius {r}",
                        ["render", "{W}/frames", "--size", "64x36", "--no-movie", "--radius", r],
                        [("--radius", "larger than")],
                        setup=lambda w: write(w / "frames" / "frame_00000.ply", good_ply())))
    out.append(Case("ply: frame is a link to /dev/zero", ["render", "{W}/frames", "--no-movie"],
                    [("not a regular file",)],
                    setup=lambda w: ((w / "frames").mkdir(), os.symlink("/dev/zero", w / "frames" / "frame_00000.ply"))))

    # 7. output folders: nothing of another run lost or mixed.
    def used(w):
        r = subprocess.run([BIN, "run", str(w / "scene.toml"), "--backend", "cpu", "--out", str(w / "out"),
                            "--checkpoint-every", "1"], capture_output=True, stdin=subprocess.DEVNULL)
        assert r.returncode == 0, r.stderr
    def base(w):
        write(w / "scene.toml", GOOD_SCENE)
        used(w)
    other = GOOD_SCENE.replace("radius = 0.06", "radius = 0.07")
    out.append(Case("folder: fresh run into a used folder", run, [("already holds", "--overwrite")],
                    setup=base, keep=["out"]))
    out.append(Case("folder: other scene into a used folder", run, [("already holds",)],
                    setup=lambda w: (base(w), write(w / "scene.toml", other)), keep=["out"]))
    out.append(Case("folder: unparsable frames.pvd on resume",
                    ["run", "--resume", "{W}/out/checkpoint_00001.ckpt", "--backend", "cpu", "--out", "{W}/out"],
                    [("frames.pvd",)], setup=lambda w: (base(w), write(w / "out/frames.pvd", "garbage")), keep=["out"]))
    out.append(Case("folder: resume another scene's checkpoint here",
                    ["run", "--resume", "{W}/o/checkpoint_00001.ckpt", "--backend", "cpu", "--out", "{W}/out"],
                    [("another run",)], keep=["out"],
                    setup=lambda w: (write(w / "o.toml", other),
                                     subprocess.run([BIN, "run", str(w / "o.toml"), "--backend", "cpu", "--out", str(w / "o"),
                                                     "--checkpoint-every", "1"], capture_output=True), base(w))))
    def locked(w):
        base(w)
        w_out = w / "out"
        p = subprocess.Popen([BIN, "run", str(w / "scene.toml"), "--backend", "cpu", "--threads", "1", "--no-output",
                              "--frames", "100000", "--checkpoint-every", "100000", "--out", str(w_out), "--overwrite"],
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        LONG.append(p)
        t = time.time()
        while str(p.pid) not in (w_out / ".rtmpm.lock").read_text(errors="ignore"):
            time.sleep(0.02)
            if time.time() - t > 30:
                break
    out.append(Case("folder: second run while the first runs", run + ["--overwrite"], [("in use",)], setup=locked))
    out.append(Case("folder: render while a run writes", ["render", "{W}/out"], [("in use",)], setup=locked))
    out.append(Case("folder: --out is a file", ["run", S, "--backend", "cpu", "--out", "{W}/file"], [("file",)],
                    setup=lambda w: (write(w / "scene.toml", GOOD_SCENE), write(w / "file", "x"))))
    def mixed(w):
        base(w)
        write(w / "b.toml", other)
        subprocess.run([BIN, "run", str(w / "b.toml"), "--backend", "cpu", "--out", str(w / "b"), "--frames", "4"],
                       capture_output=True)
        for f in ["frame_00003.ply", "frame_00004.ply"]:
            shutil.copy(w / "b" / f, w / "out" / f)
    out.append(Case("folder: render two runs' frames", ["render", "{W}/out", "--no-movie", "--size", "64x36"],
                    [("two runs",)], setup=mixed))

    # 9. the newer features: rigid bodies, joints, emitters, moving colliders, 32-bit values, particle
    # files, output folders, resume with bodies and files, `mesh`, the flags that size buffers.
    out.extend(newer_feature_cases(S, run, rigid))
    # 10. batch files run and rendered, and the live view's flags.
    out.extend(batch_run_and_view_cases(S))
    out.extend(live_view_cases(S))
    # 11. CK-MPM with the other features, batch sweeps that break one world, the picture
    # commands' numbers, and blow-ups from a keyframed collider or an emitter within one step.
    out.extend(ck_mpm_cases(S))
    out.extend(batch_sweep_cases(S))
    out.extend(picture_flag_cases(S))
    out.extend(step_budget_cases(S))

    # 8. flags.
    for args, words in [
        (["bench", "--n", "8", "--backend", "cpu"], ("20..=1600",)),
        (["bench", "--n", "0", "--backend", "cpu"], ("20..=1600",)),
        (["bench", "--n", "1601", "--backend", "cpu"], ("20..=1600",)),
        (["bench", "--n", "99999999999", "--backend", "cpu"], ("--n",)),
        (["run", S, "--backend", "cpu", "--threads", "999999", "--no-output", "--frames", "1"], ("thread",)),
        (["run", S, "--backend", "cpu", "--frames", "-1"], ("-1",)),
        (["run", S, "--backend", "gpu"], ("--backend",)),
        (["run", S, "--precision", "f16"], ("precision", "f16")),
        (["render", "{W}", "--fps", "nan"], ("--fps",)),
        (["render", "{W}", "--size", "0x0"], ("size",)),
        (["render", "{W}", "--size", "100000x100000"], ("size",)),
        (["run"], ("no scene given",)),
        (["view", S, "--backend", "cpu", "--serve", "nonsense"], ("HOST:PORT",)),
        (["view", S, "--backend", "cpu", "--serve", "192.0.2.1:8080"], ("not an address",)),
        (["view", S, "--backend", "cpu", "--record", "{W}/movie.avi"], (".gif or .mp4",)),
        (["view", S, "--backend", "cpu", "--size", "99999x9", "--serve"], ("size",)),
        (["view", S, "--backend", "cpu", "--threads", "999999", "--record", "{W}/m.gif",
          "--frames", "1"], ("thread",)),
        (["view", S, "--backend", "cpu"], ("--serve",)),
    ]:
        out.append(Case("flags: " + " ".join(a for a in args if "{W}" not in a), args, [words],
                        setup=lambda w: write(w / "scene.toml", GOOD_SCENE)))
    return out


BATCH_TAIL = '\n[batch]\ncount = 3\n[batch.sweep]\n"gravity[1]" = [-9.81, -1.62, -20.0]\n'


def batch_run_and_view_cases(S):
    """Section 10: `rtmpm run`, `render` and `mesh` of batch files and folders, and `view` flags."""
    out = []
    batch = GOOD_SCENE.replace('formats = ["ply", "vtu"]', 'formats = ["ply"]') + BATCH_TAIL
    run = ["run", S, "--backend", "cpu", "--out", "{W}/out"]

    def scene(w, text=batch):
        write(w / "scene.toml", text)

    def ran(w):
        scene(w)
        r = subprocess.run([BIN] + [a.replace("{W}", str(w)) for a in run], capture_output=True,
                           stdin=subprocess.DEVNULL)
        assert r.returncode == 0, r.stderr

    for name, args, words in [
        ("--steps", run + ["--steps", "5"], ("--steps 5", "--frames N")),
        ("--backend cuda", ["run", S, "--backend", "cuda", "--no-output"], ("--backend cpu",)),
        ("--render", run + ["--render"], ("draws no pictures",)),
        ("--preview", run + ["--preview", "{W}/p.png"], ("draws no pictures",)),
        ("--checkpoint-every 0", run + ["--checkpoint-every", "0"], ("--checkpoint-every N",)),
        ("--checkpoint-every with --no-output",
         ["run", S, "--backend", "cpu", "--no-output", "--checkpoint-every", "1"], ("--no-output",)),
        ("--resume of a file, not a batch checkpoint folder", run + ["--resume", "{W}/scene.toml"],
         ("not a folder",)),
        # Without a GPU: the CUDA backend's refusal; with one: the missing checkpoint folder.
        ("--resume of a missing checkpoint on the GPU",
         ["run", S, "--backend", "cuda", "--no-output", "--resume", "{W}/ck"],
         ("--backend cpu", "no batch checkpoint")),
        ("--threads 0", run + ["--threads", "0"], ("--threads",)),
        ("--frames 10^11", ["run", S, "--backend", "cpu", "--no-output", "--frames", "100000000000"],
         ("more than the",)),
    ]:
        out.append(Case(f"batch run: {name}", args, [words], setup=scene))
    # A batch folder run again: refused with the fix (no resume advised: this batch wrote no
    # checkpoint); a world's folder as --out of the batch.
    out.append(Case("batch run: into its own used folder", run, [("already holds", "--overwrite")],
                    setup=ran, keep=["out"]))
    out.append(Case("batch run: into a world's folder of an earlier batch",
                    ["run", S, "--backend", "cpu", "--out", "{W}/out/world_000"],
                    [("already holds",)], setup=ran, keep=["out"]))
    out.append(Case("batch run: one world frozen by a blow-up, the others run", run, [()], may_accept=True,
                    setup=lambda w: scene(w, batch.replace('[-9.81, -1.62, -20.0]', '[-9.81, -1.62, -3e5]'))))
    out.append(Case("batch: view of a batch file", ["view", S, "--backend", "cpu", "--record", "{W}/m.gif",
                    "--frames", "1"], [("[batch]",), ("rtmpm run",)], setup=scene))
    out.append(Case("batch: mesh of a batch folder", ["mesh", "{W}/out"], [("batch run",), ("world_000",)],
                    setup=ran))

    # Hand-edited batch.csv files given to `render`.
    def csv(rows, header="world,folder,label,status,frames,steps"):
        def mk(w):
            ran(w)
            write(w / "out" / "batch.csv", "\n".join([header] + rows) + "\n")
        return mk
    for name, mk, words in [
        ("200k worlds listed", csv([f'{i},world_000,"g = {i}",done,2,10' for i in range(200_000)]),
         ("more than the 8192",)),
        ("a folder outside", csv(['0,../../etc,"x",done,2,10']), ("not a folder of",)),
        ("a missing folder", csv(['0,world_999,"x",done,2,10']), ("world_999",)),
        ("too few columns", csv(["0,world_000"]), ("batch.csv:2",)),
        ("no worlds", csv([]), ("lists no world",)),
        ("binary garbage", lambda w: (ran(w), write(w / "out" / "batch.csv", bytes(range(256)) * 8)), ("batch.csv",)),
    ]:
        out.append(Case(f"batch render: batch.csv with {name}", ["render", "{W}/out", "--no-movie", "--size", "64x36"],
                        [words], setup=mk))

    # `rtmpm view` flags: addresses, sizes, recordings, radius, colour range.
    view = ["view", S, "--backend", "cpu", "--no-window"]
    for args, words in [
        (["--serve", "127.0.0.1:99999"], ("HOST:PORT",)),
        (["--serve", "127.0.0.1:-1"], ("HOST:PORT",)),
        (["--serve", ":8080"], ("HOST:PORT",)),
        (["--serve", "[::1]:8080x"], ("HOST:PORT",)),
        (["--serve", "localhost:"], ("HOST:PORT",)),
        (["--record", "{W}/m.gif", "--size", "7x5"], ("16 to 8192",)),
        (["--record", "{W}/m.gif", "--size", "99999999999x2"], ("WIDTHxHEIGHT",)),
        (["--record", "{W}/m.gif", "--size", "64x36x2"], ("WIDTHxHEIGHT",)),
        (["--record", "{W}/m.gif", "--range", "nan,1"], ("finite",)),
        (["--record", "{W}/m.gif", "--range", "1,0"], ("hi must be above lo",)),
        (["--record", "{W}/m.gif", "--radius=-1"], ("--radius",)),
        (["--record", "{W}/m.gif", "--radius", "nan"], ("--radius",)),
        (["--record", "{W}/m.gif", "--radius", "1e30", "--frames", "1"], ("--radius 1e30 m is larger than the domain",)),
        (["--record", "/dev/null"], (".gif or .mp4",)),
        (["--record", "{W}/.gif"], (".gif or .mp4",)),
        (["--record", "{W}/nope/m.gif"], ("does not exist",)),
        (["--record", "{W}/m.gif", "--frames", "0"], ("--frames",)),
        (["--record", "{W}/m.gif", "--frames", "99999999999999"], ("more than the",)),
    ]:
        out.append(Case("view flags: " + " ".join(a for a in args if "{W}" not in a), view + args, [words],
                        setup=lambda w: write(w / "scene.toml", GOOD_SCENE)))
    # A recording's name taken by a folder, and by the user's own file: kept, refused at once.
    out.append(Case("view flags: --record onto a folder, with --overwrite",
                    view + ["--record", "{W}/m.gif", "--overwrite", "--frames", "1"], [("it is a folder",)],
                    setup=lambda w: (write(w / "scene.toml", GOOD_SCENE), (w / "m.gif").mkdir()), keep=["m.gif"]))
    out.append(Case("view flags: --record onto a user's file", view + ["--record", "{W}/mine.gif", "--frames", "1"],
                    [("exists", "--overwrite")],
                    setup=lambda w: (write(w / "scene.toml", GOOD_SCENE), write(w / "mine.gif", "mine")),
                    keep=["mine.gif"]))
    return out


CK = '\n[solver]\ntransfer = "ck-mpm"\n'
RIGID_BOX = '[[rigid_body]]\nshape = "box"\nmin = [0.3, 0.3, 0.3]\nmax = [0.36, 0.36, 0.36]\ndensity = 500.0\n'


def ck_mpm_cases(S):
    """Section 11a: CK-MPM (`transfer = "ck-mpm"`) with the options of the classic transfers,
    rigid bodies, emitters, batches, particle files, keyframes, the CUDA backend, and the resume
    of a checkpoint written with another transfer."""
    out = []
    ck = GOOD_SCENE + CK
    run = ["run", S, "--backend", "cpu", "--out", "{W}/out"]
    for name, text, words in [
        ("update = musl", ck + 'update = "musl"\n', [("solver.update",), ("ck-mpm",)]),
        ("flip = 0.5", ck + "flip = 0.5\n", [("solver.flip",), ("ck-mpm",)]),
        ("flip = 0", ck + "flip = 0.0\n", [("solver.flip",)]),
        ("a rigid body", ck + RIGID_BOX, [("solver.transfer",), ("rigid_body[0]",)]),
        ("(gimp, musl) a rigid body", GOOD_SCENE + '\n[solver]\ntransfer = "gimp"\nupdate = "musl"\n' + RIGID_BOX,
         [("solver.update",), ("rigid_body[0]",)]),
    ]:
        out.append(Case(f"ck-mpm: {name}", ["check", S], words,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))
    out.append(Case("ck-mpm: a rigid body (run)", run + ["--frames", "1", "--no-output"],
                    [("solver.transfer",), ("rigid_body[0]",)],
                    setup=lambda w: write(w / "scene.toml", ck + RIGID_BOX)))
    emitter = ('[[emitter]]\nmaterial = "water"\nshape = "box"\nmin = [0.27, 0.1, 0.27]\n'
               'max = [0.33, 0.125, 0.33]\nvelocity = [0.0, 2.0, 0.0]\nrate = 2000.0\n')
    keyed = ('[[collider]]\nshape = "sphere"\ncenter = [0.4, 0.3, 0.4]\nradius = 0.03\n'
             'keyframes = [{ t = 0.0 }, { t = 0.05, position = [0.4, 0.3, 0.3] }]\n')
    pts = ck.replace('shape = "sphere"\ncenter = [0.33, 0.2, 0.3]\nradius = 0.06',
                     'shape = "particles"\nfile = "p.ply"')
    three = b"".join(struct.pack("<3f", 0.3 + 0.01 * i, 0.2, 0.3) for i in range(3))
    for name, text, files in [
        ("an emitter", ck + emitter, {}),
        ("a batch", ck.replace('formats = ["ply", "vtu"]', 'formats = ["ply"]') + BATCH_TAIL, {}),
        ("a particle file", pts,
         {"p.ply": ply_bytes(["element vertex 3"] + [f"property float {c}" for c in "xyz"], three)}),
        ("a keyframed collider", ck + keyed, {}),
    ]:
        def mk(w, text=text, files=files):
            write(w / "scene.toml", text)
            for f, data in files.items():
                write(w / f, data)
        out.append(Case(f"ck-mpm: a run with {name}", run, [()], may_accept=True, setup=mk))
    # One GPU runs it (or, without a GPU, the CUDA backend's own error); several GPUs refuse it
    # before any GPU work.
    out.append(Case("ck-mpm: --backend cuda --gpus 2", ["run", S, "--backend", "cuda", "--gpus", "2", "--no-output"],
                    [("--gpus 1",), ("second grid",)], setup=lambda w: write(w / "scene.toml", ck)))

    # A checkpoint of an MLS run resumed with the scene file edited to CK-MPM: the checkpoint's
    # scene runs on, so the edit would be ignored without a word.
    def mls_run(w, then):
        write(w / "scene.toml", GOOD_SCENE)
        r = subprocess.run([BIN, "run", str(w / "scene.toml"), "--backend", "cpu", "--out", str(w / "out"),
                            "--frames", "1", "--checkpoint-every", "1"], capture_output=True,
                           stdin=subprocess.DEVNULL)
        assert r.returncode == 0, r.stderr
        write(w / "scene.toml", then)
    resume = ["run", S, "--resume", "{W}/out/checkpoint_00001.ckpt", "--backend", "cpu", "--out", "{W}/out"]
    out.append(Case("ck-mpm: resume of an MLS checkpoint with the scene edited to ck-mpm", resume,
                    [("scene.toml:",), ("differs from the scene stored in the checkpoint",)],
                    setup=lambda w: mls_run(w, ck), keep=["out"]))
    out.append(Case("ck-mpm: resume with the checkpoint's own scene file", resume + ["--frames", "2"],
                    [()], may_accept=True, setup=lambda w: mls_run(w, GOOD_SCENE)))
    return out


def batch_sweep_cases(S):
    """Section 11b: sweeps that break one world (a negative modulus, infinities, a density
    whose sound speed overflows), huge counts, fields the file leaves out."""
    out = []
    for name, tail, words in [
        ("a range to a negative Young's modulus", '[batch]\ncount = 3\n[batch.sweep]\n'
         '"material[0].youngs_modulus" = { from = -1e4, to = 2e4 }\n', [("world 0",), ("-10000",), ("youngs_modulus",)]),
        ("a list ending in a negative Young's modulus", '[batch]\ncount = 3\n[batch.sweep]\n'
         '"material[0].youngs_modulus" = [2e4, 2e4, -5]\n', [("world 2",), ("-5",)]),
        ("gravity of -inf in one world", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = [-9.81, -inf]\n',
         [("world 1",), ("finite",)]),
        ("gravity of -1e30 in one world", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = [-9.81, -1e30]\n',
         [("world 1",), ("gravity",)]),
        ("a range to inf", '[batch]\ncount = 2\n[batch.sweep]\n"gravity[1]" = { from = -9.81, to = inf }\n',
         [("`to`",), ("finite",)]),
        ("count 1e9 (integer)", "[batch]\ncount = 1000000000\n", [("1000000000",), ("65536",)]),
        ("count 1e9 (float)", "[batch]\ncount = 1e9\n", [("batch.count",), ("whole number",)]),
        ("a log range of densities down to 1e-45", '[batch]\ncount = 3\n[batch.sweep]\n'
         '"material[0].density" = { from = 1e-45, to = 1, spacing = "log" }\n', [("world 0",), ("material[0].density",)]),
        ("a density whose sound speed overflows f32", '[batch]\ncount = 2\n[batch.sweep]\n'
         '"material[0].density" = [1000, 1e-38]\n', [("world 1",), ("sound speed",)]),
        ("a number for a text field the file leaves out", '[batch]\ncount = 2\n[batch.sweep]\n'
         '"walls.condition" = [1, 2]\n', [("world 0 (walls.condition = 1) is refused",)]),
        ("a count for a lattice body", '[batch]\ncount = 2\n[batch.sweep]\n"body[0].count" = [1, 2]\n',
         [("world 0",), ("random",)]),
        ("a field of a table the file lacks", '[batch]\ncount = 2\n[batch.sweep]\n"solver.flip" = [0.1, 0.2]\n',
         [("no `solver`",)]),
        ("time.dt in a CFL scene", '[batch]\ncount = 2\n[batch.sweep]\n"time.dt" = [1e-3, 2e-3]\n',
         [("world 0",), ("time.cfl",)]),
    ]:
        out.append(Case(f"batch sweep: {name}", ["check", S], words,
                        setup=lambda w, t=GOOD_SCENE + "\n" + tail: write(w / "scene.toml", t)))
    out.append(Case("scene: density 1e-38 (sound speed past f32)", ["check", S],
                    [("material[0].density",), ("sound speed",)],
                    setup=lambda w: write(w / "scene.toml", GOOD_SCENE.replace(
                        "density = 1000.0\nyoungs", "density = 1e-38\nyoungs"))))
    return out


def picture_flag_cases(S):
    """Section 11c: the numbers of `render`, `view`, `mesh` and `run --threads` not tried
    before: frame rates a movie cannot have, fields of view of 0 and 180, cameras so far that
    nothing shows, a paused or over-long recording without a front-end, zero threads."""
    out = []
    ply_scene = GOOD_SCENE.replace('formats = ["ply", "vtu"]', 'formats = ["ply"]')

    def ran(w):
        write(w / "scene.toml", ply_scene)
        r = subprocess.run([BIN, "run", str(w / "scene.toml"), "--backend", "cpu", "--out", str(w / "out")],
                           capture_output=True, stdin=subprocess.DEVNULL)
        assert r.returncode == 0, r.stderr
    render = ["render", "{W}/out", "--size", "64x36"]
    for args, words, kind in [
        (["--fps", "1e30"], [("--fps",), ("out of range",)], "error"),
        (["--fps", "1e-30"], [("--fps",), ("out of range",)], "error"),
        (["--fps", "0"], [("--fps",)], "error"),
        (["--fps=-1"], [("--fps",)], "error"),
        (["--fps", "60"], [("--fps 60",), ("50 frames",)], "warn"),
        (["--fov", "0"], [("--fov",), ("field of view",)], "error"),
        (["--fov", "nan"], [("--fov",), ("field of view",)], "error"),
        (["--fov", "180"], [("--fov",), ("field of view",)], "error"),
        (["--camera", "1e30,0,0"], [("--camera",), ("too far apart", "would show nothing")], "error"),
        (["--camera", "1e6,0,0"], [("--camera",), ("would show nothing",)], "error"),
        (["--target", "1e30,1e30,1e30"], [("--target",), ("too far apart",)], "error"),
        (["--target", "inf,0,0"], [("--target",)], "error"),
        (["--radius", "0"], [("--radius",)], "error"),
        (["--radius", "nan"], [("--radius",)], "error"),
        (["--radius=-1"], [("--radius",)], "error"),
        (["--radius", "1e-30", "--no-movie"], [()], "accept"),
        (["--gif-size", "8x8"], [("--gif-size",)], "error"),
        (["--range", "0,1e39"], [("--range",)], "error"),
        (["--range", "0,1", "--no-movie"], [("--range",), ("coloured by material",)], "warn"),
        (["--gif-size", "64x36", "--no-movie"], [("--gif-size",), ("--no-movie",)], "warn"),
    ]:
        out.append(Case("render flags: " + " ".join(args), render + args, words, warn=kind == "warn",
                        may_accept=kind == "accept", setup=ran))
    for args, words in [
        (["--bench", "--bench-particles", "99999999999"], [("--bench-particles",), ("particles fit",)]),
        (["--bench", "--bench-particles", "0"], [("--bench-particles",)]),
    ]:
        out.append(Case("render flags: " + " ".join(args), ["render"] + args, words))
    view = ["view", S, "--backend", "cpu", "--no-window", "--record", "{W}/m.gif", "--size", "64x36"]
    for args, words, accept in [
        (["--fov", "0", "--frames", "1"], [("--fov",), ("field of view",)], False),
        (["--fov", "179.99", "--frames", "1"], [("field of view",), ("would show nothing",)], False),
        (["--camera", "1e30,0,0", "--frames", "1"], [("--camera",), ("too far apart", "would show nothing")], False),
        (["--target", "1e30,1e30,1e30", "--frames", "1"], [("too far apart",)], False),
        (["--paused", "--frames", "2"], [("--paused",)], False),
        (["--threads", "0", "--frames", "1"], [("--threads",)], False),
        (["--pace", "frames:0"], [("frames:N",)], False),
        (["--quality", "0"], [("--quality",)], False),
        (["--quality", "1e30"], [("--quality",)], False),
        # Past the scene's 2 frames, and without --frames: both end (a view pauses at the end).
        (["--frames", "3"], [()], True),
        ([], [()], True),
    ]:
        out.append(Case("view flags (recording): " + (" ".join(args) or "no --frames"), view + args, words,
                        may_accept=accept, setup=lambda w: write(w / "scene.toml", GOOD_SCENE)))
    out.append(Case("flags: run --threads 0", ["run", S, "--backend", "cpu", "--no-output", "--threads", "0"],
                    [("--threads",)], setup=lambda w: write(w / "scene.toml", GOOD_SCENE)))
    fixed = GOOD_SCENE.replace("cfl = 0.4\nmax_dt = 2e-3", "dt = 1e-3")
    # --cuda-options on the CPU backend (`--threads` keeps these on the CPU when the corpus runs
    # its cases on a GPU backend).
    for args, words, kind in [
        (["run", S, "--backend", "cpu", "--out", "{W}/out", "--checkpoint-every", "0"], [("--checkpoint-every",)], "error"),
        (["run", S, "--backend", "cpu", "--threads", "2", "--no-output", "--cuda-options", "p2g=shared"],
         [("--cuda-options",), ("ignores them",)], "warn"),
        (["bench", "--backend", "cpu", "--threads", "2", "--scene", S, "--frames", "1", "--cuda-options",
          "warp_reduce=off"], [("--cuda-options",), ("ignores them",)], "warn"),
        (["run", S, "--backend", "cpu", "--no-output", "--steps", "0"], [()], "accept"),
    ]:
        out.append(Case("flags: " + " ".join(a for a in args if "{W}" not in a), args, words,
                        warn=kind == "warn", may_accept=kind == "accept",
                        setup=lambda w: write(w / "scene.toml", fixed)))
    for args, words, warn in [
        (["--materials=-1"], [("--materials",)], False),
        (["--materials", "4294967296"], [("--materials",)], False),
        (["--materials", "7"], [("no particle of the materials meshed",)], True),
    ]:
        out.append(Case("mesh flags: " + " ".join(args), ["mesh", "{W}/out"] + args, words, warn=warn,
                        setup=ran))
    return out


def step_budget_cases(S):
    """Section 11d: blow-ups caused by a keyframed collider or an emitter whose fast part ends
    within the failed step (the advice must name it, not the time step: its words, not those of
    the fixed-step warning printed before the run), and a keyframed segment that CFL steps
    would have passed over unseen."""
    out = []
    fixed = GOOD_SCENE.replace("cfl = 0.4\nmax_dt = 2e-3", "dt = 1e-3")

    def keyed(keys):
        return ('[[collider]]\nshape = "sphere"\ncenter = [0.19, 0.26, 0.19]\nradius = 0.04\nkeyframes = ['
                + ", ".join(f"{{ t = {t}, position = [{x}, 0.26, 0.19] }}" for t, x in keys) + "]\n")
    jet = ('[[emitter]]\nmaterial = "water"\nshape = "box"\nmin = [0.27, 0.1, 0.27]\nmax = [0.33, 0.125, 0.33]\n'
           'velocity = [0.0, 500.0, 0.0]\nrate = 200000.0\nstart = 0.02\nstop = 0.0205\n')
    run = ["run", S, "--backend", "cpu", "--no-output"]
    for name, text, words, accept in [
        ("a keyframed collider at 400 m/s for half a fixed step", fixed + keyed([(0, 0.19), (0.02, 0.19), (0.0205, 0.39)]),
         [("blew up",), ("collider[1] moves at",), ("cells in a step",)], False),
        ("an emitter at 500 m/s stopping within a fixed step", fixed + jet,
         [("blew up",), ("emitter[0] `emitter0` moves at",), ("cells in a step",)], False),
        ("a keyframed collider at 400 m/s between two CFL steps", GOOD_SCENE.replace("max_dt = 2e-3", "max_dt = 1e-2")
         + keyed([(0, 0.19), (0.02, 0.19), (0.0205, 0.39)]), [()], True),
    ]:
        out.append(Case(f"step budget: {name}", run, words, may_accept=accept,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))
    return out


# ---------------------------------------------------------------- the live view's WebSocket

def ws_connect(port):
    """A WebSocket to the live view's /ws (the handshake by hand: no package needed)."""
    import base64
    import socket
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = sock.recv(1)
        if not chunk:
            raise ConnectionError("closed during the handshake")
        head += chunk
    if b" 101 " not in head.split(b"\r\n")[0]:
        raise ConnectionError(head.decode(errors="replace").splitlines()[0])
    return sock


def ws_send(sock, payload, opcode=1):
    mask = os.urandom(4)
    n = len(payload)
    head = bytes([0x80 | opcode])
    if n < 126:
        head += bytes([0x80 | n])
    elif n < 65536:
        head += bytes([0x80 | 126]) + struct.pack(">H", n)
    else:
        head += bytes([0x80 | 127]) + struct.pack(">Q", n)
    sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))


def ws_frames(sock, seconds):
    """(opcode, payload) of the server's frames for `seconds` (or until it closes)."""
    end = time.time() + seconds
    buf = b""
    out = []
    while time.time() < end:
        sock.settimeout(max(0.01, end - time.time()))
        try:
            chunk = sock.recv(1 << 16)
        except (TimeoutError, OSError):
            break
        if not chunk:
            out.append((8, b""))
            break
        buf += chunk
        while len(buf) >= 2:
            n, at = buf[1] & 0x7F, 2
            if n == 126:
                if len(buf) < 4:
                    break
                n, at = struct.unpack(">H", buf[2:4])[0], 4
            elif n == 127:
                if len(buf) < 10:
                    break
                n, at = struct.unpack(">Q", buf[2:10])[0], 10
            if len(buf) < at + n:
                break
            out.append((buf[0] & 0x0F, buf[at:at + n]))
            buf = buf[at + n:]
    return out


# (name, payload, words one of which the error reply or the close reason must hold; None: a
# valid command at the edge of its range, taken without an error)
WS_MESSAGES = [
    ("garbage", b"\x00\xffnot json at all", ("UTF-8",)),
    ("garbage UTF-8", "\x00\u00ffnot json at all".encode(), ("cannot read",)),
    ("a JSON list", b"[1, 2, 3]", ("cannot read",)),
    ("an unknown command", b'{"cmd": "explode"}', ("cannot read",)),
    ("a drag at NaN", b'{"cmd": "tool_move", "x": NaN, "y": 1}', ("cannot read",)),
    ("a drag at 1e39", b'{"cmd": "tool_move", "x": 1e39, "y": 1}', ("finite", "cannot read")),
    ("a drag at a text", b'{"cmd": "tool_start", "x": "left", "y": 1}', ("cannot read",)),
    ("gravity of 1e30", b'{"cmd": "gravity", "value": [0, -1e30, 0]}', ("gravity",)),
    ("gravity of two numbers", b'{"cmd": "gravity", "value": [0, -9.81]}', ("cannot read",)),
    ("gravity of null", b'{"cmd": "gravity", "value": null}', ("cannot read",)),
    ("a zoom of -1", b'{"cmd": "zoom", "factor": -1}', ("zoom",)),
    ("a resize to 2^32", b'{"cmd": "resize", "width": 4294967296, "height": 10}', ("cannot read",)),
    ("a resize to 1x1", b'{"cmd": "resize", "width": 1, "height": 1}', ("out of range",)),
    ("a pace of 2^32-1 steps", b'{"cmd": "pace", "steps": 4294967295}', ("pace",)),
    ("a tool of -1 m", b'{"cmd": "tool_shape", "shape": "sphere", "size": -1}', ("positive",)),
    ("a ball of an unknown material", b'{"cmd": "throw", "x": 1, "y": 1, "material": "lava"}', ("no material",)),
    ("a ball at 1e6 m/s", b'{"cmd": "throw", "x": 1, "y": 1, "speed": 1e6}', ("ball speed",)),
    ("a colouring of 3000 letters", b'{"cmd": "color_by", "value": "' + b"x" * 3000 + b'"}', ("unknown colouring",)),
    ("JSON nested 1500 deep", b"[" * 1500 + b"]" * 1500, ("cannot read",)),
    ("a binary message", b"\x89PNG", ("binary messages",)),
    ("a message of 1 MB", b"x" * (1 << 20), ("closing", "too long", "size")),
    ("gravity of 1e4 (the largest taken)", b'{"cmd": "gravity", "value": [0, -1e4, 0]}', None),
    ("a tool of 1e4 m dragged", b'{"cmd": "tool_shape", "shape": "box", "size": 1e4}', None),
    ("... started", b'{"cmd": "tool_start", "x": 640, "y": 360}', None),
    ("... moved by 1e5 pixels", b'{"cmd": "tool_move", "x": 100000, "y": -100000}', None),
]


def ws_said(opcode, payload):
    """What a server frame says back to a command: an error message's text, a close frame's
    reason; nothing for pictures, status and role messages."""
    import json
    if opcode == 8:
        return "closed: " + payload[2:].decode(errors="replace")
    if opcode != 1:
        return ""
    try:
        m = json.loads(payload)
    except ValueError:
        return payload.decode(errors="replace")
    return m.get("message", "") if isinstance(m, dict) and m.get("type") == "error" else ""


def live_view_runner(argv, w, env, timeout):
    """Start `rtmpm view --serve 127.0.0.1:0`, send each of WS_MESSAGES on a connection of its own,
    then check that the view still serves and advances, and end it with Ctrl-C."""
    import signal
    p = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         env=env, cwd=w, preexec_fn=limit)
    log = []
    port = None
    start = time.time()
    while port is None and time.time() - start < timeout:
        line = p.stdout.readline().decode(errors="replace")
        if not line:
            break
        log.append(line.rstrip())
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        if m:
            port = int(m.group(1))
    problems = []
    if port is None:
        p.kill()
        rest = p.communicate()[0].decode(errors="replace")
        return p.returncode, "\n".join(log) + rest, False, None
    for name, payload, words in WS_MESSAGES:
        try:
            sock = ws_connect(port)
            ws_frames(sock, 0.3)  # hello, role, the first pictures
            ws_send(sock, payload, opcode=2 if name == "a binary message" else 1)
            replies = ws_frames(sock, 1.0)
            # A slow server (a debug build on two busy cores) may answer after the first second:
            # an expected error is waited for up to 5 s in all (the same words are required); a
            # message that must be taken gets the 1 s window only.
            waited = 1.0
            while (words is not None and waited < 5.0 and not any(op == 8 for op, _ in replies)
                   and not any(x in " ".join(ws_said(op, pl) for op, pl in replies) for x in words)):
                replies += ws_frames(sock, 1.0)
                waited += 1.0
            sock.close()
        except Exception as e:  # the server refused or died
            problems.append(f"{name}: {e}")
            continue
        said = " ".join(ws_said(op, pl) for op, pl in replies)
        if words is None and said.strip():
            problems.append(f"{name}: refused: {said[:200]}")
        elif words is not None and not any(x in said for x in words):
            problems.append(f"{name}: no error naming {words}, got: {said[:200] or 'nothing'}")
        else:
            log.append(f"error: {name}: {said[:150]}" if words else f"{name}: taken")
    alive = p.poll() is None
    if alive:
        try:
            import urllib.request
            status = urllib.request.urlopen(f"http://127.0.0.1:{port}/status", timeout=10).read()
            log.append(f"status after: {status[:150]!r}")
        except Exception as e:
            problems.append(f"/status after the messages: {e}")
        p.send_signal(signal.SIGINT)
    try:
        rest = p.communicate(timeout=30)[0].decode(errors="replace")
        timed_out = False
    except subprocess.TimeoutExpired:
        p.kill()
        rest = p.communicate()[0].decode(errors="replace")
        timed_out = True
    text = "\n".join(log) + "\n" + rest + "".join(f"\nproblem: {x}" for x in problems)
    if timed_out or not alive or "panicked" in text:
        return p.returncode, text, timed_out, None
    return p.returncode, text, False, ("unclear" if problems else "clear")


def live_view_cases(S):
    """The live view's WebSocket messages: garbage, huge, wrong types, out-of-range values."""
    c = Case("view websocket: 21 hostile messages and 4 at the edge of their range, then /status",
             ["view", S, "--backend", "cpu", "--threads", "1", "--no-window", "--serve", "127.0.0.1:0",
              "--frames", "1000000"], [()],
             setup=lambda w: write(w / "scene.toml", GOOD_SCENE.replace("duration = 0.05", "duration = 1000.0")))
    c.runner = live_view_runner
    return [c]


def newer_feature_cases(S, run, rigid):
    """Section 9 of the corpus: the features added after the first hostile-input pass."""
    out = []
    box = '"box"\nmin = [0.3, 0.3, 0.3]\nmax = [0.36, 0.36, 0.36]'
    emitter = ('[[emitter]]\nmaterial = "water"\nshape = "box"\nmin = [0.27, 0.1, 0.27]\n'
               'max = [0.33, 0.125, 0.33]\nvelocity = [0.0, 2.0, 0.0]\nrate = 2000.0\n')
    fixed_dt = GOOD_SCENE.replace("cfl = 0.4\nmax_dt = 2e-3", "dt = 1e-3")
    for name, text, words, warn in [
        ("rigid body at 1e6 m/s", GOOD_SCENE + rigid_body_tail(rigid.replace("density = 500.0", "density = 500.0\nvelocity = [1e6, 0.0, 0.0]")),
         [("rigid_body[0].velocity",), ("400",)], False),
        ("rigid body of density 1e30", GOOD_SCENE + rigid_body_tail(rigid.replace("500.0", "1e30")),
         [("rigid_body[0].density",)], False),
        ("rigid body spinning at 1e9 rad/s", GOOD_SCENE + rigid_body_tail(rigid.replace("density = 500.0", "density = 500.0\nangular_velocity = [0.0, 1e9, 0.0]")),
         [("rigid_body[0].angular_velocity",)], False),
        ("two rigid bodies of one name", GOOD_SCENE + rigid_body_tail(
            rigid.replace("density", 'name = "a"\ndensity') + rigid.replace("0.3, 0.3, 0.3", "0.2, 0.3, 0.3").replace(
                "0.36, 0.36, 0.36", "0.26, 0.36, 0.36").replace("density", 'name = "a"\ndensity')),
         [("rigid_body[1].name",), ("unique",)], False),
        ("rigid body name with a comma", GOOD_SCENE + rigid_body_tail(rigid.replace("density", 'name = "a,b"\ndensity')),
         [("rigid_body[0].name",)], False),
        ("rigid body thinner than a cell", GOOD_SCENE + rigid_body_tail(rigid.replace("max = [0.36, 0.36, 0.36]", "max = [0.36, 0.301, 0.36]")),
         [("rigid_body[0]",), ("thick",)], True),
        ("half-space rigid body", GOOD_SCENE + rigid_body_tail(rigid.replace(box, '"half_space"\npoint = [0.0, 0.1, 0.0]\nnormal = [0.0, 1.0, 0.0]')),
         [("rigid_body[0]",), ("half_space", "half-space")], False),
        ("joint limits of three values", GOOD_SCENE + rigid_body_tail(
            rigid + '[[joint]]\ntype = "revolute"\nbody = 0\nanchor = [0.3, 0.36, 0.3]\naxis = [0.0, 0.0, 1.0]\nlimits = [0.0, 1.0, 2.0]\n'),
         [("joint[0].limits",)], False),
        ("revolute limits beyond pi", GOOD_SCENE + rigid_body_tail(
            rigid + '[[joint]]\ntype = "revolute"\nbody = 0\nanchor = [0.3, 0.36, 0.3]\naxis = [0.0, 0.0, 1.0]\nlimits = [-10.0, 10.0]\n'),
         [("joint[0]",), ("pi",)], True),
        ("emitter of 1e-9 particles a second", GOOD_SCENE + rigid_body_tail(emitter.replace("2000.0", "1e-9")),
         [("emitter[0].rate",), ("no particle",)], False),
        ("emitter starting after the run", GOOD_SCENE + rigid_body_tail(emitter + "start = 10.0\nstop = 11.0\n"),
         [("emitter[0]",), ("emits nothing",)], True),
        ("emitter thinner than a particle", GOOD_SCENE + rigid_body_tail(emitter.replace("max = [0.33, 0.125, 0.33]", "max = [0.33, 0.101, 0.33]")),
         [("emitter[0].shape",)], False),
        ("mesh emitter", GOOD_SCENE + rigid_body_tail(emitter.replace('"box"\nmin = [0.27, 0.1, 0.27]\nmax = [0.33, 0.125, 0.33]', '"mesh"\nfile = "m.obj"')),
         [("emitter[0]",), ("mesh", "shape")], False),
        ("emitter piling its particles up", GOOD_SCENE + rigid_body_tail(emitter.replace("2000.0", "1e7")),
         [("emitter[0]",), ("pile up",)], True),
        ("collider outrunning a fixed step", fixed_dt + rigid_body_tail(
            '[[collider]]\nshape = "sphere"\ncenter = [0.3, 0.3, 0.3]\nradius = 0.03\nvelocity = [100.0, 0.0, 0.0]\n'),
         [("collider[1]",), ("cells per step",)], True),
        ("gravity of 1e5 m/s^2", GOOD_SCENE.replace("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, -1e5, 0.0]"),
         [("gravity",), ("Earth",)], True),
        ("Young's modulus 1e300", GOOD_SCENE.replace("youngs_modulus = 2.0e4", "youngs_modulus = 1e300"),
         [("material[0].youngs_modulus",), ("32-bit float",)], False),
        ("density 1e-50", GOOD_SCENE.replace("density = 1000.0\nyoungs", "density = 1e-50\nyoungs"),
         [("material[0].density",), ("32-bit float", "positive")], False),
    ]:
        out.append(Case(f"newer: {name}", ["check", S], words, warn=warn,
                        setup=lambda w, t=text: write(w / "scene.toml", t)))

    # A particle file whose data is longer than its header says.
    pts = GOOD_SCENE.replace('shape = "sphere"\ncenter = [0.33, 0.2, 0.3]\nradius = 0.06',
                             'shape = "particles"\nfile = "p.ply"')
    three = b"".join(struct.pack("<3f", 0.3 + 0.01 * i, 0.2, 0.3) for i in range(3))
    out.append(Case("newer: PLY particles beyond the header's count", ["check", S],
                    [("p.ply",), ("header announces",)],
                    setup=lambda w: (write(w / "scene.toml", pts),
                                     write(w / "p.ply", ply_bytes(["element vertex 2"] + [f"property float {c}" for c in "xyz"], three)))))

    # Flags that size buffers.
    for args, words in [
        (run + ["--frame-chunk", "0"], ("--frame-chunk",)),
        (run + ["--frames-in-flight", "1000000000", "--frame-chunk", "100000000"], ("--frames-in-flight",)),
        (run + ["--whole-frames", "--frames-in-flight", "1000000000"], ()),
        (["mesh", "{W}", "--bench", "--bench-particles", "100000000000"], ("--bench-particles",)),
        (["mesh", "{W}", "--bench", "--bench-particles", "3"], ("--bench-particles",)),
    ]:
        # PLY frames only: streamed from the backend through the frame writer's buffers.
        ply_only = GOOD_SCENE.replace('formats = ["ply", "vtu"]', 'formats = ["ply"]')
        out.append(Case("newer flags: " + " ".join(a for a in args if "{W}" not in a), args, [words],
                        may_accept=not words, setup=lambda w, t=ply_only: write(w / "scene.toml", t)))

    # --overwrite in a folder that rtmpm never wrote: the user's files that merely match its names
    # are kept, and the refusal names every one of them.
    def users_folder(w):
        write(w / "scene.toml", GOOD_SCENE)
        write(w / "out" / "frame_00000.ply", "my own file")
        write(w / "out" / "frame_00001.vtu", "mine too")
        write(w / "out" / "frames.pvd", "and this")
    for flag in ([], ["--overwrite"]):
        out.append(Case("newer folder: a user's files with rtmpm's names" + (" and --overwrite" if flag else ""),
                        run + flag, [("frame_00000.ply",), ("frame_00001.vtu",), ("frames.pvd",)],
                        setup=users_folder, keep=["out"]))

    # Resume: files changed since the checkpoint, bodies.csv, a particles body without its file.
    cube = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
            "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n")
    mesh_collider = GOOD_SCENE + rigid_body_tail(
        '[[collider]]\nshape = "mesh"\nfile = "m.obj"\nscale = 0.05\ntranslate = [0.3, 0.3, 0.3]\n')
    ckpt = ["run", "--resume", "{W}/out/checkpoint_00001.ckpt", "--backend", "cpu", "--out", "{W}/out"]

    def first_run(w, scene, frames="1"):
        write(w / "scene.toml", scene)
        r = subprocess.run([BIN, "run", str(w / "scene.toml"), "--backend", "cpu", "--out", str(w / "out"),
                            "--frames", frames, "--checkpoint-every", "1"], capture_output=True, stdin=subprocess.DEVNULL)
        assert r.returncode == 0, r.stderr

    def edited_mesh(w):
        write(w / "m.obj", cube)
        first_run(w, mesh_collider)
        write(w / "m.obj", cube.replace("v 1 1 1", "v 1.2 1 1"))
    out.append(Case("newer resume: a collider's mesh edited since the checkpoint", ckpt,
                    [("m.obj",), ("changed since the checkpoint",)], setup=edited_mesh, keep=["out"]))

    def gone_seed(w):
        write(w / "p.ply", ply_bytes(["element vertex 3"] + [f"property float {c}" for c in "xyz"], three))
        first_run(w, pts)
        (w / "p.ply").unlink()
    out.append(Case("newer resume: a particles body whose file is gone", ckpt + ["--frames", "2"],
                    [()], may_accept=True, setup=gone_seed))

    rigid_scene = GOOD_SCENE + rigid_body_tail(rigid.replace("density", 'name = "crate"\ndensity'))

    def broken_rows(w):
        first_run(w, rigid_scene, frames="2")
        lines = (w / "out" / "bodies.csv").read_text().splitlines()
        lines[1] = lines[1].replace('"crate"', '"other"')
        write(w / "out" / "bodies.csv", "\n".join(lines) + "\n")
    out.append(Case("newer resume: bodies.csv naming another body", ckpt, [("bodies.csv:2",)],
                    setup=broken_rows, keep=["out/bodies.csv"]))

    def lost_rows(w):
        first_run(w, rigid_scene, frames="2")
        write(w / "out" / "bodies.csv", "frame,time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz\n")
    out.append(Case("newer resume: bodies.csv without its rows", ckpt, [("bodies.csv",), ("frames 0",)],
                    warn=True, setup=lost_rows))

    # `rtmpm mesh` on frames of two runs, and on a frame with NaN positions.
    def two_runs(w):
        other = GOOD_SCENE.replace("radius = 0.06", "radius = 0.07")
        for name, text in [("a", GOOD_SCENE), ("b", other)]:
            write(w / f"{name}.toml", text)
            subprocess.run([BIN, "run", str(w / f"{name}.toml"), "--backend", "cpu", "--out", str(w / name),
                            "--frames", "1"], capture_output=True, stdin=subprocess.DEVNULL)
        (w / "frames").mkdir()
        shutil.copy(w / "a" / "frame_00000.ply", w / "frames" / "frame_00000.ply")
        shutil.copy(w / "b" / "frame_00001.ply", w / "frames" / "frame_00001.ply")
    out.append(Case("newer mesh: frames of two runs", ["mesh", "{W}/frames"], [("two runs",)], setup=two_runs))
    nan_pts = b"".join(struct.pack("<3f", *p) for p in [(0.3, 0.2, 0.3), (float("nan"), 0.2, 0.3)])
    out.append(Case("newer mesh: a frame with a NaN position", ["mesh", "{W}/frames"], [("non-finite",)], warn=True,
                    setup=lambda w: write(w / "frames" / "frame_00000.ply",
                                          ply_bytes(["element vertex 2"] + [f"property float {c}" for c in "xyz"], nan_pts))))
    dense = b"".join(struct.pack("<3f", 0.3, 0.2, 0.3) for _ in range(100_000))
    out.append(Case("newer mesh: 100k coincident particles", ["mesh", "{W}/frames"], [()], may_accept=True,
                    setup=lambda w: write(w / "frames" / "frame_00000.ply",
                                          ply_bytes(["element vertex 100000"] + [f"property float {c}" for c in "xyz"], dense))))
    return out


# ---------------------------------------------------------------- running and judging

LONG = []
BIN = ""


def limit():
    resource.setrlimit(resource.RLIMIT_AS, (MEM_LIMIT, MEM_LIMIT))


def judge(case, rc, text, timed_out, lost):
    if timed_out:
        return "hang"
    if lost:
        return "lost"
    if rc < 0 or rc in (101, 134, 137, 139) or "panicked" in text or "memory allocation of" in text:
        return "crash"
    if rc == 0 and case.warn:
        warnings = "\n".join(l for l in text.splitlines() if l.startswith("warning"))
        ok = all(not words or any(w in warnings for w in words) for words in case.expect)
        return "warned" if warnings and ok else "silent"
    if rc == 0:
        return "accepted" if case.may_accept else "unclear"
    if not any(l.startswith("error") for l in text.splitlines()):
        return "unclear"
    for words in case.expect:
        if words and not any(w in text for w in words):
            return "unclear"
    return "clear"


def main():
    global BIN
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rtmpm", default=None)
    ap.add_argument("--work", default=str(ROOT / "target" / "hostile"))
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--report", default=None)
    ap.add_argument("--only", default=None)
    ap.add_argument("--backend", default="cpu", help="backend of the run cases (cpu, or cuda on a GPU machine)")
    a = ap.parse_args()
    BIN = a.rtmpm or next((str(p) for p in [ROOT / "target/release/rtmpm", ROOT / "target/debug/rtmpm"] if p.exists()), None)
    if not BIN:
        sys.exit("build rtmpm first: cargo build --release")
    BIN = str(Path(BIN).resolve())
    work = Path(a.work)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    env = dict(os.environ, RTMPM_PROGRESS_SECONDS="1000000", NO_COLOR="1")
    env.pop("RUST_BACKTRACE", None)
    rows = []
    all_cases = [c for c in cases() if not a.only or a.only in c.name]
    for i, c in enumerate(all_cases):
        w = work / f"case{i:03d}"
        w.mkdir()
        try:
            if c.setup:
                c.setup(w)
        except Exception as e:  # a setup failure is a bug of this script, not of rtmpm
            rows.append((c.name, "setup-failed", 0, f"{e}"))
            print(f"{'setup-failed':9} {0:6.2f}s  {c.name}: {e}", flush=True)
            continue
        before = {k: tree_hash(w / k) for k in c.keep}
        args = [s.replace("{W}", str(w)) for s in c.args]
        if a.backend != "cpu" and c.gpu_valid:
            if args[0] != "check":
                rows.append((c.name, "not-run", 0, "a valid scene on this GPU (minutes of set-up)"))
                print(f"{'not-run':9} {0:6.2f}s  {c.name}: a valid scene on this GPU", flush=True)
                continue
            c.may_accept = True
        if a.backend != "cpu" and any(k in c.name for k in GPU_RUNS):
            c.may_accept = True
        if a.backend != "cpu" and "--threads" not in args:
            args = [a.backend if x == "cpu" and args[i - 1] == "--backend" else x for i, x in enumerate(args)]
        t = time.time()
        if c.runner:
            rc, text, timed_out, verdict = c.runner([BIN] + args, w, env, a.timeout)
            dt = time.time() - t
            verdict = verdict or judge(c, rc, text, timed_out, False)
            lines = [l for l in text.splitlines() if l.strip()]
            # An unclear live-view case names what went wrong (its first problem), not its first error.
            said = [l for l in lines if l.startswith("problem:")] if verdict == "unclear" else []
            first = (said or [next((l for l in lines if l.startswith("error")), lines[0] if lines else "")])[0][:160]
            rows.append((c.name, verdict, dt, first))
            print(f"{verdict:9} {dt:6.2f}s  {c.name}: {first}", flush=True)
            continue
        try:
            # No address-space limit with CUDA: the driver reserves more virtual memory than the
            # limit when it creates a context (CUDA_ERROR_OUT_OF_MEMORY before any allocation of ours).
            r = subprocess.run([BIN] + args, capture_output=True, stdin=subprocess.DEVNULL, timeout=a.timeout,
                               preexec_fn=limit if a.backend == "cpu" else None, env=env, cwd=w)
            rc, text, timed_out = r.returncode, (r.stderr + r.stdout).decode(errors="replace"), False
        except subprocess.TimeoutExpired as e:
            rc, text, timed_out = None, ((e.stderr or b"") + (e.stdout or b"")).decode(errors="replace"), True
        dt = time.time() - t
        for p in LONG:
            p.kill()
            p.wait()
        LONG.clear()
        lost = any(tree_hash(w / k) != h for k, h in before.items())
        verdict = judge(c, rc, text, timed_out, lost)
        lines = [l for l in text.splitlines() if l.strip()]
        first = next((l for l in lines if l.startswith("error")), lines[0] if lines else "")[:160]
        rows.append((c.name, verdict, dt, first))
        print(f"{verdict:9} {dt:6.2f}s  {c.name}: {first}", flush=True)
    tally = {}
    for _, v, _, _ in rows:
        tally[v] = tally.get(v, 0) + 1
    bad = sum(tally.get(k, 0) for k in ["crash", "hang", "lost", "unclear", "silent", "setup-failed"])
    summary = (f"{len(rows)} hostile inputs: {tally.get('clear', 0)} clear errors, "
               f"{tally.get('warned', 0)} warned, {tally.get('silent', 0)} silent, "
               f"{tally.get('accepted', 0)} accepted (valid), {tally.get('unclear', 0)} unclear, "
               f"{tally.get('crash', 0)} crashes, {tally.get('hang', 0)} hangs, {tally.get('lost', 0)} data lost"
               + (f", {tally['setup-failed']} setup failures" if "setup-failed" in tally else "")
               + (f", {tally['not-run']} valid on the GPU and not run" if "not-run" in tally else ""))
    print("\n" + summary)
    if a.report:
        with open(a.report, "w") as f:
            f.write(f"# Hostile-input corpus\n\n`{' '.join(sys.argv)}` with `{BIN}`\n\n{summary}\n\n")
            f.write("| case | outcome | s | first line |\n| --- | --- | --- | --- |\n")
            for n, v, dt, first in rows:
                f.write(f"| {n} | {v} | {dt:.2f} | {first.replace('|', '/')} |\n")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
