#!/usr/bin/env python3
"""Write a binary STL height field of about N triangles (75 x 75 mm, smooth
bumps) for the raster scaling runs:  gen_terrain_stl.py N OUT.stl"""
import sys

import numpy as np

n_tri = int(sys.argv[1])
k = max(2, int((n_tri / 2) ** 0.5))
x = np.linspace(-37.5, 37.5, k + 1)
X, Y = np.meshgrid(x, x, indexing="ij")
Z = 10 + 4 * np.sin(X / 7) * np.cos(Y / 9) + 2 * np.sin((X + Y) / 3.3)
P = np.stack([X, Y, Z], axis=-1).astype(np.float32)
a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
t1 = np.stack([a, b, c], axis=2).reshape(-1, 3, 3)
t2 = np.stack([a, c, d], axis=2).reshape(-1, 3, 3)
tris = np.concatenate([t1, t2])
rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
rec["v"] = tris
with open(sys.argv[2], "wb") as f:
    f.write(b"interpd generated terrain".ljust(80, b" "))
    f.write(np.uint32(len(tris)).tobytes())
    f.write(rec.tobytes())
print(len(tris))
