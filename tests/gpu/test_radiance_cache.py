"""World radiance cache (gpu_shaders/radiance_cache.py) through F12 renders of the LUMEN_GI
engine (llvmpipe in a bpy subprocess), against exact answers. The cache is switched on by
patching gi_settings.from_scene (the scene has no property for it yet); gi.indirect_light is
wrapped to read the cache back after every GI call (tests only: read-backs).

- Uniform sky L = 1, a sphere of albedo 0.8 and nothing else: every traced probe texel whose rays
  all missed holds exactly L (its hits' light 0 + its sky share 1 x L); the sphere's radiance is 0.8 L within 2% (the white furnace of
  test_gi.py, the far field now from the cache) and most screen-probe rays were served by it.
- A probe beside a wall that emits Le (albedo 0) and a black sky: its texels pointing at the
  wall hold Le (within 3%: the voxel lighting / surface cache at the hits), those pointing away 0.
- test_gi.py's closed room (walls emit 0.5, albedo 0.5, converged L = 1): with and without the
  cache the image's mean agrees within 3%.
- A closed box of thin walls (thinner than a voxel) in a bright sky, its inside lit by nothing:
  probes outside the walls exist and see the sky, yet the inside's indirect light stays under
  1% of the sky (no leak), as without the cache.
- The budget: 8 view_draw redraws of a still camera (tools/viewport_harness.py) trace exactly
  rc_budget probes per frame, new probes first, at most rc_retrace (8) old ones (the screen probes' jittered placement keeps
  adding cells over the first 16 frames, so new ones keep coming here).
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
                          miss=data["miss"],
                          spacing=rc.spacing))
    return out
gi.indirect_light = _wrapped

def finish(size, quality="LOW", frames=4, bounces=8):
    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.lumen.engine.render_quality = quality
    scene.lumen.engine.render_frames = frames
    scene.lumen.engine.bounces = bounces
    if not RC.get("baked"):
        res, err = bake()
        assert err is None, err
        RC["baked"] = True
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
    np.save(prefix + "_miss.npy", r["miss"][traced])
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
scene.lumen.engine.debug_view = "RADIANCE_CACHE"
R = finish(48, frames=1, bounces=1)
np.save("view.npy", R["shown"])
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
    miss = np.load(tmp_path / "furnace_miss.npy")
    missed = atlas[..., 3] >= 99.0                          # every ray of the texel left (t_max)
    assert missed.mean() > 0.5
    # the texel's radiance: its hits' light + its sky share x L (1): exactly L
    np.testing.assert_array_equal(atlas[missed][:, :3] + miss[missed][:, None] * 1.0, 1.0)
    assert slots[:, 3].min() >= 1
    img = np.load(tmp_path / "combined.npy")[..., :3]
    hit = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    lum = img.mean(axis=-1)
    print(lum[hit].mean(), np.percentile(lum[hit], [1, 5, 50, 95, 99]))
    assert abs(lum[hit].mean() - 0.8) <= 0.02 * 0.8
    assert (np.abs(lum[hit] - 0.8) <= 0.05 * 0.8).mean() >= 0.95
    view = np.load(tmp_path / "view.npy")                  # the RADIANCE_CACHE debug view
    served = hit & (view[..., 1] == 1.0)                    # (magenta: no probe, green 0)
    print("view served", served.sum() / hit.sum())
    assert served.sum() >= 0.5 * hit.sum()
    np.testing.assert_array_equal(view[served][:, :3], 1.0)     # the sky's L, exactly


def texel_dirs():
    sys.path.insert(0, str(HERE.parents[1]))
    from gpu_shaders.probe_math import oct_texel_dirs
    return oct_texel_dirs(8)                                # [y, x, 3], the atlas' [ty, tx]


LE = 0.7
WALL = COMMON + f"""
scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(2.0, 0.0, 0.0))
wall = bpy.context.object
wall.scale = (1.0, 8.0, 8.0)                # front face x = 1.5, 8 x 8 m
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
wall.data.materials.append(principled("Wall", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0),
                                      strength={LE}))
bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.25)
bpy.context.object.data.materials.append(principled("Ball", (0.5, 0.5, 0.5)))
world((0.0, 0.0, 0.0))
camera((-2.5, 0.0, 0.3), (0.0, 0.0, 0.0), lens=50.0)
R = finish(48, frames=2, bounces=2)
used, traced = save_last("wall")
emit(used=used, traced=traced, served=READS[-1]["served"])
"""


def test_probe_beside_emitting_wall_sees_it_in_the_right_texels(tmp_path):
    run = run_python(WALL, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    print(run.result)
    atlas = np.load(tmp_path / "wall_atlas.npy")           # [probes, 8, 8, 4]
    slots = np.load(tmp_path / "wall_slots.npy")
    spacing = 0.577 * 2.0 ** (slots[:, 3] - 1)
    pos = (slots[:, :3] + 0.5) * spacing[:, None]
    dirs = texel_dirs()
    toward = dirs[..., 0] > 0.7                             # at the wall (x = 1.5, 8 x 8 m)
    away = dirs[..., 0] < -0.3                              # the black sky
    near = (pos[:, 0] > 0.0) & (pos[:, 0] < 1.2) & (np.abs(pos[:, 1:]).max(axis=1) < 1.2)
    assert near.sum() >= 2, pos
    seen = atlas[near][:, toward]                           # [probes * texels, 4]
    lum = seen[..., :3].mean(axis=-1)
    print(np.percentile(lum, [0, 5, 50, 95, 100]), seen[..., 3].min(), seen[..., 3].max())
    assert abs(np.median(lum) - LE) <= 0.02 * LE
    assert (np.abs(lum - LE) <= 0.05 * LE).mean() >= 0.95
    assert (seen[..., 3] < 1.6).all()                      # they hit the wall, within 1.5 m
    back = atlas[near][:, away]
    missed = back[..., 3] >= 99.0                           # (the others met the sphere)
    assert missed.mean() > 0.6
    np.testing.assert_array_equal(back[missed][:, :3], 0.0)


ROOM = COMMON + """
scene = empty_scene(voxel_density=10.0, cache_dir="cache")
mat = principled("Wall", (0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0), strength=0.5)
closed_room(mat)
world((0.0, 0.0, 0.0))
camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
out = {}
for on in (False, True):
    RC["on"] = on
    R = finish(48)
    np.save(f"room_{int(on)}.npy", R["combined"])
    out[str(on)] = R["gi_timings"]["probes"]
emit(probes_seconds=out, served=READS[-1]["served"], traced=READS[-1]["traced"])
"""


def test_closed_room_same_with_and_without_the_cache(tmp_path):
    run = run_python(ROOM, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    off = np.load(tmp_path / "room_0.npy")[..., :3].mean(axis=-1)
    on = np.load(tmp_path / "room_1.npy")[..., :3].mean(axis=-1)
    expected = 0.5 / (1.0 - 0.5) * (1.0 - 0.5 ** 10)
    print(run.result, off.mean(), on.mean(), np.percentile(np.abs(on - off), [50, 95, 99]))
    assert run.result["served"] > 0.02                     # some rays crossed the room: cache
    assert abs(on.mean() - off.mean()) <= 0.03 * off.mean()
    assert abs(on.mean() - expected) <= 0.03 * expected
    assert (np.abs(on - expected) <= 0.1 * expected).mean() >= 0.95


BOX = COMMON + """
scene = empty_scene(voxel_density=10.0, cache_dir="cache")
mat = principled("Wall", (0.7, 0.7, 0.7))
half, t = (3.0, 3.0, 1.5), 0.04                  # walls of 0.04 m: thinner than a 0.1 m voxel
for axis in range(3):
    for sign in (-1.0, 1.0):
        size = [2 * h + 2 * t for h in half]
        size[axis] = t
        loc = [0.0, 0.0, 0.0]
        loc[axis] = sign * (half[axis] + t / 2)
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=loc)
        ob = bpy.context.object
        ob.scale = size
        bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
        ob.data.materials.append(mat)
world((1.0, 1.0, 1.0))
camera((-2.2, -2.2, -0.6), (1.0, 1.0, 0.0), lens=16.0)
out = {}
for on in (True, False):
    RC["on"] = on
    R = finish(48, frames=2, bounces=2)
    np.save(f"box_{int(on)}.npy", R["combined"])
    if on:
        used, traced = save_last("box")
        out.update(served=READS[-1]["served"], used=used, traced=traced)
emit(**out)
"""


def test_no_leak_into_a_closed_box_from_probes_outside(tmp_path):
    run = run_python(BOX, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    atlas = np.load(tmp_path / "box_atlas.npy")
    slots = np.load(tmp_path / "box_slots.npy")
    pos = (slots[:, :3] + 0.5) * (0.577 * 2.0 ** (slots[:, 3] - 1))[:, None]
    outside = (np.abs(pos) > np.array([3.0, 3.0, 1.5]) + 0.04).any(axis=1)
    sky = ((atlas[..., 3] >= 99.0) & (np.load(tmp_path / "box_miss.npy") == 1.0)).any(axis=(1, 2))
    on = np.load(tmp_path / "box_1.npy")[..., :3].mean(axis=-1)
    off = np.load(tmp_path / "box_0.npy")[..., :3].mean(axis=-1)
    print(run.result, (outside & sky).sum(), on.mean(), off.mean(), np.percentile(on, [50, 99]))
    assert run.result["served"] > 0.1                      # rays across the box used the cache
    assert (outside & sky).sum() >= 4                      # probes outside the walls see the sky
    assert on.mean() < 0.01 and np.percentile(on, 99) < 0.05    # yet nothing leaks in
    assert off.mean() < 0.01


BUDGET = COMMON + """
import viewport_harness
RC["budget"] = 12
RC["read"] = False
from lumen_gi.gpu_shaders import radiance_cache, compute
LOG = []
_update = radiance_cache.RadianceCache.update
def update(self, *args, **kw):
    _update(self, *args, **kw)
    data = self.read()
    used = data["slots"][:, 3] > 0
    entries = compute.read(self.list).reshape(-1, 4)
    LOG.append(dict(traced=self.traced_count(), used=int(used.sum()),
                    fresh=int(((entries[:, 0] >= 0) & (entries[:, 1] > 0.5)).sum()),
                    never=int((used & (data["state"][:, 0] == 0)).sum()),
                    now=int((used & (data["state"][:, 0] == self.last["frame"] + 1)).sum())))
radiance_cache.RadianceCache.update = update
scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=8.0)
bpy.context.object.data.materials.append(principled("Floor", (0.5, 0.5, 0.5)))
bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.5, location=(0, 0, 0.5))
world((1.0, 1.0, 1.0))
camera((0.0, -4.0, 2.0), (0.0, 0.0, 0.3), lens=30.0)
res, err = bake()
assert err is None, err
scene.lumen.engine.viewport_quality = "LOW"
viewport_harness.run(scene, engine.LumenGIRenderEngine, 64, 64, redraws=8)
emit(log=LOG)
"""


def test_budget_new_probes_first_then_the_oldest(tmp_path):
    sys.path.insert(0, str(HERE.parents[1] / "tools"))
    run = run_python(BUDGET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    log = run.result["log"]
    print(log)
    assert len(log) == 8
    assert log[0]["used"] > 3 * 12                          # more probes than one frame's budget
    for cur in log:
        assert cur["traced"] == min(12, cur["used"])       # the budget, no more
        assert cur["now"] == cur["traced"]                 # (stamped by the trace pass)
        waiting = cur["never"] + cur["fresh"]              # new probes before this frame's trace
        assert cur["fresh"] == min(12, waiting)            # new probes first
        assert cur["traced"] - cur["fresh"] <= 8           # then at most rc_retrace old ones
    assert log[0]["never"] == log[0]["used"] - 12
