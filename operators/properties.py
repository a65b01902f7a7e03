"""Scene and object settings (`scene.lumen`, `object.lumen`), in three groups under the scene's:

    scene.lumen.bake       what the bake makes (LumenBakeSettings): read by the bake operator
    scene.lumen.engine     how the Lumen GI engine renders (LumenEngineSettings): viewport and F12
                           apart (viewport_quality / render_quality, as Cycles' preview_samples /
                           samples), the GI method and its settings, the debug view
    scene.lumen.last_bake  what the last bake made (LumenLastBake): written by the bake and export
                           operators only; it lives in the .blend so the panel still shows what
                           the cache on disk holds after the file is reopened

Every default comes from the bpy-free dataclass that uses it (lumen_addon.bake.BakeSettings and
ObjectInput, gpu_shaders.gi_settings.GISettings, gpu_shaders.gi_methods.MethodSettings), so it is
stated once; tests/blender/test_properties.py checks each. Files saved with the flat layout of
before are moved into these groups on load (legacy_settings.py).
"""
from dataclasses import fields

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from ..gpu_shaders.gi_methods import MethodSettings
from ..gpu_shaders.gi_settings import CACHE_TEXELS_PER_FRAME, VIEWPORT_SPLIT, GISettings
from ..lumen_addon.bake import BakeSettings, ObjectInput
from ..lumen_addon.sdf import HARD_MAX_RESOLUTION

INT_MAX = 2 ** 31 - 1   # IntProperty is 32-bit; stats beyond it are clamped for display
# One cache folder per scene: baking one scene of a .blend never replaces another scene's cache.
DEFAULT_CACHE_DIR = "//lumen_cache/{scene}"

BAKE = BakeSettings()
GI = GISettings()
METHOD = MethodSettings()
OBJECT = {f.name: f.default for f in fields(ObjectInput)}


GI_QUALITY_ITEMS = (
    ('OFF', "Off", "No bounced light: direct light and sky shadowing only (fastest)"),
    ('LOW', "Low", "Coarse bounced light, quickest: enough for layout and blocking"),
    ('MEDIUM', "Medium", "Balanced detail and speed"),
    ('HIGH', "High", "Four times Medium's bounced-light samples across the screen: sharper "
     "around small objects and where they touch, slower"))


VIEWPORT_SPLIT_ITEMS = (
    ('1', "Every Redraw", "Each redraw updates the bounced light of every pixel: slowest redraws, "
     "fewest of them to a clean image"),
    ('4', "4 Redraws", "Each redraw updates a quarter of the pixels and of the probes' rays: "
     "redraws about three times faster, four times as many of them to the same image"),
    ('16', "16 Redraws", "Each redraw updates a sixteenth: the fastest redraws for big viewports "
     "and slow machines, the slowest to refine"))


GI_METHOD_ITEMS = (
    ('LUMEN', "Lumen", "Bounced light from everything in the scene, on or off screen, "
     "including glowing materials and the sky, with several bounces: the most complete"),
    ('SSGI', "Screen Space (SSGI)", "Bounced light from what the screen shows only: fast and "
     "detailed, but light from anything off screen or hidden behind objects is missing"),
    ('RSM', "Reflective Shadow Maps", "One bounce of the lamps' light from what each lamp "
     "sees, ignoring what stands in the bounced light's way (emission does not bounce)"),
    ('LPV', "Light Propagation Volumes", "One bounce of the lamps' light spread through a coarse "
     "grid around the scene: smooth and cheap, but blurred, and it leaks through thin walls "
     "(emission does not bounce)"),
    ('VXGI', "Voxel Cone Tracing (VXGI)", "A few wide cones per pixel through the voxel "
     "lighting clipmaps: smooth and cheap per pixel, but blurry, and walls thinner than the "
     "cones' sampling leak light"))


# Blender 5.0 warns on every set of a path property that is not declared blend-relative ('//');
# Blender 4.2 has no such option and refuses to register a property that names it.
_BLEND_RELATIVE = ({'PATH_SUPPORTS_BLEND_RELATIVE'}
                   if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties
                   else set())


class LumenBakeSettings(bpy.types.PropertyGroup):
    """Inputs of the bake (`scene.lumen.bake`): shape and surface-lighting detail, cache folder."""
    __slots__ = ()   # Blender 5 warns about property groups that accept arbitrary attributes

    voxel_density: FloatProperty(
        name="Voxel Density",
        description="How finely the bake records each object's shape, in samples per metre of its size in "
                    "the scene (a scaled object gets as many as an unscaled one of its size). "
                    "Higher keeps thin parts and narrow gaps from leaking or blocking light, but "
                    "the bake takes longer and needs more memory",
        default=BAKE.voxel_density, min=0.1, soft_max=100.0)
    max_resolution: IntProperty(
        name="Max Resolution",
        description="Most shape samples along any one object's side. Large objects stop getting "
                    "finer past it, which keeps their bake time and memory in check; raise it for "
                    "big objects whose small details leak light",
        default=BAKE.max_resolution, min=14, max=HARD_MAX_RESOLUTION)
    texel_density: FloatProperty(
        name="Texel Density",
        description="How sharp the light stored on surfaces is, in texels per metre. Higher "
                    "shows bounced light and colour bleeding from smaller details, at more GPU "
                    "memory and more lighting work per frame",
        default=BAKE.texel_density, min=1.0, max=200.0)
    texel_budget: IntProperty(
        name="Texel Budget",
        description="Most texels all objects' stored surface lighting may use together. When the "
                    "scene needs more, every object's is made blurrier to fit (with a warning). "
                    "The panel shows the atlas size and GPU memory it means",
        default=BAKE.texel_budget, min=4096)
    min_card_size: FloatProperty(
        name="Min Card Size",
        description="Objects smaller than this on every side store no surface lighting of their "
                    "own (emitters always do): light bouncing off them is taken from their "
                    "surroundings, which misses most of what small objects bounce onto each "
                    "other. Renders scatters of thousands of pebbles or leaves much faster. 0 "
                    "(the default) gives every object its own",
        default=BAKE.min_card_size, min=0.0, soft_max=1.0, subtype='DISTANCE', unit='LENGTH')
    cache_dir: StringProperty(
        name="Cache Folder",
        description="Where the bake is written and read from. // is the .blend file's folder and "
                    "{scene} this scene's name, so by default each scene of the file keeps its "
                    "own bake",
        default=DEFAULT_CACHE_DIR, subtype='DIR_PATH', options=_BLEND_RELATIVE)


class LumenEngineSettings(bpy.types.PropertyGroup):
    """How the Lumen GI engine renders (`scene.lumen.engine`): the viewport's settings and the F12
    render's apart, the GI method and its settings, the debug view."""
    __slots__ = ()

    viewport_quality: EnumProperty(
        name="Viewport Quality",
        description="How much work the viewport spends on bounced light each frame. Higher is "
                    "sharper and steadier while you move, but slower. A still viewport keeps "
                    "refining toward the final render",
        items=GI_QUALITY_ITEMS, default=GI.quality)
    cache_texels_per_frame: IntProperty(
        name="Cache Texels per Frame",
        description="Viewport only: how much of the light stored on surfaces is brought up to "
                    "date each frame, most visible and oldest first. Lower keeps big scenes "
                    "fast, but changes in the lighting spread more slowly; 0 uses the Viewport "
                    "Quality's amount (16k, 32k or 64k texels). Final renders update all of it",
        default=CACHE_TEXELS_PER_FRAME, min=0, soft_max=1 << 20, step=1024)
    viewport_split: EnumProperty(
        name="Spread over",
        description="Viewport only: over how many redraws one step of refinement is spread. "
                    "More keeps the viewport responsive while it refines (each redraw does less) "
                    "but takes more redraws to a clean image. Final renders do everything at once",
        items=VIEWPORT_SPLIT_ITEMS, default=str(VIEWPORT_SPLIT))
    render_quality: EnumProperty(
        name="Render Quality",
        description="How much work a final render (F12) spends on bounced light in each of its "
                    "frames. Higher is sharper around small objects, but slower",
        items=GI_QUALITY_ITEMS, default=GI.quality)
    bounces: IntProperty(
        name="Bounces",
        description="How many times light bounces from surface to surface in a final render. "
                    "More brightens deep corners and rooms lit through an opening; each bounce "
                    "adds render time. The viewport keeps adding bounces while it is still",
        default=GI.bounces, min=1, max=16)
    converge_bounces: BoolProperty(
        name="Converge Bounces",
        description="Final render: keep adding bounces beyond Bounces (up to 16) until the "
                    "bounced light stops changing, as a room lit through a window needs; an "
                    "open scene stops at Bounces. Off: exactly Bounces",
        default=GI.converge_bounces)
    render_frames: IntProperty(
        name="Render Frames",
        description="Frames a final render averages, each with its samples slightly moved. More "
                    "removes blotches and noise from the bounced light; render time grows with it",
        default=GI.render_frames, min=1, max=256)
    noise_threshold: FloatProperty(
        name="Noise Threshold",
        description="Final render: stop averaging frames early (after 4) once the bounced "
                    "light's remaining noise, relative to what each pixel shows, is below this, "
                    "as Cycles' adaptive sampling does. Lower is cleaner and slower; 0 always "
                    "renders every frame",
        default=GI.noise_threshold, min=0.0, max=1.0, precision=4, step=0.1)
    seed: IntProperty(
        name="Seed",
        description="Final render: which random patterns the bounced light is sampled with. "
                    "Renders with different seeds differ only in their noise",
        default=GI.seed, min=0, max=1 << 16)
    aa_samples: IntProperty(
        name="Anti-Aliasing Samples",
        description="Final render: the image is averaged over this many slightly moved "
                    "camera positions, so edges and shadow edges come out smooth (filtered as "
                    "Film > Filter Size says). Each sample redraws the geometry and direct light; "
                    "the bounced light is computed once. 1 turns it off",
        default=GI.aa_samples, min=1, max=64)
    gi_method: EnumProperty(
        name="GI Method",
        description="Which technique brings the bounced light. Lumen sees the whole scene; the "
                    "others are the older methods it is compared with: faster, each with the "
                    "limits it describes. Direct light and the output are the same for all",
        items=GI_METHOD_ITEMS, default=METHOD.method)
    gi_gather: EnumProperty(
        name="Final Gather",
        description="How each pixel collects bounced light with Lumen",
        items=(('PROBES', "Screen Probes", "Few rays, shared between neighbouring pixels and "
                "smoothed: fast, the normal choice"),
               ('PIXEL', "Per Pixel (Reference)", "64 rays for every pixel each frame: slow, a "
                "reference to check the probes against")),
        default=GI.gather)
    radiance_cache: BoolProperty(
        name="Radiance Cache",
        description="Experimental: rays stop after about 2 m and take the far light from probes "
                    "kept between frames. Off by default: on llvmpipe it saves little time and "
                    "made two of three test scenes slightly worse",
        default=GI.radiance_cache)
    screen_trace: BoolProperty(
        name="Screen Trace",
        description="Rays first cross the empty space the image on screen shows, and the "
                    "scene's distance fields find what they hit from there. Experimental: off "
                    "by default, it looks the same as without (within 1% on our test scenes) "
                    "and saves up to 15% of the rays' time in renders, but costs a little in "
                    "the viewport on the CPU renderer we test on",
        default=GI.screen_trace)
    screen_hit: EnumProperty(
        name="Screen Hit Light",
        description="With Screen Trace: the light a ray that hits something on screen brings back",
        items=(("CACHE", "Surface Cache", "The light stored on the surface it hit, found and "
                "read by the distance fields as without the screen: the screen only skips the "
                "empty space before it"),
               ("COLOUR", "Screen Colour", "The image's own colour where it hit (Lumen's way "
                "in the lecture): sharper, but noisier and darker here")),
        default=GI.screen_hit)
    adaptive_probes: BoolProperty(
        name="Adaptive Probes",
        description="Where the regular probes cannot light a pixel (edges, small objects), place "
                    "extra, denser probes there instead of tracing rays for each such pixel",
        default=GI.adaptive_probes)
    probe_importance: BoolProperty(
        name="Importance Sampling",
        description="Experimental: probes send more of their rays where last frame's light and "
                    "the surfaces around them say it matters. Off by default: less noise near "
                    "bright spots, but measured slightly worse in a room lit by one small emitter",
        default=GI.probe_importance)
    ssgi_rays: IntProperty(
        name="SSGI Rays per Pixel",
        description="Rays each pixel sends per frame to find bounced light on screen. More is "
                    "less noisy and proportionally slower (neighbouring pixels' rays are shared "
                    "as well)",
        default=METHOD.ssgi_rays, min=1, max=32)
    ssgi_steps: IntProperty(
        name="SSGI Steps",
        description="How far a ray may search across the screen before it gives up. More finds "
                    "light from farther away and takes longer; fewer misses distant bounces "
                    "(Lumen's screen trace uses 50)",
        default=METHOD.ssgi_steps, min=4, max=256)
    ssgi_thickness: FloatProperty(
        name="SSGI Thickness",
        description="How thick objects are assumed to be behind what the screen shows. Too "
                    "thin lets bounced light slip behind objects; too thick makes thin objects "
                    "block light like solid walls",
        default=METHOD.ssgi_thickness, min=0.001, soft_max=2.0, subtype='DISTANCE', unit='LENGTH')
    ssgi_reuse: IntProperty(
        name="SSGI Ray Reuse",
        description="How far neighbouring pixels share their rays, as a radius (1: 3x3 pixels). "
                    "Higher is smoother at no cost, but blurs the light in corners and where "
                    "objects touch",
        default=METHOD.ssgi_reuse, min=0, max=3)
    rsm_resolution: IntProperty(
        name="RSM Resolution",
        description="Detail of the picture each light keeps of what it lights, in texels per "
                    "side (a point light keeps six). Higher brings bounced light from smaller lit "
                    "details, at more GPU memory and time",
        default=METHOD.rsm_resolution, min=16, max=4096)
    rsm_samples: IntProperty(
        name="RSM Samples",
        description="Points of the lights' pictures each pixel collects bounced light from per "
                    "frame. More is smoother and slower (the original method used 400)",
        default=METHOD.rsm_samples, min=1, max=4096)
    lpv_cells: IntProperty(
        name="LPV Cells",
        description="Grid cells along the scene's longest side: more is sharper and leaks less "
                    "light through walls, but is slower and needs more iterations",
        default=METHOD.lpv_cells, min=4, max=128, soft_min=8, soft_max=64)
    lpv_iterations: IntProperty(
        name="LPV Iterations",
        description="How many cells the bounced light may travel; about twice LPV Cells lets it "
                    "cross the whole scene. More is slower",
        default=METHOD.lpv_iterations, min=0, max=256)
    lpv_occlusion: BoolProperty(
        name="LPV Occlusion",
        description="Let walls and objects block the spreading light; turn it off to see how far "
                    "the light leaks",
        default=METHOD.lpv_occlusion)
    vxgi_cones: IntProperty(
        name="VXGI Cones",
        description="Cones per pixel: one along the surface normal, the rest in a ring around "
                    "it. More are slower but miss small bright things less often",
        default=METHOD.vxgi_cones, min=1, max=32)
    vxgi_cone_angle: FloatProperty(
        name="VXGI Cone Angle",
        description="Width of each cone in degrees: wider is smoother but blurrier",
        default=METHOD.vxgi_cone_angle, min=5.0, max=180.0)
    vxgi_distance: FloatProperty(
        name="VXGI Distance",
        description="How far a cone travels before it takes the sky's light",
        default=METHOD.vxgi_distance, min=0.01, soft_max=100.0, subtype='DISTANCE', unit='LENGTH')
    vxgi_step: FloatProperty(
        name="VXGI Step",
        description="Step length, in cone widths, where nothing is near: smaller is slower and "
                    "misses thin things less often",
        default=METHOD.vxgi_step, min=0.1, max=4.0)
    vxgi_offset: FloatProperty(
        name="VXGI Offset",
        description="How far cones start off the surface, in the finest voxels: more avoids "
                    "surfaces darkening themselves, less keeps contact shadows",
        default=METHOD.vxgi_offset, min=0.0, soft_max=4.0)
    debug_view: EnumProperty(
        name="Debug View",
        description="Show one stage of the lighting instead of the finished image, to find out "
                    "where a problem comes from (Combined: the finished image)",
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
               ('LPV_GRID', "LPV Grid", "GI Method LPV: the light propagation volume's "
                "horizontal slices side by side, bottom slice first, as each cell's mean light"),
               ('VXGI_OCCLUSION', "VXGI Cone Occlusion", "GI Method VXGI: how much of each "
                "pixel's cones surfaces stopped (white) rather than the sky (black)"),
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
                "the cache off, Combined)"),
               ('TRACE_METHOD', "Trace Method", "Which trace served each pixel's rays: red the "
                "screen, green the mesh distance fields, blue the global distance field, black "
                "the sky (Lumen with Screen Trace on; else Combined)")),
        default='COMBINED')


class LumenLastBake(bpy.types.PropertyGroup):
    """What the last bake made (`scene.lumen.last_bake`); written by the bake and export
    operators only."""
    __slots__ = ()

    objects: IntProperty(name="Objects", description="Objects the last bake included", min=0)
    unique_meshes: IntProperty(
        name="Unique Meshes", min=0,
        description="Distinct shapes baked: copies and instances of one mesh share one")
    reused: IntProperty(
        name="Reused", min=0,
        description="Meshes taken unchanged from the bake before, which saved their bake time")
    bricks: IntProperty(
        name="Bricks", min=0,
        description="Blocks of shape samples kept near surfaces, all levels of detail: memory "
                    "grows with them")
    bytes: IntProperty(name="Bytes", description="Memory of the baked shapes", min=0)
    cards: IntProperty(
        name="Cards", min=0,
        description="Surface patches that store the light on the objects' surfaces")
    texels: IntProperty(name="Texels", description="Texels of stored surface light in use", min=0)
    coverage: FloatProperty(
        name="Coverage", min=0.0, max=1.0, subtype='FACTOR',
        description="Share of the least-covered mesh's surface that stores light. Where none is "
                    "stored, bounced light from that part is missing")
    seconds: FloatProperty(name="Seconds", description="How long the last bake took", min=0.0)
    status: StringProperty(name="Status", description="Outcome of the last bake or export")


class LumenSceneSettings(bpy.types.PropertyGroup):
    """`scene.lumen`: the three groups."""
    __slots__ = ()

    bake: PointerProperty(type=LumenBakeSettings, name="Bake",
                          description="What the bake makes and where it keeps it")
    engine: PointerProperty(type=LumenEngineSettings, name="Engine",
                            description="How the Lumen GI engine renders, viewport and final")
    last_bake: PointerProperty(type=LumenLastBake, name="Last Bake",
                               description="What the last bake made")


class LumenObjectSettings(bpy.types.PropertyGroup):
    __slots__ = ()

    two_sided: BoolProperty(
        name="Two Sided",
        description="For thin open surfaces with no inside (leaves, paper, single-sided walls): "
                    "baked as a thin sheet that still blocks light. Leave off for closed "
                    "objects, whose inside is then known, so light cannot leak through them",
        default=OBJECT["two_sided"])
    resolution_scale: FloatProperty(
        name="Resolution Scale",
        description="Detail of this object's baked shape relative to the Voxel Density: above 1 "
                    "for small or intricate objects that leak light or lose shadows, below 1 for "
                    "large plain ones, to save bake time and memory",
        default=OBJECT["resolution_scale"], min=0.01, max=16.0)


_CLASSES = (LumenBakeSettings, LumenEngineSettings, LumenLastBake, LumenSceneSettings,
            LumenObjectSettings)


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
