"""The Lumen tab of the 3D viewport sidebar (N-panel): settings, bake, stats, export, atlas."""
import bpy

from ..lumen_addon.estimate import texel_budget_text
from .bake_op import RUNNING, cached_estimate, human_bytes


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
            draw_estimate(layout, context)

        col = layout.column()
        col.prop(s, "voxel_density")
        col.prop(s, "max_resolution")
        col.prop(s, "texel_density")
        col.prop(s, "texel_budget")
        col.label(text=texel_budget_text(s.texel_budget))
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
        for i, text in enumerate(stale_lines(scene)):
            box.label(text=text, icon='ERROR' if i == 0 else 'BLANK1')

        if scene.render.engine == 'LUMEN_GI':
            box = layout.box()
            box.label(text="Preview Engine", icon='SHADING_RENDERED')
            draw_gi_settings(box, s, scene.render)
            box.prop(s, "debug_view")
            draw_memory(box, scene)

        layout.operator("lumen.export_cache", icon='EXPORT')
        layout.operator("lumen.open_atlas", icon='IMAGE_DATA')


def draw_estimate(layout, context):
    """'Bake: ~2.1 GB, ~25 s' under the Bake button (bake_op.cached_estimate: counts and bounds
    only), with a warning icon when the bake operator will ask before starting it."""
    depsgraph = getattr(context.view_layer, "depsgraph", None)
    if depsgraph is None:
        return
    try:
        est = cached_estimate(context.scene, depsgraph)
    except Exception:            # a panel must draw whatever the scene holds
        return
    if est.triangles:
        layout.label(text=f"Bake: {est.text()}", icon='ERROR' if est.large else 'TIME')


def stale_lines(scene, limit: int = 5) -> list:
    """The panel's lines on objects added or edited since the bake, as the Lumen GI engine's
    last frame of this scene found them (engine.STALE); [] when none or not rendered yet."""
    from ..gpu_shaders.engine import STALE

    names = list(STALE.get(scene.name) or [])
    if not names:
        return []
    head = f"{len(names)} object{'s' if len(names) != 1 else ''} changed since the bake:"
    more = [f"and {len(names) - limit} more"] if len(names) > limit else []
    return [head] + names[:limit] + more


def draw_gi_settings(layout, s, render=None):
    col = layout.column()
    col.prop(s, "viewport_gi_quality")
    col.prop(s, "cache_texels_per_frame")
    if render is not None:      # Blender's own viewport setting, used by Cycles and EEVEE too
        col.prop(render, "preview_pixel_size", text="Viewport Pixel Size")
    col.prop(s, "gi_quality")
    sub = col.column()
    sub.active = s.gi_quality != 'OFF'
    sub.prop(s, "gi_method")
    if s.gi_method in ('LPV', 'VXGI'):
        sub.label(text="Not built yet: renders with Lumen", icon='INFO')
    sub.prop(s, "bounces")
    sub.prop(s, "render_frames")
    if s.gi_method == 'SSGI':
        for name in ("ssgi_rays", "ssgi_steps", "ssgi_thickness", "ssgi_reuse"):
            sub.prop(s, name)
    elif s.gi_method == 'RSM':
        sub.prop(s, "rsm_resolution")
        sub.prop(s, "rsm_samples")
    else:
        sub.prop(s, "gi_gather")


def draw_memory(layout, scene):
    """GPU bytes per resource of the last frame, grouped by stage (SDF, cards, global SDF, probes)."""
    from ..gpu_shaders.engine import MEMORY

    memory = MEMORY.get(scene.name)
    grid = layout.column(align=True)
    if not memory:
        grid.label(text="GPU memory: render once to measure")
        return
    stages = {}
    for name, value in memory.items():
        stage = ("Cards" if name.startswith("cards_") else "Global SDF" if name.startswith("global_sdf")
                 else "Screen targets" if name.startswith("screen_")
                 else "Screen probes" if name.startswith("probes_") else "Lights" if name == "lights"
                 else "SSGI" if name.startswith("ssgi_") else "RSM" if name.startswith("rsm_")
                 else "Mesh SDFs")
        stages[stage] = stages.get(stage, 0) + value
    for label, value in list(stages.items()) + [("Total", sum(memory.values()))]:
        row = grid.split(factor=0.5)
        row.label(text=f"GPU {label}")
        row.label(text=human_bytes(value))


class RENDER_PT_lumen_gi(bpy.types.Panel):
    """Render properties of the Lumen GI engine: GI quality, bounces, F12 accumulation."""
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    bl_label = "Lumen GI"
    COMPAT_ENGINES = {'LUMEN_GI'}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.lumen
        draw_gi_settings(layout, s, context.scene.render)
        layout.prop(s, "debug_view")
        draw_memory(layout, context.scene)


_CLASSES = (VIEW3D_PT_lumen, RENDER_PT_lumen_gi)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
