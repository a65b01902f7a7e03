"""Files saved before the settings were grouped open with their settings intact.

Until the settings were split into `scene.lumen.bake`, `.engine` and `.last_bake`, every one lay
flat in `scene.lumen` (`scene.lumen.gi_quality`, `scene.lumen.last_cards`...). Blender keeps such
values in the .blend as raw ID properties of the `lumen` group whatever the classes now say, so
after a file loads (`load_post`) each old value still there is moved into its group under its new
name and the old key is deleted: a second load finds nothing to move. Enums are stored as the
index of their item, so the old item orders are frozen here (items added later do not shift them).
"""
import bpy

QUALITY = ("OFF", "LOW", "MEDIUM", "HIGH")
GATHER = ("PROBES", "PIXEL")
METHOD = ("LUMEN", "SSGI", "RSM", "LPV", "VXGI")
DEBUG_VIEW = ("COMBINED", "DEPTH", "STEPS", "NORMAL", "ALBEDO", "DIRECT", "INDIRECT", "SSGI_HITS",
              "RSM_FLUX", "HYBRID", "SC_FINAL", "SC_ALBEDO", "SC_NORMAL", "SC_DIRECT",
              "SC_INDIRECT", "CARDS", "SC_UPDATES", "PROBES", "PROBE_FALLBACK", "VOXEL_LIGHTING")

# old flat key -> (group, new name, the old enum's identifiers in item order, or None)
MOVES = {
    "voxel_density": ("bake", "voxel_density", None),
    "max_resolution": ("bake", "max_resolution", None),
    "texel_density": ("bake", "texel_density", None),
    "texel_budget": ("bake", "texel_budget", None),
    "cache_dir": ("bake", "cache_dir", None),
    "viewport_gi_quality": ("engine", "viewport_quality", QUALITY),
    "gi_quality": ("engine", "render_quality", QUALITY),
    "cache_texels_per_frame": ("engine", "cache_texels_per_frame", None),
    "bounces": ("engine", "bounces", None),
    "render_frames": ("engine", "render_frames", None),
    "gi_method": ("engine", "gi_method", METHOD),
    "gi_gather": ("engine", "gi_gather", GATHER),
    "ssgi_rays": ("engine", "ssgi_rays", None),
    "ssgi_steps": ("engine", "ssgi_steps", None),
    "ssgi_thickness": ("engine", "ssgi_thickness", None),
    "ssgi_reuse": ("engine", "ssgi_reuse", None),
    "rsm_resolution": ("engine", "rsm_resolution", None),
    "rsm_samples": ("engine", "rsm_samples", None),
    "debug_view": ("engine", "debug_view", DEBUG_VIEW),
    "last_objects": ("last_bake", "objects", None),
    "last_unique_meshes": ("last_bake", "unique_meshes", None),
    "last_reused": ("last_bake", "reused", None),
    "last_bricks": ("last_bake", "bricks", None),
    "last_bytes": ("last_bake", "bytes", None),
    "last_cards": ("last_bake", "cards", None),
    "last_texels": ("last_bake", "texels", None),
    "last_coverage": ("last_bake", "coverage", None),
    "last_seconds": ("last_bake", "seconds", None),
    "last_status": ("last_bake", "status", None),
}


def migrate_scene(scene) -> list:
    """Move the scene's old flat settings into their groups; returns the old keys moved. A value
    the new property refuses (a wrong type, an enum index it never had) is dropped: the setting
    keeps its default rather than failing the load."""
    settings = getattr(scene, "lumen", None)
    if settings is None or scene.library is not None:     # linked scenes are read-only
        return []
    moved = []
    for key in [k for k in settings.keys() if k in MOVES]:
        group, name, items = MOVES[key]
        value = settings[key]
        try:
            if items is not None:
                value = items[int(value)]
            setattr(getattr(settings, group), name, value)
            moved.append(key)
        except (TypeError, ValueError, IndexError, AttributeError):
            pass
        del settings[key]
    return moved


def migrate_all() -> dict:
    """migrate_scene for every scene of the open file: {scene name: old keys moved}."""
    out = {}
    for scene in bpy.data.scenes:
        moved = migrate_scene(scene)
        if moved:
            out[scene.name] = moved
            print(f"Lumen GI: moved {len(moved)} settings of scene {scene.name!r} into "
                  f"scene.lumen.bake / .engine / .last_bake")
    return out


@bpy.app.handlers.persistent
def _on_load(_filepath):
    migrate_all()


def register():
    bpy.app.handlers.load_post.append(_on_load)
    try:                 # enabled with a file already open; at start-up bpy.data is restricted
        migrate_all()
    except AttributeError:
        pass


def unregister():
    if _on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_on_load)
