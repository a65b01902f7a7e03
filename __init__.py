"""Lumen GI: Blender extension entry point (register/unregister only).

Imports are relative (once installed the package is `bl_ext.<repo>.lumen_gi`, not a fixed
name) and happen inside register(): pytest imports this file as the package of the repository
root, and that must not pull bpy into test processes that only test the core.
"""


def _modules():
    from . import gpu_shaders, operators
    return (operators, gpu_shaders)


def register():
    for mod in _modules():
        mod.register()


def unregister():
    for mod in reversed(_modules()):
        mod.unregister()
