"""`lumen.export_cache`: write the scene's last bake to a folder of the user's choice.

Without a bake in memory (a freshly opened file) it bakes first, synchronously. Errors are
reported like the bake's: an ERROR naming the object or folder, {'CANCELLED'}, nothing written.
"""
import bpy
from bpy.props import BoolProperty, StringProperty

from ..lumen_addon.cache import write_cache
from .bake_op import (LAST_BAKES, RUNNING, bake_now, failure_message, record_bake, report_warnings,
                      resolve_folder)


class LUMEN_OT_export_cache(bpy.types.Operator):
    """Write the last Lumen GI bake (baking first if there is none) to a folder"""

    bl_idname = "lumen.export_cache"
    bl_label = "Export Lumen Cache"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="Folder", description="Folder to write the cache into",
                             subtype='DIR_PATH')
    filter_folder: BoolProperty(default=True, options={'HIDDEN', 'SKIP_SAVE'})

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def invoke(self, context, event):
        if not self.filepath:
            self.filepath = str(resolve_folder("//lumen_export", "lumen_export")) + "/"
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def _fail(self, scene, msg):
        scene.lumen.last_bake.status = f"Export failed: {msg}"
        self.report({'ERROR'}, f"Lumen export failed: {msg}")
        return {'CANCELLED'}

    def execute(self, context):
        scene = context.scene
        if not self.filepath.strip():
            return self._fail(scene, "no folder given")
        if scene.name in RUNNING:
            return self._fail(scene, f"a bake of scene '{scene.name}' is still running")
        bake = LAST_BAKES.get(scene.name)
        try:
            if bake is None:
                bake, warnings = bake_now(context, scene)
                report_warnings(self, warnings)
                report_warnings(self, bake.warnings)
            folder = resolve_folder(self.filepath, "lumen_export")
            write_cache(folder, bake)
        except Exception as exc:
            return self._fail(scene, failure_message(exc))
        if LAST_BAKES.get(scene.name) is not bake:
            record_bake(scene, bake, "")
        scene.lumen.last_bake.status = f"Exported {len(bake.instances)} objects to {folder}"
        self.report({'INFO'}, scene.lumen.last_bake.status)
        return {'FINISHED'}


def register():
    bpy.utils.register_class(LUMEN_OT_export_cache)


def unregister():
    bpy.utils.unregister_class(LUMEN_OT_export_cache)
