#!/usr/bin/env python3
"""Generate scenes/meshes/boat.obj: a small convex boat hull (0.24 m long, 0.1 m beam, 0.08 m
deep), centred at the origin, bow towards +x, deck up (+y), faces wound outward.

The hull is the solid {(x, y, z): (x, z) in s(y) P}: P a convex plan outline, pointed at the bow
(half-beam b (1 - (x/a)^2) for x > 0) and fuller at the stern (b (1 - (x/a)^4) for x < 0), and
s(y) a concave widening from the keel to the deck, sampled at a few heights. Scaled copies of a
convex polygon stacked with concave scales bound a convex solid (each side face is a planar
trapezoid), so `convex = true` applies. For `[[rigid_body]] shape = "mesh"`.
Usage: python3 scripts/gen_boat_mesh.py > scenes/meshes/boat.obj"""
import math

A, B, H = 0.12, 0.05, 0.04  # half-length, half-beam, half-depth (m)
M = 40                      # points around the outline
LEVELS = 6                  # heights from the keel (y = -H) to the deck (y = +H)


def half_beam(x):
    u = x / A
    return B * (1 - u * u) if x >= 0 else B * (1 - u ** 4)


outline = []
for i in range(M):
    th = 2 * math.pi * i / M
    x = A * math.cos(th)
    z = half_beam(x) * (1 if math.sin(th) >= 0 else -1)
    if i in (0, M // 2):
        z = 0.0
    outline.append((x, z))

verts = []
for k in range(LEVELS):
    t = k / (LEVELS - 1)
    y = -H + 2 * H * t
    s = 0.45 + 0.55 * math.sin(0.5 * math.pi * t)  # concave: narrower keel, full deck
    verts += [(s * x, y, s * z) for x, z in outline]
bottom = len(verts)
verts.append((0.0, -H, 0.0))
top = len(verts)
verts.append((0.0, H, 0.0))

faces = []
for k in range(LEVELS - 1):
    for i in range(M):
        a, b = k * M + i, k * M + (i + 1) % M
        c, d = a + M, b + M
        # The outline runs counter-clockwise seen from -y (x then z): outward is (b, a, c, d).
        faces += [(a, c, b), (b, c, d)]
for i in range(M):
    faces.append((bottom, i, (i + 1) % M))
    faces.append((top, (LEVELS - 1) * M + (i + 1) % M, (LEVELS - 1) * M + i))

print("# Convex boat hull for rtmpm (scripts/gen_boat_mesh.py): 0.24 x 0.08 x 0.1 m, bow +x")
for v in verts:
    print("v %.6f %.6f %.6f" % v)
for f in faces:
    print("f %d %d %d" % tuple(i + 1 for i in f))
