"""Lumen's first trace on the screen (gpu_shaders/screen_trace.py, glsl/screen_trace_lib.glsl,
glsl/lumen_trace_lib.glsl; llvmpipe through bpy, F12).

- Closed room (every wall albedo 0.5, emitting 0.5, black world; the camera inside): every ray
  of every pixel hits a wall, so the TRACE_METHOD view's shares (screen red, mesh SDF green,
  global SDF blue) add up to exactly 1 on every pixel, and the screen serves a real part of them.
  The room's Diffuse Indirect with the screen trace is the same as without it (mean within 2%,
  95% of pixels within 10%): the screen changes where a ray's SDF trace starts, not what it
  reads (with the surface cache's hits, default: within 0.5% in the mean, 95% within 2%).
- Open floor under a white sky, nothing else: every ray leaves into the sky, so no trace serves
  any ray (all shares exactly 0), and the floor's indirect light is the same with and without.
- A closed room whose roof is hidden from the camera (visible_camera off), under a white sky,
  seen from above through that roof: the depth buffer does not hold the roof, so it vouches
  for the space the roof fills; without the hidden-object guard (lumen_trace_lib.glsl) rays
  leaving the room upwards found the sky (the quality bench's `thin` leaked 37%). Inside, the
  indirect light with the screen trace stays as dark as without it.
- An emitting wall (albedo 0, Le) beside a black floor: the rays that find the wall on screen
  read its emission; the floor's indirect light agrees with the SDF-only trace within 5% in the
  mean (what the wall gives the floor: pi Le times its form factor, either way).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import mathutils
from lumen_gi.gpu_shaders import engine

def camera(location, target, lens=18.0):
    cam = aimed_camera(location, target)
    cam.data.lens = lens
    return cam

def world(colour):
    w = bpy.data.worlds.new("World")
    bpy.context.scene.world = w
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)

def render(name, screen, view="COMBINED", hit="CACHE"):
    scene = bpy.context.scene
    scene.lumen.engine.screen_trace = screen
    scene.lumen.engine.screen_hit = hit
    scene.lumen.engine.debug_view = view
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if view == "COMBINED":
        np.save(f"{name}_{screen}{'_colour' if hit == 'COLOUR' else ''}_indirect.npy",
                R["indirect"])
        np.save(f"{name}_position.npy", R["position"])
        out[f"{name}_{screen}"] = dict(gi=R["gi_timings"], memory=R["gpu_bytes"])
    else:
        np.save(f"{name}_{view}.npy", R["shown"])

def setup(size=48, frames=2, bounces=2):
    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.lumen.engine.render_quality = "LOW"
    scene.lumen.engine.render_frames = frames
    scene.lumen.engine.bounces = bounces
    res, err = bake()
    assert err is None, err

out = {}
# 1. closed room
scene = empty_scene(voxel_density=10.0, cache_dir="room")
mat = principled("Wall", (0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0), strength=0.5)
closed_room(mat)
world((0.0, 0.0, 0.0))
camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
setup(bounces=4)
render("room", True)
render("room", True, hit="COLOUR")
render("room", True, "TRACE_METHOD")
render("room", False)

# 2. open floor under a white sky
scene = empty_scene(voxel_density=10.0, cache_dir="floor")
bpy.ops.mesh.primitive_plane_add(size=8.0)
bpy.context.object.data.materials.append(principled("Floor", (0.0, 0.0, 0.0)))
world((1.0, 1.0, 1.0))
camera((3.0, -2.5, 2.5), (0.0, 0.0, 0.0), lens=30.0)
setup()
render("floor", True)
render("floor", True, "TRACE_METHOD")
render("floor", False)

# 3. an emitting wall beside a black floor, black world
scene = empty_scene(voxel_density=10.0, cache_dir="wall")
bpy.ops.mesh.primitive_plane_add(size=8.0)
bpy.context.object.data.materials.append(principled("Floor", (0.0, 0.0, 0.0)))
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-1.05, 0.0, 1.0))
wall = bpy.context.object
wall.scale = (0.1, 3.0, 2.0)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
wall.data.materials.append(principled("Glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0),
                                      strength=2.0))
world((0.0, 0.0, 0.0))
camera((3.0, -2.5, 2.5), (-0.5, 0.0, 0.5), lens=30.0)
setup()
render("wall", True)
render("wall", True, hit="COLOUR")
render("wall", True, "TRACE_METHOD")
render("wall", False)

# 4. a closed room whose roof the camera does not see, under a white sky, seen from above
scene = empty_scene(voxel_density=10.0, cache_dir="roof")
walls = closed_room(principled("Wall", (0.5, 0.5, 0.5)))
next(w for w in walls if w.name == "Wall2+").visible_camera = False
world((1.0, 1.0, 1.0))
camera((0.0, -0.05, 5.0), (0.0, 0.0, -1.0), lens=50.0)
setup()
render("roof", True)
render("roof", False)
emit(**out)
"""


def _load(tmp_path, name):
    on = np.load(tmp_path / f"{name}_True_indirect.npy")[..., :3].mean(-1)
    off = np.load(tmp_path / f"{name}_False_indirect.npy")[..., :3].mean(-1)
    shares = np.load(tmp_path / f"{name}_TRACE_METHOD.npy")[..., :3]
    hit = np.load(tmp_path / f"{name}_position.npy")[..., 3] > 0.5
    return on, off, shares, hit


def _colour(tmp_path, name):
    """The screen trace's indirect light with screen_hit COLOUR (the lecture's screen colour)."""
    return np.load(tmp_path / f"{name}_True_colour_indirect.npy")[..., :3].mean(-1)


def test_screen_trace(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=900)
    assert run.returncode == 0, run.explain()
    for k, v in run.result.items():
        print(k, {p: round(s, 3) for p, s in v["gi"].items()})

    on, off, shares, hit = _load(tmp_path, "room")
    assert hit.all()
    total = shares.sum(-1)
    print("room shares (screen, mesh, global):", shares.reshape(-1, 3).mean(0))
    np.testing.assert_allclose(total, 1.0, atol=1e-6)      # every ray served by one trace
    assert shares[..., 0].mean() > 0.25                    # the screen serves a real part
    colour = _colour(tmp_path, "room")
    print("room indirect on (cache, colour)/off:", on.mean(), colour.mean(), off.mean(),
          "pixels within 2%:", (np.abs(on - off) <= 0.02 * off).mean())
    for x in (on, colour):
        assert abs(x.mean() - off.mean()) <= 0.02 * off.mean()
        assert (np.abs(x - off) <= 0.1 * off).mean() >= 0.95
    # a hit's light from the surface cache: the SDF trace's own light, pixel by pixel
    assert abs(on.mean() - off.mean()) <= 0.005 * off.mean()
    assert (np.abs(on - off) <= 0.02 * off).mean() >= 0.95

    on, off, shares, hit = _load(tmp_path, "floor")
    assert hit.mean() > 0.3
    np.testing.assert_array_equal(shares[hit], 0.0)        # every ray leaves into the sky
    print("floor indirect on/off:", on[hit].mean(), off[hit].mean())
    assert off[hit].mean() > 0.5                           # the sky's light is there
    assert abs(on[hit].mean() - off[hit].mean()) <= 0.01 * off[hit].mean()

    on, off, shares, hit = _load(tmp_path, "wall")
    pos = np.load(tmp_path / "wall_position.npy")
    floor = hit & (np.abs(pos[..., 2]) < 1e-3) & (pos[..., 0] > -0.9) & (pos[..., 0] < 2.0)
    assert floor.mean() > 0.1
    print("wall: floor shares", shares[floor].mean(0), "indirect on/off:", on[floor].mean(),
          off[floor].mean())
    assert shares[floor][:, 0].mean() > 0.05               # the wall is found on screen
    colour = _colour(tmp_path, "wall")
    print("wall: floor indirect colour:", colour[floor].mean())
    for x in (on, colour):
        assert abs(x[floor].mean() - off[floor].mean()) <= 0.05 * off[floor].mean()

    on = np.load(tmp_path / "roof_True_indirect.npy")[..., :3].mean(-1)
    off = np.load(tmp_path / "roof_False_indirect.npy")[..., :3].mean(-1)
    pos = np.load(tmp_path / "roof_position.npy")
    hit = pos[..., 3] > 0.5
    inside = hit & (np.abs(pos[..., 0]) < 1.45) & (np.abs(pos[..., 1]) < 1.15) \
        & (pos[..., 2] < 0.95)
    assert inside.mean() > 0.2
    print("roof: inside indirect on/off:", on[inside].mean(), off[inside].mean())
    assert off[inside].mean() < 0.05                       # closed: no light gets in
    assert on[inside].mean() <= off[inside].mean() + 0.02  # nor through the hidden roof


VIEWPORT = """
import viewport_harness
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="still")
closed_room(principled("Wall", (0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0), strength=0.5))
box = cube("Box", 0.4, (0.3, 0.2, -0.8))
box.data.materials.append(principled("Box", (0.8, 0.2, 0.2)))
aimed_camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 32
scene.render.resolution_percentage = 100
scene.render.preview_pixel_size = "1"
scene.lumen.engine.viewport_quality = "LOW"
scene.lumen.engine.screen_trace = True
res, err = bake()
assert err is None, err

def state(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if i == 1:
        box.location.x -= 0.3              # reaches redraw 2
    return dict(gbuffer=R["gbuffer_reused"], draws=R["gbuffer_draws"],
                hzb=R["gi_screen_hzb_reused"], changes=R["changes"])

out = viewport_harness.run(scene, engine.LumenGIRenderEngine, 32, 32, 4, state)
emit(frames=out["after"])
"""


def test_still_viewport_keeps_its_gbuffer_and_hzb(tmp_path):
    """A still viewport's redraws draw no G-buffer and build no HZB: the last redraw's are the
    same view of the same instances (mesh_batches.MeshBatches.draw, ScreenTrace's `previous`).
    A moved object draws both again."""
    run = run_python(VIEWPORT, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    f = run.result["frames"]
    print(f)
    assert not f[0]["gbuffer"] and f[0]["draws"] > 0 and f[0]["hzb"] is False
    assert f[1]["gbuffer"] and f[1]["draws"] == 0 and f[1]["hzb"] is True
    assert "objects" in f[2]["changes"], f[2]
    assert not f[2]["gbuffer"] and f[2]["draws"] > 0 and f[2]["hzb"] is False
    assert f[3]["gbuffer"] and f[3]["hzb"] is True
