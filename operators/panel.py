"""The extension's panels, where Blender's engines put theirs.

3D viewport sidebar (N-panel), Lumen tab: Lumen GI (Bake button or progress, estimate, export,
atlas) with sub-panels Bake Settings (scene.lumen.bake), Object (the active mesh's object.lumen)
and Last Bake (scene.lumen.last_bake, and what changed since).
Render Properties, with the Lumen GI engine chosen (as EEVEE's Sampling > Viewport / Render):
Lumen GI > Viewport, Render, GI Method (a sub-panel per method, shown for the chosen one: the
MethodPanel subclasses), Debug (debug view, GPU memory). All read scene.lumen.engine.
Object Properties > Visibility > Ray Visibility (a mesh's Camera, Diffuse and Shadow, a light's
Diffuse: what the engine honours), where EEVEE and Cycles put theirs.
"""
import bpy

from ..lumen_addon.estimate import texel_budget_text
from .bake_op import RUNNING, cached_estimate, human_bytes

ENGINE = 'LUMEN_GI'


class VIEW3D_PT_lumen(bpy.types.Panel):
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Lumen"
    bl_label = "Lumen GI"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        job = RUNNING.get(scene.name)
        if job is not None:
            layout.progress(factor=job.fraction, type='BAR',
                            text=f"Baking {job.fraction:.0%} (Esc to cancel)")
        else:
            layout.operator("lumen.bake", icon='RENDER_STILL')
            draw_estimate(layout, context)
        row = layout.row(align=True)
        row.operator("lumen.export_cache", icon='EXPORT')
        row.operator("lumen.open_atlas", icon='IMAGE_DATA')


class _SidebarChild:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Lumen"
    bl_parent_id = "VIEW3D_PT_lumen"


class VIEW3D_PT_lumen_bake(_SidebarChild, bpy.types.Panel):
    bl_label = "Bake Settings"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.lumen.bake
        col = layout.column()
        col.prop(s, "voxel_density")
        col.prop(s, "max_resolution")
        col = layout.column()
        col.prop(s, "texel_density")
        col.prop(s, "texel_budget")
        col.label(text=texel_budget_text(s.texel_budget))
        col.prop(s, "min_card_size")
        layout.prop(s, "cache_dir")


class VIEW3D_PT_lumen_object(_SidebarChild, bpy.types.Panel):
    bl_label = "Object"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        obj = context.object
        if obj is None or obj.type != 'MESH':
            layout.label(text="Select a mesh for per-object settings", icon='INFO')
            return
        layout.label(text=obj.name, icon='OBJECT_DATA')
        col = layout.column()
        col.prop(obj.lumen, "resolution_scale")
        col.prop(obj.lumen, "two_sided")


class VIEW3D_PT_lumen_last_bake(_SidebarChild, bpy.types.Panel):
    bl_label = "Last Bake"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        s = scene.lumen.last_bake
        grid = layout.column(align=True)
        for label, value in (("Objects", str(s.objects)),
                             ("Unique meshes", str(s.unique_meshes)),
                             ("Reused", str(s.reused)),
                             ("Bricks", str(s.bricks)),
                             ("Size", human_bytes(s.bytes)),
                             ("Cards", str(s.cards)),
                             ("Texels", f"{s.texels:,}"),
                             ("Coverage", f"{s.coverage:.1%}"),
                             ("Seconds", f"{s.seconds:.2f}")):
            row = grid.split(factor=0.5)
            row.label(text=label)
            row.label(text=value)
        if s.status:
            layout.label(text=s.status)
        for i, text in enumerate(stale_lines(scene)):
            layout.label(text=text, icon='ERROR' if i == 0 else 'BLANK1')


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


# Resource-name prefix (engine MEMORY keys) -> the stage the Debug panel sums it under; the
# rest are the mesh SDFs.
MEMORY_STAGES = (("cards_", "Cards"), ("global_sdf", "Global SDF"), ("screen_", "Screen targets"),
                 ("probes_", "Screen probes"), ("lights", "Lights"), ("sky", "Sky"),
                 ("voxel_lighting", "Voxel lighting"), ("ssgi_", "SSGI"), ("rsm_", "RSM"),
                 ("lpv_", "LPV"), ("vxgi_", "VXGI"), ("radiance_cache", "Radiance cache"),
                 ("gbuffer_", "G-buffer meshes"))


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
        stage = next((label for prefix, label in MEMORY_STAGES if name.startswith(prefix)),
                     "Mesh SDFs")
        stages[stage] = stages.get(stage, 0) + value
    for label, value in list(stages.items()) + [("Total", sum(memory.values()))]:
        row = grid.split(factor=0.5)
        row.label(text=f"GPU {label}")
        row.label(text=human_bytes(value))


class _RenderPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def begin(self, context):
        """The layout, split as Blender's own render panels are, and scene.lumen.engine."""
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        return layout, context.scene.lumen.engine


class RENDER_PT_lumen_gi(_RenderPanel, bpy.types.Panel):
    """Render properties of the Lumen GI engine; its sub-panels hold the settings."""
    bl_label = "Lumen GI"

    def draw(self, context):
        pass


class RENDER_PT_lumen_gi_viewport(_RenderPanel, bpy.types.Panel):
    bl_label = "Viewport"
    bl_parent_id = "RENDER_PT_lumen_gi"

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "viewport_quality", text="Quality")
        col.prop(s, "viewport_split")
        col.prop(s, "cache_texels_per_frame")
        # Blender's own viewport setting, which Cycles and EEVEE use too
        col.prop(context.scene.render, "preview_pixel_size", text="Pixel Size")


class RENDER_PT_lumen_gi_render(_RenderPanel, bpy.types.Panel):
    bl_label = "Render"
    bl_parent_id = "RENDER_PT_lumen_gi"

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "render_quality", text="Quality")
        sub = col.column()
        sub.active = s.render_quality != 'OFF'
        sub.prop(s, "bounces")
        sub.prop(s, "converge_bounces")
        sub.prop(s, "render_frames", text="Frames")
        sub.prop(s, "noise_threshold")
        sub.prop(s, "seed")
        col.prop(s, "aa_samples", text="Anti-Aliasing")


class RENDER_PT_lumen_gi_method(_RenderPanel, bpy.types.Panel):
    bl_label = "GI Method"
    bl_parent_id = "RENDER_PT_lumen_gi"

    def draw(self, context):
        layout, s = self.begin(context)
        layout.active = gi_on(s)
        layout.prop(s, "gi_method", text="Method")


def gi_on(s) -> bool:
    """Whether the viewport or the render brings bounced light (the method panels matter)."""
    return s.viewport_quality != 'OFF' or s.render_quality != 'OFF'


class MethodPanel(_RenderPanel):
    """A sub-panel of GI Method shown only while its METHOD is the chosen one (as EEVEE's
    sub-panels poll on their feature). A new method adds a subclass with METHOD and draw."""
    bl_parent_id = "RENDER_PT_lumen_gi_method"
    METHOD = ""

    @classmethod
    def poll(cls, context):
        return (context.engine in cls.COMPAT_ENGINES
                and context.scene.lumen.engine.gi_method == cls.METHOD)

    def begin(self, context):
        layout, s = _RenderPanel.begin(self, context)
        layout.active = gi_on(s)
        return layout, s


class RENDER_PT_lumen_gi_lumen(MethodPanel, bpy.types.Panel):
    bl_label = "Lumen"
    METHOD = 'LUMEN'

    def draw(self, context):
        layout, s = self.begin(context)
        layout.prop(s, "gi_gather")
        layout.prop(s, "screen_trace")
        row = layout.row()
        row.active = s.screen_trace
        row.prop(s, "screen_hit")
        layout.prop(s, "adaptive_probes")
        layout.prop(s, "probe_importance")
        layout.prop(s, "radiance_cache")


class RENDER_PT_lumen_gi_ssgi(MethodPanel, bpy.types.Panel):
    bl_label = "Screen Space (SSGI)"
    METHOD = 'SSGI'

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "ssgi_rays", text="Rays per Pixel")
        col.prop(s, "ssgi_steps", text="Steps")
        col.prop(s, "ssgi_thickness", text="Thickness")
        col.prop(s, "ssgi_reuse", text="Ray Reuse")


class RENDER_PT_lumen_gi_rsm(MethodPanel, bpy.types.Panel):
    bl_label = "Reflective Shadow Maps"
    METHOD = 'RSM'

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "rsm_resolution", text="Resolution")
        col.prop(s, "rsm_samples", text="Samples")


class RENDER_PT_lumen_gi_lpv(MethodPanel, bpy.types.Panel):
    bl_label = "Light Propagation Volumes"
    METHOD = 'LPV'

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "lpv_cells", text="Cells")
        col.prop(s, "lpv_iterations", text="Iterations")
        col.prop(s, "lpv_occlusion", text="Occlusion")
        col.prop(s, "rsm_resolution", text="Light Map Resolution")


class RENDER_PT_lumen_gi_vxgi(MethodPanel, bpy.types.Panel):
    bl_label = "Voxel Cone Tracing"
    METHOD = 'VXGI'

    def draw(self, context):
        layout, s = self.begin(context)
        col = layout.column()
        col.prop(s, "vxgi_cones", text="Cones")
        col.prop(s, "vxgi_cone_angle", text="Cone Angle")
        col.prop(s, "vxgi_distance", text="Distance")
        col.prop(s, "vxgi_step", text="Step")
        col.prop(s, "vxgi_offset", text="Offset")


class RENDER_PT_lumen_gi_debug(_RenderPanel, bpy.types.Panel):
    bl_label = "Debug"
    bl_parent_id = "RENDER_PT_lumen_gi"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, s = self.begin(context)
        layout.prop(s, "debug_view")
        draw_memory(layout, context.scene)


class OBJECT_PT_lumen_ray_visibility(bpy.types.Panel):
    """Object Properties > Visibility > Ray Visibility with Lumen GI: the switches the engine
    honours (Blender's Visibility panel draws them for EEVEE only, and Cycles has its own): a
    mesh's Camera, Diffuse and Shadow; a light's Diffuse (off, it lights nothing we shade)."""
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_visibility"
    COMPAT_ENGINES = {ENGINE}
    KINDS = {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT'}     # what the bake turns into meshes

    @classmethod
    def poll(cls, context):
        ob = context.object
        return (context.engine in cls.COMPAT_ENGINES and ob is not None
                and (ob.type in cls.KINDS or ob.type == 'LIGHT'))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.object
        col = layout.column()
        if ob.type == 'LIGHT':
            col.prop(ob, "visible_diffuse", text="Diffuse", toggle=False)
            return
        col.prop(ob, "visible_camera", text="Camera", toggle=False)
        col.prop(ob, "visible_diffuse", text="Diffuse", toggle=False)
        col.prop(ob, "visible_shadow", text="Shadow", toggle=False)


# Parents before their children (Blender requires it); the order is the drawing order.
SIDEBAR_PANELS = (VIEW3D_PT_lumen, VIEW3D_PT_lumen_bake, VIEW3D_PT_lumen_object,
                  VIEW3D_PT_lumen_last_bake)
RENDER_PANELS = (RENDER_PT_lumen_gi, RENDER_PT_lumen_gi_viewport, RENDER_PT_lumen_gi_render,
                 RENDER_PT_lumen_gi_method, RENDER_PT_lumen_gi_lumen, RENDER_PT_lumen_gi_ssgi,
                 RENDER_PT_lumen_gi_rsm, RENDER_PT_lumen_gi_lpv,
                 RENDER_PT_lumen_gi_vxgi, RENDER_PT_lumen_gi_debug)
OBJECT_PANELS = (OBJECT_PT_lumen_ray_visibility,)       # a child of Blender's Visibility panel
_CLASSES = SIDEBAR_PANELS + RENDER_PANELS + OBJECT_PANELS


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
