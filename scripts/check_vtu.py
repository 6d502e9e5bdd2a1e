#!/usr/bin/env python3
"""Check rtmpm .vtu frames (and .pvd collections) with meshio.

Usage: check_vtu.py [--points N] FILE [FILE ...]

Each FILE is a .vtu frame or a .pvd collection (every frame it lists is checked, paths
relative to the .pvd's folder). For every frame: meshio must read it, the arrays `velocity`
(N x 3) and `material` (N) must exist with one entry per point, and, with --points, the number
of points must be N. Exits non-zero with a message on the first failure.

Requires meshio (`pip install meshio`).
"""

import argparse
import os
import sys
import xml.etree.ElementTree as ET


def fail(msg):
    print(f"check_vtu: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def check_vtu(path, expected_points):
    import meshio

    try:
        mesh = meshio.read(path)
    except Exception as e:  # meshio raises various types
        fail(f"{path}: meshio cannot read it: {e}")
    n = len(mesh.points)
    if expected_points is not None and n != expected_points:
        fail(f"{path}: {n} points, expected {expected_points}")
    if mesh.points.shape[1:] != (3,):
        fail(f"{path}: points have shape {mesh.points.shape}, expected ({n}, 3)")
    for name, comps in (("velocity", 3), ("material", 1)):
        if name not in mesh.point_data:
            fail(f"{path}: no point array '{name}' (have {sorted(mesh.point_data)})")
        a = mesh.point_data[name]
        if len(a) != n:
            fail(f"{path}: '{name}' has {len(a)} entries, expected {n}")
        shape_comps = 1 if a.ndim == 1 else a.shape[1]
        if shape_comps != comps:
            fail(f"{path}: '{name}' has {shape_comps} components, expected {comps}")
    ncells = sum(len(c.data) for c in mesh.cells)
    if ncells != n or any(c.type != "vertex" for c in mesh.cells):
        fail(f"{path}: expected {n} vertex cells, got {[(c.type, len(c.data)) for c in mesh.cells]}")
    print(f"ok {path}: {n} points, point arrays {sorted(mesh.point_data)}")
    return n


def check_pvd(path, expected_points):
    try:
        root = ET.parse(path).getroot()
    except Exception as e:
        fail(f"{path}: not valid XML: {e}")
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        fail(f"{path}: not a VTK Collection file")
    datasets = root.findall("./Collection/DataSet")
    if not datasets:
        fail(f"{path}: collection lists no DataSet")
    times = []
    base = os.path.dirname(path)
    for ds in datasets:
        f = ds.get("file")
        t = ds.get("timestep")
        if f is None or t is None:
            fail(f"{path}: DataSet without file/timestep: {ds.attrib}")
        try:
            times.append(float(t))
        except ValueError:
            fail(f"{path}: bad timestep {t!r}")
        frame = os.path.join(base, f)
        if not os.path.exists(frame):
            fail(f"{path}: listed frame {frame} does not exist")
        check_vtu(frame, expected_points)
    if times != sorted(times):
        fail(f"{path}: timesteps are not increasing: {times}")
    print(f"ok {path}: {len(datasets)} frames, t = {times[0]} .. {times[-1]}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=None, help="expected number of points")
    ap.add_argument("files", nargs="+")
    args = ap.parse_args()
    try:
        import meshio  # noqa: F401
    except ImportError:
        fail("meshio is not installed (pip install meshio)")
    for f in args.files:
        if not os.path.exists(f):
            fail(f"{f}: no such file")
        if f.endswith(".pvd"):
            check_pvd(f, args.points)
        else:
            check_vtu(f, args.points)


if __name__ == "__main__":
    main()
