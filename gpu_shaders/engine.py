"""The Lumen GI render engine (preview): traces the scene's last bake with the GPU SDF pass.

`render()` runs the trace pass for the scene camera and writes the Combined pass: hit depth as
grey (near = bright, far = dark, miss = black, alpha 1). It works headless: Blender gives a
RenderEngine with bl_use_gpu_context a GPU context in background mode too (Mesa llvmpipe).

The bake comes from the bake operator's memory (operators.bake_op.LAST_BAKES, by scene name)
or else from the scene's cache folder (scene.lumen.cache_dir, resolved like the operators do).
"""
from __future__ import annotations

import time

import bpy
import numpy as np

from . import sdf_trace
from .resources import SceneResources

# What the last render did (read by tests and scripts): trace output, camera, timings, memory.
LAST_RENDER = {}


def scene_bake(scene):
    """(bake, source) for the scene: the operator's bake in memory, else the cache folder."""
    from ..operators import bake_op
    from ..lumen_addon.cache import CacheError, read_cache

    bake = bake_op.LAST_BAKES.get(scene.name)
    if bake is not None:
        return bake, "memory"
    folder = bake_op.resolve_folder(scene.lumen.cache_dir)
    try:
        return read_cache(folder), str(folder)
    except CacheError as exc:
        raise RuntimeError(f"no Lumen bake for scene {scene.name!r}: {exc}") from exc


def camera_matrices(depsgraph, camera, width: int, height: int):
    """(inverse view-projection as numpy float64 4x4, clip_end) of `camera` for the render size."""
    render = depsgraph.scene.render
    cam = camera.evaluated_get(depsgraph)
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    view = cam.matrix_world.inverted()
    vp = np.array(proj, np.float64) @ np.array(view, np.float64)
    return np.linalg.inv(vp), float(cam.data.clip_end)


def depth_grey(hit: np.ndarray) -> np.ndarray:
    """RGBA float [h, w, 4]: grey from 1 (nearest hit) to 0.2 (farthest), black on a miss."""
    rgba = np.zeros(hit.shape + (4,), np.float32)
    rgba[..., 3] = 1.0
    mask = hit >= 0
    if mask.any():
        lo, hi = float(hit[mask].min()), float(hit[mask].max())
        g = 1.0 - 0.8 * (hit - lo) / max(hi - lo, 1e-9)
        rgba[..., :3] = np.where(mask, g, 0.0)[..., None]
    return rgba


class LumenGIRenderEngine(bpy.types.RenderEngine):
    """Lumen GI preview engine. So far one pass: SDF sphere tracing of the camera rays, shown as
    depth. view_draw draws nothing: viewport drawing arrives with the lighting passes."""

    bl_idname = "LUMEN_GI"
    bl_label = "Lumen GI"
    bl_use_gpu_context = True
    bl_use_preview = False

    def render(self, depsgraph):
        scene = depsgraph.scene
        scale = scene.render.resolution_percentage / 100.0
        width = max(1, int(scene.render.resolution_x * scale))
        height = max(1, int(scene.render.resolution_y * scale))
        LAST_RENDER.clear()
        result = self.begin_result(0, 0, width, height)
        try:
            rgba = self._trace(depsgraph, scene, width, height)
        except Exception as exc:   # reported, never raised into Blender's render job
            self.report({'ERROR'}, f"Lumen GI: {exc}")
            LAST_RENDER["error"] = str(exc)
            rgba = np.zeros((height, width, 4), np.float32)
        result.layers[0].passes["Combined"].rect = rgba.reshape(-1, 4)
        self.end_result(result)

    def _trace(self, depsgraph, scene, width, height):
        if scene.camera is None:
            raise RuntimeError(f"scene {scene.name!r} has no camera")
        t0 = time.perf_counter()
        bake, source = scene_bake(scene)
        t1 = time.perf_counter()
        resources = SceneResources.from_bake(bake)
        inv_vp, clip_end = camera_matrices(depsgraph, scene.camera, width, height)
        out = sdf_trace.trace(resources, inv_vp, width, height, t_max=clip_end)
        LAST_RENDER.update(out, inv_view_proj=inv_vp, t_max=clip_end, width=width, height=height,
                           source=source, load_seconds=t1 - t0,
                           pack_upload_seconds=time.perf_counter() - t1 - out["compile_seconds"]
                           - out["trace_seconds"], upload_seconds=resources.upload_seconds,
                           gpu_bytes=resources.stats(), bricks=resources.packed.bricks,
                           atlas_size=list(resources.packed.atlas_size))
        return depth_grey(out["hit"])

    def view_update(self, context, depsgraph):
        pass

    def view_draw(self, context, depsgraph):
        pass


def register():
    bpy.utils.register_class(LumenGIRenderEngine)


def unregister():
    bpy.utils.unregister_class(LumenGIRenderEngine)
