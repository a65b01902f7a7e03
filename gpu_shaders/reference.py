"""Numpy twins of the GPU passes (no bpy, no gpu): what the shaders are tested against.

`camera_rays` builds the rays exactly as glsl/camera_lib.glsl does; `trace_scene` traces them
with the CPU reference `MeshSDF.sphere_trace`, each instance in its own local space, and keeps
the nearest hit over instances.
"""
from __future__ import annotations

import numpy as np


def camera_rays(inv_view_proj, width: int, height: int):
    """World ray origins and unit directions (float64, [height, width, 3]) of every pixel: from
    the unprojected NDC point (u, v, -1) towards (u, v, 1), u/v at pixel centres, row 0 at v=-1."""
    m = np.asarray(inv_view_proj, np.float64)
    u = (np.arange(width) + 0.5) / width * 2 - 1
    v = (np.arange(height) + 0.5) / height * 2 - 1
    U, V = np.meshgrid(u, v)            # [height, width]

    def unproject(z):
        p = np.stack([U, V, np.full_like(U, z), np.ones_like(U)], axis=-1) @ m.T
        return p[..., :3] / p[..., 3:]

    o = unproject(-1.0)
    d = unproject(1.0) - o
    return o, d / np.linalg.norm(d, axis=-1, keepdims=True)


def trace_scene(meshes: dict, instances, origins, directions, t_max: float, mip: int = 0,
                max_steps: int = 512) -> np.ndarray:
    """World hit distance of each ray (inf on a miss): min over instances of MeshSDF.sphere_trace
    of the ray carried into the instance's local space (distances scaled back to world)."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    best = np.full(len(o), np.inf)
    for inst in instances:
        sdf = meshes[inst.mesh]
        inv = np.linalg.inv(np.asarray(inst.matrix_world, np.float64))
        lo = o @ inv[:3, :3].T + inv[:3, 3]
        ld = d @ inv[:3, :3].T
        n = np.linalg.norm(ld, axis=1)
        t = sdf.sphere_trace(lo, ld / n[:, None], float(t_max) * float(n.max()), mip=mip,
                             max_steps=max_steps) / n
        best = np.minimum(best, t)
    return best
