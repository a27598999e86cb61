#!/usr/bin/env python3
"""Make the OpenCAMLib fixture of `planner/tests/raster.rs`.

Writes a small mesh (a jittered, creased height field with a steep step and
open borders: faces, convex and concave edges, vertices and boundary edges
all touch the cutter) as ASCII STL, then OpenCAMLib's drop-cutter heights for
a ball, a flat and a bull cutter along the passes the planner will place on
it, as JSON. The test reads both with no Python.

    python3 -m venv out/venv && out/venv/bin/pip install opencamlib==2023.1.11 numpy
    out/venv/bin/python scripts/ocl_fixture.py planner/tests/data

Coordinates are rounded to f32 before they are written (as numpy's shortest
f32 text, which parses back to the same f32) and before OpenCAMLib sees them, so OpenCAMLib
and the planner (which reads STL as f32) work on identical triangles.
"""

import json
import os
import sys

import numpy as np
import opencamlib as ocl

# Mesh: CELLS x CELLS grid over SIZE x SIZE mm (2 triangles per cell).
CELLS = 12
SIZE = 16.0
SEED = 5
# Passes: the planner's, y = ymin + k * STEPOVER; OCL samples every SAMPLE mm
# from R beyond the mesh on either side.
STEPOVER = 2.5
SAMPLE = 0.25
TOOLS = ["ball:6", "flat:6", "bull:6:1"]
# OCL's start height below the part: points left there did not touch.
BELOW = 100.0
LENGTH = 50.0


def height(x, y):
    # Smooth bumps, a crease along x = y (convex), a valley along x = -y
    # (concave), and a steep 2.5 mm step near x = 4.
    z = 3.0 + 1.2 * np.sin(x / 2.3) * np.cos(y / 3.1)
    z -= 0.35 * np.abs(x - y)
    z += 0.25 * np.abs(x + y)
    z += 2.5 / (1.0 + np.exp(-(x - 4.0) * 8.0))
    return z


def mesh():
    rng = np.random.RandomState(SEED)
    g = np.linspace(-SIZE / 2, SIZE / 2, CELLS + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")
    h = SIZE / CELLS
    inner = np.zeros_like(X, dtype=bool)
    inner[1:-1, 1:-1] = True
    X = X + np.where(inner, rng.uniform(-0.3, 0.3, X.shape) * h, 0.0)
    Y = Y + np.where(inner, rng.uniform(-0.3, 0.3, Y.shape) * h, 0.0)
    P = np.stack([X, Y, height(X, Y)], axis=-1).astype(np.float32)
    tris = []
    for i in range(CELLS):
        for j in range(CELLS):
            a, b, c, d = P[i, j], P[i + 1, j], P[i + 1, j + 1], P[i, j + 1]
            # Alternate the diagonal so both kinds of edge occur.
            if (i + j) % 2 == 0:
                tris += [(a, b, c), (a, c, d)]
            else:
                tris += [(a, b, d), (b, c, d)]
    return tris


def write_stl(path, tris):
    with open(path, "w") as f:
        f.write("solid ocl_fixture\n")
        for t in tris:
            f.write(" facet normal 0 0 0\n  outer loop\n")
            for v in t:
                f.write("   vertex %s %s %s\n" % tuple(str(np.float32(c)) for c in v))
            f.write("  endloop\n endfacet\n")
        f.write("endsolid ocl_fixture\n")


def cutter(tool):
    parts = tool.split(":")
    d = float(parts[1])
    if parts[0] == "ball":
        return ocl.BallCutter(d, LENGTH)
    if parts[0] == "flat":
        return ocl.CylCutter(d, LENGTH)
    return ocl.BullCutter(d, float(parts[2]), LENGTH)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "planner/tests/data"
    os.makedirs(out, exist_ok=True)
    tris = mesh()
    write_stl(os.path.join(out, "ocl_fixture.stl"), tris)
    pts = np.array([[float(c) for c in v] for t in tris for v in t])
    x0, y0, zmin = pts[:, 0].min(), pts[:, 1].min(), pts[:, 2].min()
    x1, y1 = pts[:, 0].max(), pts[:, 1].max()
    surf = ocl.STLSurf()
    for t in tris:
        surf.addTriangle(ocl.Triangle(*[ocl.Point(*map(float, v)) for v in t]))
    npass = int(np.floor((y1 - y0) / STEPOVER)) + 1
    doc = {
        "comment": "OpenCAMLib drop-cutter heights on ocl_fixture.stl; made by scripts/ocl_fixture.py",
        "ocl_version": ocl.version(),
        "stepover": STEPOVER,
        "sample": SAMPLE,
        "below": zmin - BELOW,
        "tools": {},
    }
    for tool in TOOLS:
        # Held here: the BatchDropCutter keeps only a pointer to it.
        cut = cutter(tool)
        r = float(tool.split(":")[1]) / 2
        nx = int(round((x1 - x0 + 2 * r) / SAMPLE)) + 1
        passes = []
        for k in range(npass):
            y = y0 + k * STEPOVER
            bdc = ocl.BatchDropCutter()
            bdc.setSTL(surf)
            bdc.setCutter(cut)
            bdc.setThreads(1)
            for i in range(nx):
                bdc.appendPoint(ocl.CLPoint(x0 - r + i * SAMPLE, y, zmin - BELOW))
            bdc.run()
            zs = [p.z for p in bdc.getCLPoints()]
            # Untouched points (still at the start height) become null.
            passes.append({
                "pass": k,
                "y": y,
                "x0": x0 - r,
                "z": [None if z <= zmin - BELOW + 1e-6 else round(z, 9) for z in zs],
            })
        doc["tools"][tool] = passes
    with open(os.path.join(out, "ocl_fixture.json"), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
        f.write("\n")
    n = sum(len(p["z"]) for ps in doc["tools"].values() for p in ps)
    print(f"{len(tris)} triangles, {npass} passes, {n} OCL points")


if __name__ == "__main__":
    main()
