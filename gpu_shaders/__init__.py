"""GPU side of Lumen GI: the preview RenderEngine ("Lumen GI") and its passes.

packing.py (numpy only) lays the bake out as texture arrays; resources.py uploads them;
glsl/sdf_lib.glsl samples them; sdf_trace.py + glsl/sdf_trace.comp.glsl sphere-trace the camera
rays; engine.py is the RenderEngine. Imports of bpy/gpu happen inside register(), so pytest can
import `gpu_shaders.packing` without Blender.
"""


def register():
    from . import engine
    engine.register()


def unregister():
    from . import engine
    engine.unregister()
