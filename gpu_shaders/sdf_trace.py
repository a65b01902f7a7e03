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
from .resources import SceneResources, glsl

GROUP = 8
DEFAULT_MAX_STEPS = 512
_SHADER = {}


def trace_shader():
    """The compiled trace shader (compiled once per process)."""
    if "trace" not in _SHADER:
        info = compute.new_info((GROUP, GROUP, 1))
        SceneResources.declare(info, 0)
        info.image(0, 'RG32F', 'FLOAT_2D', 'trace_out', qualifiers={'WRITE'})
        info.push_constant('MAT4', 'inv_view_proj')
        info.push_constant('FLOAT', 't_max')
        info.push_constant('INT', 'max_steps')
        _SHADER["trace"] = compute.create(
            info, glsl("sdf_trace.comp.glsl"))
    return _SHADER["trace"]


def trace(resources: SceneResources, inv_view_proj, width: int, height: int, t_max: float,
          max_steps: int = DEFAULT_MAX_STEPS) -> dict:
    """Run the pass; returns {'hit': float32 [h, w] (-1 miss), 'steps': int32 [h, w], 'seconds'}."""
    import mathutils

    t0 = time.perf_counter()
    shader = trace_shader()
    t1 = time.perf_counter()
    out = gpu.types.GPUTexture((width, height), format='RG32F')
    resources.bind(shader)
    shader.image('trace_out', out)
    shader.uniform_float('inv_view_proj', mathutils.Matrix(np.asarray(inv_view_proj, np.float64).tolist()))
    shader.uniform_float('t_max', float(t_max))
    shader.uniform_int('max_steps', int(max_steps))
    compute.run(shader, -(-width // GROUP), -(-height // GROUP), 1)
    data = compute.read(out)
    t2 = time.perf_counter()
    return {"hit": data[..., 0].copy(), "steps": data[..., 1].astype(np.int32),
            "compile_seconds": t1 - t0, "trace_seconds": t2 - t1,
            "bytes_output": width * height * 8}
