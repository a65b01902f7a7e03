"""Numpy twins of the global SDF clipmaps (no bpy, no gpu): layout and the CPU reference values.

A level of voxel size `v` and N^3 voxels starts at integer world cell `origin` =
floor(camera / v) - N // 2 (the camera's cell is the level's centre cell, snapped to the level's
own grid). World cell c has its centre at (c + 0.5) * v and lives in texel c mod N (toroidal), so
a scroll moves no texel that stays inside the level.
"""
from __future__ import annotations

import numpy as np

LEVELS = 4
BAND_VOXELS = 4.0


def level_voxel(base: float, level: int) -> float:
    return float(base) * (2 ** int(level))


def level_origin(camera, voxel: float, n: int) -> tuple:
    """First world cell (x, y, z) of a level of voxel size `voxel` and n^3 voxels around camera."""
    c = np.floor(np.asarray(camera, np.float64) / float(voxel)).astype(np.int64)
    return tuple(int(v) for v in c - n // 2)


def texel_cells(origin, n: int) -> np.ndarray:
    """int64 [n, n, n, 3] world cell (x, y, z) held by each texel, array order [z, y, x] as read back."""
    t = np.arange(n)
    o = np.asarray(origin, np.int64)
    cx, cy, cz = (o[i] + np.mod(t - o[i], n) for i in range(3))
    z, y, x = np.meshgrid(cz, cy, cx, indexing="ij")
    return np.stack([x, y, z], axis=-1)


def texel_centres(origin, n: int, voxel: float) -> np.ndarray:
    """float64 [n, n, n, 3] world centres of each texel's cell ([z, y, x] order)."""
    return (texel_cells(origin, n) + 0.5) * float(voxel)


def scene_sdf(meshes: dict, instances, points, mip: int = 0) -> np.ndarray:
    """World distance lower bound at world points: min over instances of MeshSDF.sample in the
    instance's local space times the smallest singular value of its 3x3, raised where positive
    to the distance to the mesh bounds (less half a voxel) and to their sphere (as sdf_visit)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    best = np.full(len(p), np.inf)
    for inst in instances:
        sdf = meshes[inst.mesh]
        mw = np.asarray(inst.matrix_world, np.float64)
        inv = np.linalg.inv(mw)
        sv = np.linalg.svd(mw[:3, :3], compute_uv=False)
        scale = float(sv.min())
        local = p @ inv[:3, :3].T + inv[:3, 3]
        d = sdf.sample(local, mip=mip) * scale
        h = sdf.mips[mip].voxel_size         # as packing.instance_row
        lo, hi = np.asarray(sdf.bounds_min) - 0.5 * h, np.asarray(sdf.bounds_max) + 0.5 * h
        centre = mw[:3, :3] @ ((lo + hi) / 2) + mw[:3, 3]
        radius = float(sv.max()) * float(np.linalg.norm(hi - lo)) / 2 * (1 + 1e-5) + 1e-6
        to_box = np.linalg.norm(np.maximum(np.maximum(sdf.bounds_min - local,
                                                      local - sdf.bounds_max), 0), axis=1)
        lb = np.maximum(np.linalg.norm(p - centre, axis=1) - radius, (to_box - 0.5 * h) * scale)
        best = np.minimum(best, np.where(lb > 0, np.maximum(d, lb), d))
    return best


def level_reference(meshes: dict, instances, origin, n: int, voxel: float,
                    band_voxels: float = BAND_VOXELS) -> tuple:
    """(stored values min(d, band) float64 [n, n, n] ([z, y, x]), raw d) of one level."""
    d = scene_sdf(meshes, instances, texel_centres(origin, n, voxel)).reshape(n, n, n)
    return np.minimum(d, band_voxels * voxel), d


def due_levels(frame: int, levels: int = LEVELS) -> list:
    """Levels whose refresh slot is this frame: level k every 2^k frames."""
    return [k for k in range(levels) if int(frame) % (1 << k) == 0]


def sample_levels(levels, origins, voxels, points, band_voxels: float = BAND_VOXELS) -> tuple:
    """Numpy twin of global_sdf_sample on read-back levels ([L][n, n, n], [z, y, x]):
    (d, level) per point; level -1 and d = 1e30 outside every level."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    n = levels[0].shape[0]
    best = np.full(len(p), 1e30)
    lev = np.full(len(p), -1, np.int64)
    open_ = np.ones(len(p), bool)                 # still looking at coarser levels
    for k, (vol, o, v) in enumerate(zip(levels, origins, voxels)):
        g = p / v - 0.5 - np.asarray(o, np.float64)
        inside = open_ & np.all((g >= 0) & (g <= n - 1), axis=1)
        if not inside.any():
            continue
        gi = g[inside]
        i0 = np.minimum(np.floor(gi).astype(np.int64), n - 2)
        f = gi - i0
        cell = np.asarray(o, np.int64) + i0
        a, b = np.mod(cell, n), np.mod(cell + 1, n)
        d = np.zeros(len(gi))
        for dx in (0, 1):
            wx = f[:, 0] if dx else 1 - f[:, 0]
            tx = b[:, 0] if dx else a[:, 0]
            for dy in (0, 1):
                wy = f[:, 1] if dy else 1 - f[:, 1]
                ty = b[:, 1] if dy else a[:, 1]
                for dz in (0, 1):
                    wz = f[:, 2] if dz else 1 - f[:, 2]
                    tz = b[:, 2] if dz else a[:, 2]
                    d += wx * wy * wz * np.asarray(vol, np.float64)[tz, ty, tx]
        idx = np.flatnonzero(inside)
        take = (lev[idx] < 0) | (d > best[idx])
        best[idx[take]], lev[idx[take]] = d[take], k
        open_[idx[d < 0.999 * band_voxels * v]] = False
    return best, lev


def merge_boxes(boxes) -> list:
    """Cell boxes [(first xyz, end xyz)] (end exclusive) merged where they overlap or touch: each
    group replaced by its bounding box. Why: while an object is dragged, a coarse level (updated
    every 2^k frames) gathers one changed box per redraw, nearly the same box each time, and
    refreshed them one by one (the refresh of a cell is a recomputation, so a larger box gives
    the same values)."""
    out = [(np.asarray(a, np.int64), np.asarray(b, np.int64)) for a, b in boxes]
    merged = True
    while merged and len(out) > 1:
        merged = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                (a0, b0), (a1, b1) = out[i], out[j]
                if np.all(a0 <= b1) and np.all(a1 <= b0):
                    out[i] = (np.minimum(a0, a1), np.maximum(b0, b1))
                    del out[j]
                    merged = True
                    break
            if merged:
                break
    return [(tuple(int(v) for v in a), tuple(int(v) for v in b)) for a, b in out]
