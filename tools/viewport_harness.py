"""Call a RenderEngine's `view_draw` headless, as the 3D viewport would (tests and benchmarks).

Blender gives a RenderEngine with `bl_use_gpu_context` a GPU context inside `render()` even in
background mode, but never calls `view_draw` without a window. So `run()` registers a subclass of
the engine whose `render()` binds a GPUOffScreen of the region's size, sets the region's pixel
projection (what Blender does before a viewport's `view_draw`) and calls the engine's own
`view_draw` with a duck-typed context: region (width, height), region_data (perspective_matrix,
view_matrix of the scene camera), space_data (clip_end) and preferences. After `on_redraw`
edits the scene, the depsgraph is re-evaluated and the engine's `view_update` sees its updates
(from a depsgraph_update_post handler, while depsgraph.updates still lists them), as Blender
calls view_update before the next view_draw. The depsgraph is render()'s, a RENDER one: what
it evaluates follows render settings (objects hidden only in the viewport are drawn, modifiers
at render levels), unlike a real viewport's.

    result = run(scene, LumenGIRenderEngine, 640, 360, redraws=4, on_redraw=callback)
    result["drawn"]     float32 [h, w, 4]: the offscreen after the last redraw (display space)
    result["seconds"]   wall time of each view_draw call
    result["cpu_seconds"] CPU time of each (time.process_time: llvmpipe's threads are this
                        process's), which other jobs on a shared host move less than the wall
    result["after"]     what on_redraw(i) returned after each redraw (edits it makes reach the
                        next redraw: the depsgraph is re-evaluated, as the viewport's is)
"""
from __future__ import annotations

import time
import types

_JOB: dict = {}
_CLASSES: dict = {}


def _engine_class(base):
    """A RenderEngine with `base`'s methods and a render() that runs the harness. Not a subclass
    of `base`: registering a subclass of a registered engine makes Blender lose the Python class
    of the original (measured: "unable to get Python class for RNA struct 'LUMEN_GI'", and F12
    of LUMEN_GI then ran no render() at all)."""
    if base not in _CLASSES:
        import bpy

        def render(self, depsgraph):
            try:
                _JOB["result"] = _draw(self, depsgraph, **_JOB["args"])
            except Exception:   # reported to the caller, never raised into Blender
                import traceback
                _JOB["error"] = traceback.format_exc()

        members = {k: v for k, v in vars(base).items()
                   if not k.startswith("__") and k not in ("bl_rna", "render")}
        members.update(bl_idname=base.bl_idname + "_VIEW_DRAW",
                       bl_label=base.bl_label + " (view_draw harness)", render=render)
        cls = type("ViewDraw", (bpy.types.RenderEngine,), members)
        bpy.utils.register_class(cls)
        _CLASSES[base] = cls
    return _CLASSES[base]


def _draw(engine, depsgraph, width, height, redraws, on_redraw, until=None):
    import bpy
    import gpu
    import mathutils
    import numpy as np

    scene = depsgraph.scene
    cam = scene.camera.evaluated_get(depsgraph)
    view = cam.matrix_world.inverted()
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height)
    ctx = types.SimpleNamespace(
        region=types.SimpleNamespace(width=width, height=height),
        region_data=types.SimpleNamespace(perspective_matrix=proj @ view, view_matrix=view),
        space_data=types.SimpleNamespace(clip_end=cam.data.clip_end),
        preferences=bpy.context.preferences)
    pixels = mathutils.Matrix(((2.0 / width, 0.0, 0.0, -1.0), (0.0, 2.0 / height, 0.0, -1.0),
                               (0.0, 0.0, -1.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
    off = gpu.types.GPUOffScreen(width, height, format='RGBA16F')
    seconds, cpu, after = [], [], []

    def updated(_scene, dg):
        if dg.as_pointer() == depsgraph.as_pointer():
            engine.view_update(ctx, dg)

    bpy.app.handlers.depsgraph_update_post.append(updated)
    try:
        depsgraph.update()            # Blender calls view_update before the first view_draw too
        for i in range(redraws):
            with off.bind(), gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 0.0))
                gpu.matrix.load_identity()
                gpu.matrix.load_projection_matrix(pixels)
                t, c = time.perf_counter(), time.process_time()
                engine.view_draw(ctx, depsgraph)
                seconds.append(time.perf_counter() - t)
                cpu.append(time.process_time() - c)     # llvmpipe's threads included
            after.append(on_redraw(i) if on_redraw else None)
            if until is not None and until(i):
                break
            if on_redraw:
                depsgraph.update()    # as the viewport re-evaluates what on_redraw edited
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(updated)

    # buffer protocol in memory order (see gpu_shaders.resources.read_texture)
    drawn = np.asarray(off.texture_color.read()).ravel(order="K").astype(np.float32)
    drawn = drawn.reshape(height, width, 4)
    return {"drawn": drawn, "seconds": seconds, "cpu_seconds": cpu, "after": after}


def run(scene, base, width: int, height: int, redraws: int = 1, on_redraw=None,
        until=None) -> dict:
    """`redraws` view_draw calls of engine class `base` for the scene camera's view at
    width x height (see the module docstring); `until(i)`, called after redraw i (and its
    on_redraw), ends them early when true. Raises RuntimeError with the traceback on failure."""
    import bpy

    cls = _engine_class(base)
    before = scene.render.engine
    _JOB.clear()
    _JOB["args"] = dict(width=int(width), height=int(height), redraws=int(redraws),
                        on_redraw=on_redraw, until=until)
    scene.render.engine = cls.bl_idname
    try:
        bpy.ops.render.render()
    finally:
        scene.render.engine = before
    if "error" in _JOB:
        raise RuntimeError(_JOB["error"])
    if "result" not in _JOB:
        raise RuntimeError("the view_draw harness engine did not render")
    return _JOB["result"]
