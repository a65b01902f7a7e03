"""Everything that reads or writes Blender data: extraction, properties, operators, the panel.

Each module registers its own classes; order matters (properties before the operators and panel
that use them).
"""
from . import (atlas_op, bake_op, export_op, extract, legacy_settings, material_capture, panel,
               properties, stock_panels, world_capture)

_MODULES = (properties, legacy_settings, extract, bake_op, export_op, atlas_op, panel,
            stock_panels, world_capture, material_capture)


def register():
    for mod in _MODULES:
        mod.register()


def unregister():
    for mod in reversed(_MODULES):
        mod.unregister()
