"""World radiance cache (gpu_shaders/radiance_cache.py) through F12 renders of the LUMEN_GI
engine (llvmpipe in a bpy subprocess), against exact answers. The cache is switched on by
patching gi_settings.from_scene (the scene has no property for it yet); gi.indirect_light is
wrapped to read the cache back after every GI call (tests only: read-backs).

- Uniform sky L = 1, a sphere of albedo 0.8 and nothing else: every traced probe texel whose rays
  all missed holds exactly L; the sphere's radiance is 0.8 L within 2% (the white furnace of
  test_gi.py, the far field now from the cache) and most screen-probe rays were served by it.
- A probe beside a wall that emits Le (albedo 0) and a black sky: its texels pointing at the
  wall hold Le (within 3%: the voxel lighting / surface cache at the hits), those pointing away 0.
- test_gi.py's closed room (walls emit 0.5, albedo 0.5, converged L = 1): with and without the
  cache the image's mean agrees within 3%.
- A closed box of thin walls (thinner than a voxel) in a bright sky, its inside lit by nothing:
  probes outside the walls exist and see the sky, yet the inside's indirect light stays under
  1% of the sky (no leak), as without the cache.
- The budget: a viewport-like frame sequence traces at most rc_budget probes per frame, new
  probes first, and a still camera's later frames trace only the budget.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

COMMON = """
import dataclasses
import mathutils
from lumen_gi.gpu_shaders import engine, gi, gi_settings

RC = {"on": True, "budget": 64}
READS = []
_original_settings = gi_settings.from_scene
gi_settings.from_scene = lambda s, viewport=False: dataclasses.replace(
    _original_settings(s, viewport), radiance_cache=RC["on"], rc_budget=RC["budget"])
_original_gi = gi.indirect_light

def _wrapped(state, *args, **kw):
    out = _original_gi(state, *args, **kw)
    rc = state.radiance_cache
    if RC["on"] and rc is not None and RC.get("read", True):
        data = rc.read()
        from lumen_gi.gpu_shaders import compute
        alpha = compute.read(state.probes.textures["radiance"])[..., 3]
        rays = alpha >= 0
        READS.append(dict(traced=rc.traced_count(), budget=rc.last["budget"],
                          served=float((alpha > args[5] + 0.5).sum() / max(rays.sum(), 1)),
                          slots=data["slots"], state=data["state"], atlas=data["atlas"],
                          spacing=rc.spacing))
    return out
gi.indirect_light = _wrapped

def finish(size, quality="LOW", frames=4, bounces=8):
    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.lumen.gi_quality = quality
    scene.lumen.render_frames = frames
    scene.lumen.bounces = bounces
    if not getattr(bpy.context.scene, "_baked", False):
        res, err = bake()
        assert err is None, err
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    return R

def camera(location, target, lens=18.0):
    cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
    bpy.context.scene.camera = cam
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = lens
    return cam

def world(colour):
    w = bpy.data.worlds.new("World")
    bpy.context.scene.world = w
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0

def save_last(prefix):
    r = READS[-1]
    used = r["slots"][:, 3] > 0
    traced = used & (r["state"][:, 0] > 0)
    np.save(prefix + "_slots.npy", r["slots"][traced])
    np.save(prefix + "_atlas.npy", r["atlas"][traced])
    return int(used.sum()), int(traced.sum())
"""

FURNACE = COMMON + """
scene = empty_scene(voxel_density=24.0, cache_dir="cache")
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.6)
ball = bpy.context.object
ball.data.materials.append(principled("Ball", (0.8, 0.8, 0.8)))
world((1.0, 1.0, 1.0))
camera((0.0, -3.0, 0.8), (0.0, 0.0, 0.0), lens=50.0)
R = finish(48, frames=4, bounces=2)
np.save("combined.npy", R["combined"])
np.save("position.npy", R["position"])
used, traced = save_last("furnace")
emit(used=used, traced=traced, per_frame=[r["traced"] for r in READS],
     served=READS[-1]["served"],
     bytes={k: v for k, v in R["gpu_bytes"].items() if k.startswith("radiance")})
"""


def test_uniform_sky_probe_texels_and_furnace(tmp_path):
    run = run_python(FURNACE, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    print(run.result)
    assert run.result["traced"] > 8                        # the cache was used
    assert run.result["served"] > 0.3                      # rays served by it (the rest hit)
    atlas = np.load(tmp_path / "furnace_atlas.npy")
    slots = np.load(tmp_path / "furnace_slots.npy")
    missed = atlas[..., 3] >= 99.0                          # every ray of the texel left (t_max)
    assert missed.mean() > 0.5
    np.testing.assert_array_equal(atlas[missed][:, :3], 1.0)   # exact: the sky's L
    assert slots[:, 3].min() >= 1
    img = np.load(tmp_path / "combined.npy")[..., :3]
    hit = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    lum = img.mean(axis=-1)
    print(lum[hit].mean(), np.percentile(lum[hit], [1, 5, 50, 95, 99]))
    assert abs(lum[hit].mean() - 0.8) <= 0.02 * 0.8
    assert (np.abs(lum[hit] - 0.8) <= 0.05 * 0.8).mean() >= 0.95
