"""GPU side of Lumen GI: the preview RenderEngine ("Lumen GI") and its passes.

packing.py (numpy only) lays the bake out as texture arrays; resources.py uploads them;
glsl/sdf_lib.glsl samples them; sdf_trace.py + glsl/sdf_trace.comp.glsl sphere-trace the camera
rays; engine.py is the RenderEngine. Imports of bpy/gpu happen inside register(), so pytest can
import `gpu_shaders.packing` without Blender.
"""


_SHADER_CACHES = (("compute", "_SHADERS"), ("gbuffer", "_SHADER"),
                  ("global_sdf", "_SHADERS"), ("lpv", "_SHADERS"), ("resources", "_SHADERS"))


def free_shaders():
    """Free every cached compiled pass before Blender tears its GPU module down.

    Why: render engines free their textures when a render or a viewport ends; a shader that was
    last bound to such a texture and is freed later, by Python's final garbage collection at
    exit, crashed Blender (measured: segfault at exit after an F12 whose state was freed; none
    when the caches are cleared first)."""
    import importlib

    for module, name in _SHADER_CACHES:
        cache = getattr(importlib.import_module(f"{__name__}.{module}"), name, None)
        if cache is not None:
            cache.clear()


def register():
    import atexit

    from . import engine
    engine.register()
    atexit.register(free_shaders)


def unregister():
    import atexit

    from . import engine
    engine.unregister()
    atexit.unregister(free_shaders)
    free_shaders()
