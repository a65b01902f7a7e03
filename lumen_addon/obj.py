"""Minimal Wavefront OBJ reader (positions and faces only) for tests, benchmarks and scripts."""
from __future__ import annotations

import numpy as np


def load_obj(path) -> tuple:
    """Return (vertices float64 (V,3), triangles int64 (T,3)); polygons are fanned, 1-based or
    negative indices handled, texture/normal indices ignored."""
    verts, faces = [], []
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append(line.split()[1:4])
            elif line.startswith("f "):
                faces.append([int(tok.split("/")[0]) for tok in line.split()[1:]])
    v = np.array(verts, dtype=np.float64).reshape(-1, 3)
    tris = []
    for n in sorted({len(f) for f in faces}):
        poly = np.array([f for f in faces if len(f) == n], dtype=np.int64)
        poly = np.where(poly < 0, poly + len(v), poly - 1)
        for k in range(1, n - 1):  # fan: one column slice per corner, not per face
            tris.append(poly[:, [0, k, k + 1]])
    t = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    return v, t
