#!/usr/bin/env python3
"""Check every file format of an rtmpm run with independent readers (meshio; Python's gzip).

Usage: check_formats.py OUTDIR

OUTDIR is the output folder of `rtmpm run` of a scene writing every format (e.g.
scenes/splash_small.toml). Checks, for every frame:
  * frame_N.vtu (zlib-compressed appended data): meshio reads it; velocity (N x 3), material, id
    (0..N-1), J, and stress as a full 3x3 tensor (N x 9, symmetric) agree with frame_N.ply
    read by meshio;
  * frame_N.bgeo.gz is the gzip of frame_N.bgeo (Python's gzip), and starts with the classic
    "BgeoV" header and the point count of the PLY;
  * surface_N.obj, surface_N.ply (Blender's importers read these two), surface_N.vtu: meshio
    reads a triangle mesh with the same vertices in all three, normals of unit length, and
    surface.pvd lists the .vtu files.
The BGEO values themselves are compared with an independent reader in the Rust interop test
(splashsurf_lib). Exits non-zero with a message on the first failure. Requires meshio, numpy.
"""

import glob
import gzip
import os
import struct
import sys
import xml.etree.ElementTree as ET


def fail(msg):
    print(f"check_formats: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    if len(sys.argv) != 2:
        fail(__doc__)
    out = sys.argv[1]
    import meshio
    import numpy as np

    frames = sorted(glob.glob(os.path.join(out, "frame_*.ply")))
    if not frames:
        fail(f"no frame_*.ply in {out}")
    for ply_path in frames:
        stem = ply_path[: -len(".ply")]
        ply = meshio.read(ply_path)
        n = len(ply.points)
        vtu = meshio.read(stem + ".vtu")
        with open(stem + ".vtu", "rb") as f:
            body = f.read()
        if b"vtkZLibDataCompressor" not in body[:4096] or b"<AppendedData" not in body:
            fail(f"{stem}.vtu is not zlib-compressed appended data")
        if not np.array_equal(vtu.points.astype(np.float32), ply.points.astype(np.float32)):
            fail(f"{stem}.vtu: points differ from the PLY")
        pd = vtu.point_data
        v = np.stack([ply.point_data[c] for c in ("vx", "vy", "vz")], axis=1)
        if pd["velocity"].shape != (n, 3) or not np.array_equal(pd["velocity"], v):
            fail(f"{stem}.vtu: velocity differs from the PLY")
        if not np.array_equal(pd["material"], ply.point_data["material"]):
            fail(f"{stem}.vtu: material differs")
        if not np.array_equal(pd["id"], np.arange(n)):
            fail(f"{stem}.vtu: id is not 0..N-1")
        if not np.array_equal(pd["J"], ply.point_data["J"]):
            fail(f"{stem}.vtu: J differs")
        s = pd["stress"]
        if s.shape != (n, 9):
            fail(f"{stem}.vtu: stress has shape {s.shape}, expected ({n}, 9)")
        full = s.reshape(n, 3, 3)
        if not np.array_equal(full, full.transpose(0, 2, 1)):
            fail(f"{stem}.vtu: stress tensor is not symmetric")
        for (i, j), c in zip(((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)), ("sxx", "syy", "szz", "sxy", "syz", "sxz")):
            if not np.array_equal(full[:, i, j], ply.point_data[c]):
                fail(f"{stem}.vtu: stress[{i}][{j}] differs from the PLY's {c}")
        raw = open(stem + ".bgeo", "rb").read()
        if gzip.decompress(open(stem + ".bgeo.gz", "rb").read()) != raw:
            fail(f"{stem}.bgeo.gz is not the gzip of {stem}.bgeo")
        if raw[:5] != b"BgeoV" or struct.unpack(">ii", raw[5:13]) != (5, n):
            fail(f"{stem}.bgeo: header is not classic V5 with {n} points")
        print(f"ok {stem}: {n} particles in PLY, VTU (compressed, 9-component stress), BGEO, BGEO.gz")

    surfaces = sorted(glob.glob(os.path.join(out, "surface_*.vtu")))
    if len(surfaces) != len(frames):
        fail(f"{len(surfaces)} surface_*.vtu for {len(frames)} frames")
    for vtu_path in surfaces:
        stem = vtu_path[: -len(".vtu")]
        meshes = {ext: meshio.read(stem + ext) for ext in (".vtu", ".obj", ".ply")}
        ref = meshes[".vtu"]
        tri = [c for c in ref.cells if c.type == "triangle"]
        if not tri or len(tri[0].data) == 0:
            fail(f"{stem}.vtu: no triangles")
        ntri = len(tri[0].data)
        for ext, m in meshes.items():
            t = [c for c in m.cells if c.type == "triangle"]
            if not t or not np.array_equal(t[0].data, tri[0].data):
                fail(f"{stem}{ext}: triangles differ from the .vtu's")
            if not np.allclose(m.points, ref.points, rtol=0, atol=1e-6):
                fail(f"{stem}{ext}: vertices differ from the .vtu's")
        normals = ref.point_data["Normals"]
        if not np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4):
            fail(f"{stem}.vtu: normals are not unit vectors")
        print(f"ok {stem}: {len(ref.points)} vertices, {ntri} triangles in OBJ, PLY, VTU")
    root = ET.parse(os.path.join(out, "surface.pvd")).getroot()
    listed = [d.get("file") for d in root.findall("./Collection/DataSet")]
    if listed != [os.path.basename(p) for p in surfaces]:
        fail(f"surface.pvd lists {listed}")
    print(f"ok {out}/surface.pvd: {len(listed)} meshes")


if __name__ == "__main__":
    main()
