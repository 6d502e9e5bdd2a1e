#!/usr/bin/env python3
"""Check every file format of an rtmpm run with independent readers (meshio; Python's gzip).

Usage: check_formats.py OUTDIR
       check_formats.py --same-surfaces DIR_A DIR_B
       check_formats.py --bodies OUTDIR

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
  * frame_N.usda and surface_N.usda (when present): read by Pixar's USD library (usd-core):
    points, velocities, ids, material, J and the stress tensor equal the PLY's; the surface
    Mesh has the .vtu's vertices and triangles.
With --bodies, OUTDIR is a run of a scene with rigid bodies writing USD frames
(crates/rtmpm/tests/data/rigid_shapes.toml): in every frame_N.usda, each body of bodies.csv is an
Xform /bodies/<name> whose local-to-world transform, as usd-core computes it, is the pose of that
frame in bodies.csv (translation and rotation), holding a Cube, Sphere, Cylinder or Mesh prim
"shape"; the world bounding box of a Cube, Sphere or Cylinder is centred on the body's position.
The BGEO values themselves are compared with an independent reader in the Rust interop test
(splashsurf_lib). Exits non-zero with a message on the first failure. Requires meshio, numpy, and usd-core for
the .usda files.
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


def usd_stage(path):
    try:
        from pxr import Usd
    except ImportError:
        fail("usd-core is not installed (pip install usd-core)")
    stage = Usd.Stage.Open(path)
    if stage is None:
        fail(f"{path}: USD cannot open it")
    return stage


def check_usd_points(path, ply, np):
    from pxr import UsdGeom

    stage = usd_stage(path)
    if UsdGeom.GetStageUpAxis(stage) != "Y":
        fail(f"{path}: up axis is not Y")
    pts = UsdGeom.Points(stage.GetPrimAtPath("/particles"))
    if not pts:
        fail(f"{path}: no Points prim /particles")
    n = len(ply.points)
    p = np.array(pts.GetPointsAttr().Get(), dtype=np.float32)
    if not np.array_equal(p, ply.points.astype(np.float32)):
        fail(f"{path}: points differ from the PLY")
    v = np.array(pts.GetVelocitiesAttr().Get(), dtype=np.float32)
    pv = np.stack([ply.point_data[c] for c in ("vx", "vy", "vz")], axis=1)
    if not np.array_equal(v, pv):
        fail(f"{path}: velocities differ from the PLY")
    if list(pts.GetIdsAttr().Get()) != list(range(n)):
        fail(f"{path}: ids are not 0..N-1")
    pv_api = UsdGeom.PrimvarsAPI(pts)
    mat = np.array(pv_api.GetPrimvar("material").Get())
    if not np.array_equal(mat, ply.point_data["material"]):
        fail(f"{path}: material differs")
    if pv_api.GetPrimvar("material").GetInterpolation() != "vertex":
        fail(f"{path}: material is not a vertex primvar")
    if not np.array_equal(np.array(pv_api.GetPrimvar("J").Get(), dtype=np.float32), ply.point_data["J"]):
        fail(f"{path}: J differs")
    st = np.array(pv_api.GetPrimvar("stress").Get())
    if st.shape != (n, 3, 3):
        fail(f"{path}: stress has shape {st.shape}")
    for (i, j), c in zip(((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)), ("sxx", "syy", "szz", "sxy", "syz", "sxz")):
        if not np.array_equal(st[:, i, j].astype(np.float32), ply.point_data[c]) or not np.array_equal(st[:, j, i].astype(np.float32), ply.point_data[c]):
            fail(f"{path}: stress[{i}][{j}] differs from the PLY's {c}")


def check_usd_mesh(path, ref, triangles, np):
    from pxr import UsdGeom

    stage = usd_stage(path)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/surface"))
    if not mesh:
        fail(f"{path}: no Mesh prim /surface")
    p = np.array(mesh.GetPointsAttr().Get(), dtype=np.float32)
    if not np.array_equal(p, ref.points.astype(np.float32)):
        fail(f"{path}: vertices differ from the .vtu's")
    counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    if not (counts == 3).all() or not np.array_equal(idx.reshape(-1, 3), triangles):
        fail(f"{path}: faces differ from the .vtu's triangles")
    if len(mesh.GetNormalsAttr().Get()) != len(p):
        fail(f"{path}: not one normal per vertex")


def same_surfaces(a, b):
    """The surface_N.obj of two folders agree: triangle counts within 0.5 %, bounding boxes
    within 1e-5 m, enclosed volumes within 0.1 %."""
    import meshio
    import numpy as np

    files = sorted(glob.glob(os.path.join(a, "surface_*.obj")))
    if not files:
        fail(f"no surface_*.obj in {a}")
    for fa in files:
        fb = os.path.join(b, os.path.basename(fa))
        ma, mb = meshio.read(fa), meshio.read(fb)
        ta = [c.data for c in ma.cells if c.type == "triangle"][0]
        tb = [c.data for c in mb.cells if c.type == "triangle"][0]
        if abs(len(ta) - len(tb)) > 0.005 * len(ta):
            fail(f"{fb}: {len(tb)} triangles, {fa}: {len(ta)}")
        for m, name in ((ma, fa), (mb, fb)):
            if not np.isfinite(m.points).all():
                fail(f"{name}: non-finite vertices")
        if not np.allclose(ma.points.min(0), mb.points.min(0), atol=1e-5) or not np.allclose(ma.points.max(0), mb.points.max(0), atol=1e-5):
            fail(f"{fb}: bounding box differs from {fa}'s")

        def volume(m, t):
            p = m.points[t]
            return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0

        va, vb = volume(ma, ta), volume(mb, tb)
        if not va > 0 or abs(va - vb) > 1e-3 * va:
            fail(f"{fb}: encloses {vb} m^3, {fa}: {va} m^3")
        print(f"ok {fb}: the same surface as {fa} ({len(tb)} triangles, {vb:.6g} m^3)")


def prim_name(name, fallback, used):
    """The USD writer's prim name for a body (rtmpm_io::usd::prim_name)."""
    n = "".join(c if c.isascii() and c.isalnum() else "_" for c in name)
    if n[:1].isdigit():
        n = "_" + n
    if not n or n in used:
        n = fallback
    used.append(n)
    return n


def check_bodies(out):
    import csv

    import numpy as np
    from pxr import Usd, UsdGeom

    rows = list(csv.DictReader(open(os.path.join(out, "bodies.csv"))))
    frames = sorted(glob.glob(os.path.join(out, "frame_*.usda")))
    if not frames or not rows:
        fail(f"{out}: no frame_*.usda or no rows in bodies.csv")
    checked = 0
    for path in frames:
        frame = int(os.path.basename(path)[len("frame_") : -len(".usda")])
        stage = usd_stage(path)
        cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
        used = []
        for i, r in enumerate(x for x in rows if int(x["frame"]) == frame):
            name = prim_name(r["body"], f"body_{i}", used)
            prim = stage.GetPrimAtPath(f"/bodies/{name}")
            if not prim:
                fail(f"{path}: no prim /bodies/{name} for body {r['body']!r}")
            m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
            pos = np.array([float(r[k]) for k in "xyz"])
            if not np.allclose(np.array(m.ExtractTranslation()), pos, rtol=0, atol=1e-6):
                fail(f"{path}: /bodies/{name} is at {m.ExtractTranslation()}, bodies.csv says {pos}")
            x, y, z, w = (float(r[k]) for k in ("qx", "qy", "qz", "qw"))
            rot = np.array(
                [
                    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                ]
            )
            # USD multiplies row vectors (p' = p M): its rotation block is the transpose.
            got = np.array(m.ExtractRotationMatrix())
            if not np.allclose(got, rot.T, rtol=0, atol=1e-5):
                fail(f"{path}: /bodies/{name} rotation {got.tolist()} is not bodies.csv's {rot.T.tolist()}")
            shape = prim.GetChild("shape")
            kind = shape.GetTypeName() if shape else None
            if kind not in ("Cube", "Sphere", "Cylinder", "Mesh"):
                fail(f"{path}: /bodies/{name}/shape is {kind}")
            if kind != "Mesh":
                centre = np.array(cache.ComputeWorldBound(shape).ComputeAlignedRange().GetMidpoint())
                if not np.allclose(centre, pos, rtol=0, atol=1e-5):
                    fail(f"{path}: /bodies/{name}/shape is centred on {centre}, not {pos}")
            checked += 1
    print(f"ok {out}: {checked} body poses in {len(frames)} USD frames match bodies.csv")


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--same-surfaces":
        same_surfaces(sys.argv[2], sys.argv[3])
        return
    if len(sys.argv) == 3 and sys.argv[1] == "--bodies":
        check_bodies(sys.argv[2])
        return
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
        if os.path.exists(stem + ".usda"):
            check_usd_points(stem + ".usda", ply, np)
        print(f"ok {stem}: {n} particles in PLY, VTU (compressed, 9-component stress), BGEO, BGEO.gz, USD")

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
        if os.path.exists(stem + ".usda"):
            check_usd_mesh(stem + ".usda", ref, tri[0].data, np)
        normals = ref.point_data["Normals"]
        if not np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4):
            fail(f"{stem}.vtu: normals are not unit vectors")
        usd = ", USD" if os.path.exists(stem + ".usda") else ""
        print(f"ok {stem}: {len(ref.points)} vertices, {ntri} triangles in OBJ, PLY, VTU{usd}")
    root = ET.parse(os.path.join(out, "surface.pvd")).getroot()
    listed = [d.get("file") for d in root.findall("./Collection/DataSet")]
    if listed != [os.path.basename(p) for p in surfaces]:
        fail(f"surface.pvd lists {listed}")
    print(f"ok {out}/surface.pvd: {len(listed)} meshes")


if __name__ == "__main__":
    main()
