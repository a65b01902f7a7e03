"""The Lumen GI render engine (preview): G-buffer, SDF resources of the last bake, direct light.

`render()` runs, for the scene camera, the G-buffer pass (gbuffer.py: the evaluated meshes drawn
with gpu batches), uploads the bake's SDFs (resources.py) and runs the direct light pass
(direct_light.py: lights and sky with SDF cone-traced shadows). It writes
    Combined        albedo * direct + emission (world colour on the background), alpha 1
    Diffuse Direct  E / pi, the convention of Cycles' pass of that name (albedo excluded)
    Diffuse Color   the albedo: G-buffer base colour (Cycles' name for it)
    Normal          world normal
(Blender 5.0's own names, so the passes line up with Cycles' in the compositor and in EXRs),
hence Combined = Diffuse Color x Diffuse Direct + Emission as in Cycles (no indirect light yet).

Debug view: the scene custom property "lumen_preview_view" = "DEPTH" instead runs only the SDF
trace pass and writes hit depth as grey to Combined (near = bright, far = dark, miss = black).
It works headless: Blender gives a RenderEngine with bl_use_gpu_context a GPU context in
background mode too (Mesa llvmpipe).

The bake comes from the bake operator's memory (operators.bake_op.LAST_BAKES, by scene name)
or else from the scene's cache folder (scene.lumen.cache_dir, resolved like the operators do).
"""
from __future__ import annotations

import time

import bpy
import numpy as np

from . import sdf_trace
from .resources import SceneResources

# Extra passes: (name in the render result, channels, channel ids, type).
PASSES = (("Diffuse Direct", 3, "RGB", 'COLOR'), ("Diffuse Color", 3, "RGB", 'COLOR'),
          ("Normal", 3, "XYZ", 'VECTOR'))
VIEW_PROPERTY = "lumen_preview_view"

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


def view_projection(depsgraph, camera, width: int, height: int):
    """(view-projection numpy float64 4x4, camera world position, clip_end) for the render size."""
    render = depsgraph.scene.render
    cam = camera.evaluated_get(depsgraph)
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    view = cam.matrix_world.inverted()
    vp = np.array(proj, np.float64) @ np.array(view, np.float64)
    return vp, np.array(cam.matrix_world.translation, np.float64), float(cam.data.clip_end)


def camera_matrices(depsgraph, camera, width: int, height: int):
    """(inverse view-projection as numpy float64 4x4, clip_end) of `camera` for the render size."""
    vp, _, clip_end = view_projection(depsgraph, camera, width, height)
    return np.linalg.inv(vp), clip_end


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
    """Lumen GI preview engine: G-buffer + SDF direct light (or the SDF trace depth debug view).
    view_draw draws nothing yet."""

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
        layer = depsgraph.view_layer.name
        for name, channels, chan_id, _ in PASSES:
            self.add_pass(name, channels, chan_id, layer=layer)
        result = self.begin_result(0, 0, width, height, layer=layer)
        passes = {}
        try:
            if scene.get(VIEW_PROPERTY, "LIT") == "DEPTH":
                passes["Combined"] = self._trace(depsgraph, scene, width, height)
            else:
                passes = self._lit(depsgraph, scene, width, height)
        except Exception as exc:   # reported, never raised into Blender's render job
            import traceback
            self.report({'ERROR'}, f"Lumen GI: {exc}")
            LAST_RENDER["error"] = str(exc)
            LAST_RENDER["traceback"] = traceback.format_exc()
            passes = {"Combined": np.zeros((height, width, 4), np.float32)}
        rl = result.layers[0]
        written = []
        for name, rgba in passes.items():
            rp = rl.passes.find_by_name(name, "") if hasattr(rl.passes, "find_by_name") else None
            rp = rp or rl.passes.get(name)
            if rp is None:
                continue
            rp.rect = np.ascontiguousarray(rgba[..., :rp.channels], np.float32).reshape(
                -1, rp.channels)
            written.append(name)
        LAST_RENDER["passes_written"] = written
        self.end_result(result)

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", 'COLOR')
        for name, channels, chan_id, kind in PASSES:
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    def _lit(self, depsgraph, scene, width, height):
        from ..operators.extract import extract_scene
        from ..operators.lights import light_table, world_colour
        from . import direct_light, gbuffer

        if scene.camera is None:
            raise RuntimeError(f"scene {scene.name!r} has no camera")
        t0 = time.perf_counter()
        objects, warnings = extract_scene(depsgraph)
        lights = light_table(depsgraph)
        sky, sky_notes = world_colour(scene)
        t1 = time.perf_counter()
        vp, cam_pos, clip_end = view_projection(depsgraph, scene.camera, width, height)
        gbuf = gbuffer.render_gbuffer(objects, vp, width, height)
        t2 = time.perf_counter()
        bake, source = scene_bake(scene)
        resources = SceneResources.from_bake(bake)
        t3 = time.perf_counter()
        out = direct_light.shade(resources, gbuf, lights, sky, cam_pos, width, height)
        t4 = time.perf_counter()
        LAST_RENDER.update(
            view_proj=vp, cam_pos=cam_pos, width=width, height=height, source=source,
            lights=lights, sky=sky, notes=[w for w in warnings] + sky_notes,
            triangles=gbuf["triangles"], extract_seconds=t1 - t0, gbuffer_seconds=t2 - t1,
            resources_seconds=t3 - t2, direct_seconds=t4 - t3,
            direct_compile_seconds=out["compile_seconds"], shade_seconds=out["shade_seconds"],
            gpu_bytes=resources.stats(), position=gbuf["position"], normal=gbuf["normal"],
            albedo=gbuf["albedo"], emission=gbuf["emission"], direct=out["direct"],
            combined=out["combined"])
        return {"Combined": out["combined"], "Diffuse Direct": out["direct"],
                "Diffuse Color": gbuf["albedo"], "Normal": gbuf["normal"]}

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
