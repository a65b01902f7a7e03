"""Blender's own Properties panels shown with the Lumen GI engine, as other render engines do.

A stock panel appears only for the engines in its COMPAT_ENGINES. Without this, choosing Lumen GI
hid Output > Format (the resolution), Camera, Light power and colour, Material Surface, World,
Color Management and the view-layer passes. We take every panel meant for any engine
('BLENDER_RENDER', Blender's marker for engine-independent panels) and, of EEVEE's own, the ones
whose settings our engine reads: the light (colour, power, radius), the material and world node
trees. DATA_PT_light is left out: it only repeats the light type that DATA_PT_EEVEE_light shows
with everything else. unregister() takes LUMEN_GI out again.
"""
from __future__ import annotations

import bpy

ENGINE = "LUMEN_GI"
EEVEE_PANELS = {"DATA_PT_EEVEE_light", "EEVEE_MATERIAL_PT_surface", "EEVEE_WORLD_PT_surface",
                "EEVEE_MATERIAL_PT_context_material"}
SKIP = {"DATA_PT_light"}
_ADDED: list = []


def _panels():
    seen, stack = [], list(bpy.types.Panel.__subclasses__())
    while stack:
        cls = stack.pop()
        seen.append(cls)
        stack.extend(cls.__subclasses__())
    return seen


def wanted(cls) -> bool:
    compat = getattr(cls, "COMPAT_ENGINES", None)
    if not isinstance(compat, set) or ENGINE in compat or cls.__name__ in SKIP:
        return False
    return "BLENDER_RENDER" in compat or cls.__name__ in EEVEE_PANELS


def register():
    # A new set per class, never .add(): subclasses share their parent's set object (the node
    # editor's light panel is DATA_PT_light's), and one add would show both.
    for cls in _panels():
        if wanted(cls):
            _ADDED.append((cls, cls.__dict__.get("COMPAT_ENGINES")))
            cls.COMPAT_ENGINES = set(cls.COMPAT_ENGINES) | {ENGINE}


def unregister():
    while _ADDED:
        cls, own = _ADDED.pop()
        if own is None:
            del cls.COMPAT_ENGINES       # inherited again
        else:
            cls.COMPAT_ENGINES = own
