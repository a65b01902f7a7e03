"""Incremental updates of the LUMEN_GI engine's GPU inputs (gpu_shaders/scene_state.py) across the
redraws of one viewport (tools/viewport_harness.py: the engine's view_draw, one engine instance
and its GPU state), in one bpy subprocess: a moved object re-uploads only the object table (no atlas upload, no re-bake) and the image
changes where it moved; a moved light re-uploads only the light rows; an unchanged scene, and a
re-bake with the same meshes, upload nothing; a new mesh after a re-bake uploads the atlas."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64

SNIPPET = f"""
import mathutils
from lumen_gi.gpu_shaders import engine, scene_state
from lumen_gi.operators import bake_op

scene = empty_scene(voxel_density=12.0, cache_dir="cache")
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, -0.05))
floor = bpy.context.object
floor.name = "Floor"
floor.scale = (4.0, 4.0, 0.1)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
box = cube("Box", 0.8, (-0.8, 0.0, 0.4))
other = cube("Other", 0.5, (1.0, 0.8, 0.25))
for obj, base in ((floor, (0.8, 0.8, 0.8)), (box, (0.9, 0.05, 0.05)), (other, (0.1, 0.1, 0.8))):
    obj.data.materials.append(principled(obj.name + "Mat", base))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.5, 0.3, 0.0)
point = link(bpy.data.objects.new("Point", bpy.data.lights.new("Point", "POINT")))
point.data.energy = 300.0
point.location = (0.5, -1.0, 2.0)
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
scene.camera = cam
cam.location = (0.0, -5.0, 4.0)
cam.rotation_euler = (mathutils.Vector((0.0, 0.0, 0.3)) - cam.location).to_track_quat("-Z", "Y").to_euler()
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 1
scene.lumen.engine.bounces = 1
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
baked = bake_op.LAST_BAKES[scene.name]
steps = {{}}
images = {{}}
import viewport_harness
LABELS = ("first", "again", "moved_object", "moved_light", "rebake_same", "rebake_new_mesh")

def step(i):
    # after redraw i: record what it uploaded, then make the edit the next redraw must see
    global baked
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    label = LABELS[i]
    steps[label] = dict(changes=R["changes"], uploads=dict(R["uploads"]),
                        same_bake=bake_op.LAST_BAKES[scene.name] is baked)
    images[label] = R["combined"].copy()
    images[label + "_albedo"] = R["albedo"].copy()
    if label == "again":
        box.matrix_world = mathutils.Matrix.Translation((0.9, 0.0, 0.0)) @ box.matrix_world
    elif label == "moved_object":
        point.location = (-1.5, -1.0, 2.0)
    elif label in ("moved_light", "rebake_same"):
        if label == "rebake_same":
            sphere("Ball", (0.0, 1.2, 0.5))
        res, err = bake()
        assert err is None, err
        baked = bake_op.LAST_BAKES[scene.name]

# the viewport: one engine instance, one GPU state for all redraws
viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, len(LABELS), step)
for label in ("f12_first", "f12_again"):        # F12: a state of its own each time
    bpy.ops.render.render()
    images[label] = engine.LAST_RENDER["combined"].copy()
views = {{}}
for view in ("STEPS", "DEPTH", "NORMAL", "ALBEDO", "DIRECT", "INDIRECT", "HYBRID", "SC_FINAL",
             "SC_ALBEDO", "SC_NORMAL", "SC_DIRECT", "SC_INDIRECT", "CARDS", "SC_UPDATES", "PROBES",
             "PROBE_FALLBACK", "COMBINED"):
    scene.lumen.engine.debug_view = view
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    views[view] = dict(view=R["view"],
                       max_steps=int(R["steps"].max()) if "steps" in R else None)
    images["view_" + view] = R["shown"].copy()
    if "position" in R:
        images["view_position"] = R["position"].copy()
        images["view_albedo"] = R["albedo"].copy()
np.savez("images.npz", **images)
emit(views=views, steps=steps, memory=engine.MEMORY[scene.name])
"""


def red_columns(albedo):
    red = (albedo[..., 0] > 0.5) & (albedo[..., 1] < 0.2)
    return red, float(np.argwhere(red)[:, 1].mean()) if red.any() else -1.0


def test_moves_reupload_only_what_changed(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    steps = run.result["steps"]
    print(steps, run.result["memory"])
    assert steps["first"]["changes"] == ["atlas", "cards", "indirection", "lights", "objects", "sky"]
    assert steps["again"]["changes"] == []
    assert steps["moved_object"]["changes"] == ["objects"]
    assert steps["moved_object"]["uploads"]["atlas"] == 1
    assert steps["moved_object"]["same_bake"]                  # no re-bake
    assert steps["moved_light"]["changes"] == ["lights"]
    assert steps["moved_light"]["uploads"] == {"atlas": 1, "indirection": 1, "objects": 2,
                                               "lights": 2, "cards": 1}
    assert steps["rebake_same"]["changes"] == []              # same meshes: nothing uploaded
    assert set(steps["rebake_new_mesh"]["changes"]) >= {"atlas", "indirection", "objects"}
    assert steps["rebake_new_mesh"]["uploads"]["atlas"] == 2

    views = run.result["views"]
    assert all(v["view"] == k for k, v in views.items()), views
    assert views["STEPS"]["max_steps"] > 0 and views["NORMAL"]["max_steps"] is None
    mem = run.result["memory"]
    assert mem["atlas"] > 0 and mem["objects"] == 4 * 10 * 16  # 4 instances x 10 RGBA32F texels
    # screen-size targets are counted: 4 RGBA32F G-buffer attachments, 32-bit depth, 2 + 2 images
    px = SIZE * SIZE
    assert mem["screen_gbuffer"] == px * 16 * 4 and mem["screen_depth"] == px * 4
    assert mem["screen_direct"] == mem["screen_composite"] == px * 16 * 2

    img = np.load(tmp_path / "images.npz")
    np.testing.assert_array_equal(img["f12_first"], img["f12_again"])   # F12 is deterministic
    surface = img["view_position"][..., 3] > 0.5
    # The cards seen through the surface cache lookup: their albedo is the G-buffer's where a card
    # sees the point (all but edges and corners), and no card is missing anywhere else.
    magenta = np.all(np.abs(img["view_CARDS"][..., :3] - [1.0, 0.0, 1.0]) < 1e-6, axis=-1)
    assert magenta[surface].mean() < 0.03
    close = np.abs(img["view_SC_ALBEDO"][..., :3] - img["view_albedo"][..., :3]).max(axis=-1) < 0.05
    assert close[surface & ~magenta].mean() > 0.95
    hybrid = img["view_HYBRID"]
    hits = (hybrid[..., 1] + hybrid[..., 2]) > 0
    # the camera is 5-6 m away: beyond the mesh SDFs' 1.8 m, hits are the global SDF's (blue)
    assert hits[surface].mean() > 0.95 and hybrid[hits, 2].mean() > 0.9
    assert img["view_INDIRECT"][surface, :3].mean() > 0.0
    red0, x0 = red_columns(img["first_albedo"])
    red1, x1 = red_columns(img["moved_object_albedo"])
    assert red0.sum() > 50 and red1.sum() > 50 and x1 > x0 + 3   # the red box moved right
    changed = np.abs(img["moved_object"] - img["first"]).max(axis=-1) > 0.02
    assert changed[red0 ^ red1].mean() > 0.9                  # where it left and where it went
    assert changed.mean() < 0.6                                # not everywhere
    assert np.abs(img["moved_light"] - img["moved_object"]).max() > 0.05
