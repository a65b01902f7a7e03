"""The SDF trace pass: one sphere-traced ray per pixel through the scene (glsl/sdf_trace.comp.glsl).

Needs a GPU context (RenderEngine.render with bl_use_gpu_context). The ray of pixel (x, y) is
`reference.camera_rays`; its numpy twin is what tests compare `MeshSDF.sphere_trace` against.
"""
from __future__ import annotations

import time

import gpu
import numpy as np

from . import compute
from .reference import camera_rays  # noqa: F401  (the numpy twin of the shader's rays)
from .resources import SceneResources

GROUP = 8
DEFAULT_MAX_STEPS = 512
TRACE = compute.Pass("sdf_trace", images=(("trace_out", 'RG32F'),),
                     push=(('MAT4', 'inv_view_proj'), ('FLOAT', 't_max'), ('INT', 'max_steps')))


def trace(resources: SceneResources, inv_view_proj, width: int, height: int, t_max: float,
          max_steps: int = DEFAULT_MAX_STEPS) -> dict:
    """Run the pass; returns {'hit': float32 [h, w] (-1 miss), 'steps': int32 [h, w], 'seconds'}."""
    t0 = time.perf_counter()
    TRACE.shader                          # compiled once per process
    t1 = time.perf_counter()
    out = gpu.types.GPUTexture((width, height), format='RG32F')
    TRACE.run((width, height), scene=resources, trace_out=out, inv_view_proj=inv_view_proj,
              t_max=float(t_max), max_steps=int(max_steps))
    data = compute.read(out)
    t2 = time.perf_counter()
    return {"hit": data[..., 0].copy(), "steps": data[..., 1].astype(np.int32),
            "compile_seconds": t1 - t0, "trace_seconds": t2 - t1,
            "bytes_output": width * height * 8}
