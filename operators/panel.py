"""The Lumen tab of the 3D viewport sidebar (N-panel): settings, bake, stats, export, atlas."""
import bpy

from .bake_op import RUNNING, human_bytes


class VIEW3D_PT_lumen(bpy.types.Panel):
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Lumen"
    bl_label = "Lumen GI"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        scene = context.scene
        s = scene.lumen

        job = RUNNING.get(scene.name)
        if job is not None:
            layout.progress(factor=job.fraction, type='BAR',
                            text=f"Baking {job.fraction:.0%} (Esc to cancel)")
        else:
            layout.operator("lumen.bake", icon='RENDER_STILL')

        col = layout.column()
        col.prop(s, "voxel_density")
        col.prop(s, "max_resolution")
        col.prop(s, "texel_density")
        col.prop(s, "texel_budget")
        col.prop(s, "cache_dir")

        obj = context.object
        box = layout.box()
        if obj is not None and obj.type == 'MESH':
            box.label(text=obj.name, icon='OBJECT_DATA')
            box.prop(obj.lumen, "resolution_scale")
            box.prop(obj.lumen, "two_sided")
        else:
            box.label(text="Select a mesh for per-object settings", icon='INFO')

        box = layout.box()
        box.label(text="Last Bake", icon='INFO')
        grid = box.column(align=True)
        for label, value in (("Objects", str(s.last_objects)),
                             ("Unique meshes", str(s.last_unique_meshes)),
                             ("Reused", str(s.last_reused)),
                             ("Bricks", str(s.last_bricks)),
                             ("Size", human_bytes(s.last_bytes)),
                             ("Cards", str(s.last_cards)),
                             ("Texels", f"{s.last_texels:,}"),
                             ("Coverage", f"{s.last_coverage:.1%}"),
                             ("Seconds", f"{s.last_seconds:.2f}")):
            row = grid.split(factor=0.5)
            row.label(text=label)
            row.label(text=value)
        if s.last_status:
            box.label(text=s.last_status)

        if scene.render.engine == 'LUMEN_GI':
            box = layout.box()
            box.label(text="Preview Engine", icon='SHADING_RENDERED')
            box.prop(s, "debug_view")
            from ..gpu_shaders.engine import MEMORY
            memory = MEMORY.get(scene.name)
            grid = box.column(align=True)
            if memory:
                for label, value in list(memory.items()) + [("total", sum(memory.values()))]:
                    row = grid.split(factor=0.5)
                    row.label(text=f"GPU {label}")
                    row.label(text=human_bytes(value))
            else:
                grid.label(text="GPU memory: render once to measure")

        layout.operator("lumen.export_cache", icon='EXPORT')
        layout.operator("lumen.open_atlas", icon='IMAGE_DATA')


def register():
    bpy.utils.register_class(VIEW3D_PT_lumen)


def unregister():
    bpy.utils.unregister_class(VIEW3D_PT_lumen)
