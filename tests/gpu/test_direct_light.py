"""Direct light of the LUMEN_GI engine (G-buffer + SDF cone-traced shadows, llvmpipe) against
Cycles' Diffuse Direct pass (CPU), one light type at a time, in one bpy subprocess.

Scene: a 4 x 4 x 0.1 m floor and a rotated 1 m box, white-ish Principled materials with no
specular layer (Specular IOR Level 0: a pure Lambert BSDF), black world, 64 x 64 pixels; then
the same with no light and Blender's bundled courtyard.exr as the world (GI Off: the sky light of
the direct pass, SDF-occluded, against Cycles with no bounces). Cycles:
128 samples, no denoiser, no adaptive sampling, pixel filter 0.01 px (point samples at the pixel
centres, like our G-buffer with anti-aliasing off). Both engines write multilayer EXRs; the DiffDir passes are compared
with relMSE = mean((ours - ref)^2 / (ref^2 + 0.01)) over all pixels and channels.
"""
import sys
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402

SIZE = 64
LIGHTS = ("SUN", "POINT", "SPOT", "AREA", "TUNED", "FANNED", "HDRI")
LIMIT = 0.05
# Measured relMSE above the limit: {light type: reason} (xfail, non-strict).
KNOWN_MISSES = {}

SNIPPET = f"""
import math, time
import mathutils
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, -0.05))
floor = bpy.context.object
floor.name = "Floor"
floor.scale = (4.0, 4.0, 0.1)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
box = cube("Box", 1.0, (0.2, 0.3, 0.5))
box.rotation_euler = (0.0, 0.0, 0.5)
for obj, base in ((floor, (0.8, 0.8, 0.8)), (box, (0.7, 0.75, 0.8))):
    mat = principled(obj.name + "Mat", base)
    mat.node_tree.nodes["Principled BSDF"].inputs["Specular IOR Level"].default_value = 0.0
    obj.data.materials.append(mat)
scene.world = bpy.data.worlds.new("World")
scene.world.color = (0.0, 0.0, 0.0)
bg = scene.world.node_tree.nodes.get("Background") if scene.world.node_tree else None
if bg is not None:
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
scene.camera = cam
cam.location = (2.2, -4.2, 3.6)
cam.rotation_euler = (mathutils.Vector((0.0, 0.2, 0.3)) - cam.location).to_track_quat("-Z", "Y").to_euler()
cam.data.lens = 35.0
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
t = time.perf_counter()
bake()
bake_seconds = time.perf_counter() - t

def aim(obj, target=(0.0, 0.0, 0.0)):
    obj.rotation_euler = (mathutils.Vector(target) - obj.location).to_track_quat("-Z", "Y").to_euler()

def hdri_world(name):
    # Blender's bundled HDRI as the world (Environment Texture -> Background): no light object
    import os
    folder = bpy.utils.system_resource('DATAFILES', path="studiolights/world")
    w = bpy.data.worlds.new(name)
    if w.node_tree is None:
        w.use_nodes = True
    env = w.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(os.path.join(folder, name))
    w.node_tree.links.new(env.outputs["Color"], w.node_tree.nodes["Background"].inputs["Color"])
    return w

def make_light(kind):
    if kind == "HDRI":
        black = scene.world
        scene.world = hdri_world("courtyard.exr")
        scene.lumen.engine.render_quality = "OFF"   # the sky light is then Diffuse Direct, as in Cycles
        return black
    data = bpy.data.lights.new(kind, "AREA" if kind in ("TUNED", "FANNED") else kind)
    obj = link(bpy.data.objects.new(kind, data))
    if kind == "SUN":
        data.energy = 3.0
        obj.location = (-3.0, 2.0, 3.5)
    elif kind == "POINT":
        data.energy = 400.0
        data.shadow_soft_size = 0.1
        obj.location = (-1.5, 1.2, 2.5)
    elif kind == "SPOT":
        data.energy = 600.0
        data.shadow_soft_size = 0.1
        data.spot_size = math.radians(70.0)
        data.spot_blend = 0.3
        obj.location = (-1.5, -1.0, 3.0)
    elif kind == "AREA":
        data.energy = 150.0
        data.size = 0.5
        obj.location = (-1.0, 1.0, 2.8)
    elif kind == "FANNED":          # a gridded softbox: Spread 60 degrees
        data.energy = 150.0
        data.size = 0.5
        data.spread = math.radians(60.0)
        obj.location = (-1.0, 1.0, 2.8)
    else:               # an area light's other settings: Normalize off, Temperature, Exposure
        data.energy = 150.0 / 0.25 / 2.0 ** 0.5      # per m^2 of its 0.5 x 0.5 m, exposure 0.5
        data.size = 0.5
        data.normalize = False
        data.exposure = 0.5
        if hasattr(data, "use_temperature"):
            data.use_temperature = True
            data.temperature = 3500.0
        obj.location = (-1.0, 1.0, 2.8)
    aim(obj)
    return obj

scene.cycles.device = "CPU"
scene.cycles.samples = 128
scene.cycles.use_denoising = False
scene.cycles.use_adaptive_sampling = False
scene.cycles.max_bounces = 0
scene.cycles.filter_width = 0.01
scene.cycles.seed = 1
vl = scene.view_layers[0]
vl.use_pass_diffuse_direct = True
vl.use_pass_diffuse_color = True
vl.use_pass_normal = True
if hasattr(scene.render.image_settings, "media_type"):
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "32"
times = {{}}
notes = []
scene.lumen.engine.aa_samples = 1   # point samples at the pixel centres, as Cycles' 0.01 px filter
for kind in {LIGHTS!r}:
    light = make_light(kind)
    for eng in ("CYCLES", "LUMEN_GI"):
        scene.render.engine = eng
        scene.render.filepath = str(__import__("pathlib").Path(f"{{kind.lower()}}_{{eng.lower()}}.exr").resolve())
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        times[f"{{kind}}_{{eng}}"] = round(time.perf_counter() - t, 3)
        if eng == "LUMEN_GI":
            R = engine.LAST_RENDER
            assert "error" not in R, R.get("traceback", R.get("error"))
            notes.append(dict(kind=kind, passes=R["passes_written"], gbuffer=R["gbuffer_seconds"],
                              direct=R["direct_seconds"], shade=R["shade_seconds"],
                              triangles=R["triangles"]))
    if kind == "HDRI":
        scene.world = light
    else:
        bpy.data.objects.remove(light)
emit(times=times, bake_seconds=bake_seconds, engine=notes)
"""


def rel_mse(ours, ref):
    return float(np.mean((ours - ref) ** 2 / (ref ** 2 + 0.01)))


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("direct_light")
    start = time.perf_counter()
    run = run_python(SNIPPET, tmp, timeout=600)
    assert run.returncode == 0, run.explain()
    out = {"tmp": tmp, "result": run.result, "seconds": time.perf_counter() - start}
    for kind in LIGHTS:
        for eng in ("cycles", "lumen_gi"):
            path = tmp / f"{kind.lower()}_{eng}.exr"
            out[kind, eng] = read_pass(path, "Diffuse Direct")
            print(f"{kind} {eng}: {path}")
    print(f"run {out['seconds']:.1f} s; {run.result}")
    return out


@pytest.mark.parametrize("kind", LIGHTS)
def test_diffuse_direct_matches_cycles(renders, kind):
    ours, ref = renders[kind, "lumen_gi"], renders[kind, "cycles"]
    err = rel_mse(ours, ref)
    ratio = float(ours.sum() / max(ref.sum(), 1e-9))
    print(f"{kind}: relMSE {err:.4f} (limit {LIMIT}), sum ours/cycles {ratio:.3f}, "
          f"mean ours {ours.mean():.4f} cycles {ref.mean():.4f}")
    assert ref.mean() > 0.01                          # the light reaches what the camera sees
    if kind in KNOWN_MISSES and err > LIMIT:
        pytest.xfail(KNOWN_MISSES[kind])
    assert err <= LIMIT


def test_sun_shadow_of_the_box_is_dark(renders):
    """Floor pixels that Cycles shows in the box's shadow (away from the shadow's edge) are dark
    in ours, and the lit floor is lit in both."""
    ours, ref = renders["SUN", "lumen_gi"][..., 0], renders["SUN", "cycles"][..., 0]
    normal = read_pass(renders["tmp"] / "sun_cycles.exr", "Normal")
    floor = normal[..., 2] > 0.9
    shadow = floor & (ref < 0.01)
    core = shadow.copy()                     # two pixels in from the shadow's edge
    for _ in range(2):
        core[1:-1, 1:-1] &= (shadow[:-2, 1:-1] & shadow[2:, 1:-1]
                             & shadow[1:-1, :-2] & shadow[1:-1, 2:])
        shadow = core.copy()
    lit = floor & (ref > 0.3)
    y, x = np.argwhere(core)[len(np.argwhere(core)) // 2]
    print(f"shadow core {core.sum()} px, ours there max {ours[core].max():.4f} "
          f"mean {ours[core].mean():.4f}; pixel ({x}, {y}) ours {ours[y, x]:.4f} "
          f"cycles {ref[y, x]:.4f}; lit floor ours {ours[lit].mean():.3f} cycles {ref[lit].mean():.3f}")
    assert core.sum() >= 10 and lit.sum() >= 100
    assert ours[y, x] < 0.02
    assert ours[core].mean() < 0.02
    assert abs(ours[lit].mean() / ref[lit].mean() - 1.0) < 0.05
