"""F12's surface-cache tile share (GISettings.render_sc_fraction, surface_cache_pages.seen):
tiles the view reads are relit every iteration, a share of the rest by priority. In a closed room
every inner wall sees the others, so the render relights them every iteration (only the slabs'
outer faces, which nothing inside sees, get the share) and matches the every-tile render within
0.5% (no bounce lost indoors); on an open ground around a box, the ground far from
the box is relit less often, and the image stays within 3% of the every-tile render."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import dataclasses
from lumen_gi.gpu_shaders import engine, gi_settings

SHARE = {"f": None}
original = gi_settings.from_scene
gi_settings.from_scene = lambda s, viewport=False: (
    original(s, viewport) if SHARE["f"] is None
    else dataclasses.replace(original(s, viewport), render_sc_fraction=SHARE["f"]))

def camera(location, target, lens=18.0):
    aimed_camera(location, target).data.lens = lens

def render(f):
    SHARE["f"] = f
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    return R["combined"][..., :3], R["position"][..., 3] > 0.5, list(R["gi_sc_tiles"]), \\
        R["gi_iterations"]

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 32
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 2
scene.lumen.engine.bounces = 2
scene.lumen.engine.converge_bounces = False   # the iterations this test counts
scene.lumen.engine.noise_threshold = 0.0
w_ = bpy.data.worlds.new("World")
scene.world = w_
w_.use_nodes = True
bg = w_.node_tree.nodes["Background"]
if MODE == "room":
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    closed_room(principled("Wall", (0.8, 0.8, 0.8), emission=(1.0, 1.0, 1.0), strength=0.2))
    camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
else:
    bg.inputs["Color"].default_value = (0.8, 0.9, 1.0, 1.0)      # a uniform sky
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, -0.25))
    g = bpy.context.object
    g.scale = (12.0, 12.0, 0.5)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    g.data.materials.append(principled("Ground", (0.5, 0.5, 0.5)))
    b = cube("Box", 1.0, (0.0, 0.0, 0.5))
    b.data.materials.append(principled("Box", (0.8, 0.3, 0.2)))
    camera((2.5, -2.5, 1.8), (0.0, 0.0, 0.4), lens=24.0)
res, err = bake()
assert err is None, err
out = {}
for name, f in (("all", 1.0), ("share", None)):
    img, hit, tiles, its = render(f)
    np.save(name + ".npy", img)
    np.save("hit.npy", hit)
    out[name] = dict(tiles=tiles, iterations=its)
emit(**out)
"""


def _run(tmp_path, mode):
    run = run_python(f"MODE = {mode!r}\n" + SNIPPET, tmp_path, timeout=900)
    assert run.returncode == 0, run.explain()
    hit = np.load(tmp_path / "hit.npy")
    return run.result, np.load(tmp_path / "all.npy")[hit], np.load(tmp_path / "share.npy")[hit]


def test_a_closed_room_relights_its_inner_walls_every_iteration(tmp_path):
    r, every, share = _run(tmp_path, "room")
    relit, total = r["share"]["tiles"]
    diff = np.abs(share - every) / np.maximum(every, 1e-3)
    print(f"room: {relit} tile relights of {total} tiles x {r['share']['iterations']} "
          f"iterations; mean {share.mean():.4f} (every tile: {every.mean():.4f}), "
          f"pixel |diff| max {diff.max():.4f}")
    assert r["share"]["iterations"] == 3
    assert r["all"]["tiles"] == [3 * total, total]
    # the slabs' outer faces (tiles of those cards alone) are seen by nothing inside: a share
    assert 0.85 * 3 * total <= relit < 3 * total
    assert abs(share.mean() / every.mean() - 1.0) < 0.005     # no bounce lost
    assert diff.max() < 1e-3                              # the outer faces: read by nothing


def test_an_open_ground_relights_its_far_tiles_less(tmp_path):
    r, every, share = _run(tmp_path, "ground")
    relit, total = r["share"]["tiles"]
    print(f"ground: {relit} tile relights of {total} tiles x 3; mean {share.mean():.4f} "
          f"(every tile: {every.mean():.4f})")
    assert r["all"]["tiles"] == [3 * total, total]
    assert total < relit < 0.8 * 3 * total            # the first iteration lights every tile
    assert abs(share.mean() / every.mean() - 1.0) < 0.03
    assert np.abs(share - every).mean() < 0.05 * every.mean()
