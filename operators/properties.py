"""Scene and object settings for the bake (`scene.lumen`, `object.lumen`).

The `last_*` scene properties are written by the bake operator only; they live in the .blend so
the panel still shows what the cache on disk holds after the file is reopened.
"""
import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from ..lumen_addon.sdf import DEFAULT_MAX_RESOLUTION, HARD_MAX_RESOLUTION

INT_MAX = 2 ** 31 - 1   # IntProperty is 32-bit; stats beyond it are clamped for display
# One cache folder per scene: baking one scene of a .blend never replaces another scene's cache.
DEFAULT_CACHE_DIR = "//lumen_cache/{scene}"


GI_QUALITY_ITEMS = (
    ('OFF', "Off", "Direct light and SDF sky occlusion only"),
    ('LOW', "Low", "A 16 px screen-probe grid, 32^3 global SDF clipmaps"),
    ('MEDIUM', "Medium", "A 16 px screen-probe grid, 48^3 clipmaps"),
    ('HIGH', "High", "An 8 px screen-probe grid, 64^3 clipmaps"))


GI_METHOD_ITEMS = (
    ('LUMEN', "Lumen", "Surface cache, signed distance fields and screen probes: light from "
     "everything, on or off screen, with many bounces"),
    ('SSGI', "Screen Space (SSGI)", "Rays through the depth buffer, reading the last frame's "
     "image: fast and detailed, but blind to anything the screen does not show"),
    ('RSM', "Reflective Shadow Maps", "One bounce of the lamps' light from what each lamp "
     "sees, ignoring what stands in the bounced light's way (emission does not bounce)"),
    ('LPV', "Light Propagation Volumes", "Not built yet: renders with Lumen"),
    ('VXGI', "Voxel Cone Tracing (VXGI)", "Not built yet: renders with Lumen"))


class LumenSceneSettings(bpy.types.PropertyGroup):
    __slots__ = ()   # Blender 5 warns about property groups that accept arbitrary attributes

    voxel_density: FloatProperty(
        name="Voxel Density", description="SDF voxels per metre at an object resolution scale of 1",
        default=20.0, min=0.1, soft_max=100.0)
    max_resolution: IntProperty(
        name="Max Resolution", description="Largest SDF resolution per axis of one mesh (mip 0)",
        default=DEFAULT_MAX_RESOLUTION, min=14, max=HARD_MAX_RESOLUTION)
    texel_density: FloatProperty(
        name="Texel Density", description="Mesh card texels per metre (surface-cache atlas)",
        default=20.0, min=1.0, max=200.0)
    texel_budget: IntProperty(
        name="Texel Budget", description="Most atlas texels for the whole scene; cards are scaled "
                                          "down (with a warning) when they would need more",
        default=2048 * 2048, min=4096)
    cache_dir: StringProperty(
        name="Cache Folder",
        description="Where the bake is written. // is the .blend file's folder and {scene} this "
                    "scene's name, so by default each scene of the file keeps its own cache",
        default=DEFAULT_CACHE_DIR, subtype='DIR_PATH')

    last_objects: IntProperty(name="Objects", description="Objects in the last bake", min=0)
    last_unique_meshes: IntProperty(name="Unique Meshes",
                                    description="Distinct meshes baked (instances share one)", min=0)
    last_bricks: IntProperty(name="Bricks", description="SDF bricks kept, all mips", min=0)
    last_bytes: IntProperty(name="Bytes", description="Size of the SDF bricks and indirection tables",
                            min=0)
    last_reused: IntProperty(name="Reused", min=0,
                             description="Meshes of the last bake taken unchanged from the bake before")
    last_cards: IntProperty(name="Cards", description="Mesh cards in the last bake", min=0)
    last_texels: IntProperty(name="Texels", description="Atlas texels used by the mesh cards",
                             min=0)
    last_coverage: FloatProperty(
        name="Coverage", description="Smallest share of a mesh's surface seen by its cards",
        min=0.0, max=1.0, subtype='FACTOR')
    last_seconds: FloatProperty(name="Seconds", description="Duration of the last bake", min=0.0)
    last_status: StringProperty(name="Status", description="Outcome of the last bake or export")

    debug_view: EnumProperty(
        name="Debug View", description="What the Lumen GI engine shows in Combined",
        items=(('COMBINED', "Combined", "Lit image: albedo x direct light + emission"),
               ('DEPTH', "Hit Distance", "SDF trace only: hit depth as grey"),
               ('STEPS', "Trace Steps", "SDF trace only: sphere-tracing steps as a heat map"),
               ('NORMAL', "Normal", "G-buffer world normal"),
               ('ALBEDO', "Albedo", "G-buffer base colour"),
               ('DIRECT', "Direct Light", "Diffuse direct light (albedo excluded)"),
               ('INDIRECT', "Indirect Light", "Diffuse indirect light only (albedo excluded)"),
               ('SSGI_HITS', "SSGI Hits", "GI Method SSGI: the share of each pixel's rays that "
                "hit something on screen (green), left the screen (blue) or ran out of steps "
                "(red)"),
               ('RSM_FLUX', "RSM Flux", "GI Method RSM: the lights' reflective shadow maps "
                "side by side, as the light their texels reflect"),
               ('HYBRID', "Mesh vs Global SDF", "SDF trace only: green = hit in the mesh SDFs "
                "(first 1.8 m), blue = hit in the global SDF clipmaps, black = miss"),
               ('SC_FINAL', "Surface Cache", "The cards' final lighting, seen through the cards "
                "(magenta: no card sees the point)"),
               ('SC_ALBEDO', "Surface Cache Albedo", "The cards' albedo, seen through the cards"),
               ('SC_NORMAL', "Surface Cache Normal", "The cards' normals, seen through the cards"),
               ('SC_DIRECT', "Surface Cache Direct", "The cards' direct light (E / pi)"),
               ('SC_INDIRECT', "Surface Cache Indirect", "The cards' indirect light (E / pi)"),
               ('CARDS', "Cards", "Each card in its own colour over the geometry"),
               ('SC_UPDATES', "Surface Cache Updates", "Update heat of the surface-cache budget: "
                "green relit this frame, to red 8 or more frames ago; magenta not yet relit"),
               ('PROBES', "Probe Atlas", "The screen probes' octahedral radiance, one tile each"),
               ('PROBE_FALLBACK', "Probe Interpolation", "Green: interpolated from probes on the "
                "pixel's plane, red: fallback (no probe on that plane)"),
               ('VOXEL_LIGHTING', "Voxel Lighting", "What a far (global SDF) ray hit reads from "
                "the voxel lighting, along the camera ray (magenta: no voxel face serves it; such "
                "hits read the surface cache)"),
               ('RADIANCE_CACHE', "Radiance Cache", "What the world radiance cache gives a ray "
                "leaving each surface along its normal (magenta: no traced probe serves it; with "
                "the cache off, Combined)")),
        default='COMBINED')
    gi_quality: EnumProperty(
        name="Render Quality", description="Budgets of the global illumination passes in F12 "
        "renders", items=GI_QUALITY_ITEMS, default='MEDIUM')
    viewport_gi_quality: EnumProperty(
        name="Viewport Quality", description="Budgets of the global illumination passes in the "
        "viewport (as Render Quality, the still viewport converges to the F12 image)",
        items=GI_QUALITY_ITEMS, default='MEDIUM')
    gi_gather: EnumProperty(
        name="Final Gather", description="How pixels gather indirect light",
        items=(('PROBES', "Screen Probes", "Lumen's screen probes: few rays, filtered, SH"),
               ('PIXEL', "Per Pixel (Reference)", "64 rays per pixel per frame through the same "
                "tracer and surface cache: slow, a check of the probes")),
        default='PROBES')
    gi_method: EnumProperty(
        name="GI Method", description="Which technique brings the indirect light (the lecture's "
        "methods side by side, on the same G-buffer, direct light and output)",
        items=GI_METHOD_ITEMS, default='LUMEN')
    ssgi_rays: IntProperty(
        name="SSGI Rays per Pixel", description="Screen-space rays each pixel traces per frame "
        "(its neighbours' rays are reused as well)", default=4, min=1, max=32)
    ssgi_steps: IntProperty(
        name="SSGI Steps", description="Most cells of the depth pyramid a ray visits before it "
        "gives up (Lumen's screen trace: 50)", default=50, min=4, max=256)
    ssgi_thickness: FloatProperty(
        name="SSGI Thickness", description="How thick surfaces are assumed behind what the "
        "screen shows: a ray that passes farther behind one goes on", default=0.1, min=0.001,
        soft_max=2.0, subtype='DISTANCE', unit='LENGTH')
    ssgi_reuse: IntProperty(
        name="SSGI Ray Reuse", description="Pixels around each pixel whose rays it reuses, as a "
        "radius (1: 3x3): more samples for free, blurring contact detail", default=1, min=0,
        max=3)
    rsm_resolution: IntProperty(
        name="RSM Resolution", description="Texels per side of each light's reflective shadow "
        "map (a point light has six, a cube)", default=256, min=16, max=4096)
    rsm_samples: IntProperty(
        name="RSM Samples", description="Shadow-map texels each pixel gathers light from per "
        "frame (the original paper used 400)", default=64, min=1, max=4096)
    bounces: IntProperty(
        name="Bounces", description="Surface-cache bounces an F12 render converges before it "
        "gathers (the viewport keeps bouncing every frame)", default=3, min=1, max=16)
    cache_texels_per_frame: IntProperty(
        name="Cache Texels per Frame", description="Viewport: surface-cache lighting texels "
        "relit per frame, in tiles of 32x32, the most visible, nearest and oldest first (0: "
        "the Viewport Quality's 16k / 32k / 64k). Caps the viewport's surface-cache cost however "
        "many cards the scene has; F12 relights every texel", default=0, min=0, soft_max=1 << 20,
        step=1024)
    render_frames: IntProperty(
        name="Render Frames", description="F12 temporal accumulation: jittered GI frames averaged",
        default=8, min=1, max=256)


class LumenObjectSettings(bpy.types.PropertyGroup):
    __slots__ = ()

    two_sided: BoolProperty(
        name="Two Sided",
        description="The mesh has no inside (foliage, cards, thin walls): the SDF is unsigned and "
                    "thickened by half a voxel so light cannot leak through")
    resolution_scale: FloatProperty(
        name="Resolution Scale", description="Multiplies the scene voxel density for this object",
        default=1.0, min=0.01, max=16.0)


_CLASSES = (LumenSceneSettings, LumenObjectSettings)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.lumen = PointerProperty(type=LumenSceneSettings)
    bpy.types.Object.lumen = PointerProperty(type=LumenObjectSettings)


def unregister():
    del bpy.types.Object.lumen
    del bpy.types.Scene.lumen
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
