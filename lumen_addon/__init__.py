"""Lumen GI core: scene data, bake algorithms and the cache format. Never imports bpy.

Public entry points: `lumen_addon.sdf.bake_mesh_sdf`, `lumen_addon.bake.bake_scene`,
`lumen_addon.cache.write_cache` / `read_cache`.
"""

__version__ = "0.1.0"
