"""The engine compares what is baked with the scene (lumen_addon/staleness.py): an object deleted
after the bake leaves the SDF scene at once (no shadow, no bounce), an object hidden from camera
rays stays in it, and objects added or edited since the bake are listed: F12's notes, the
viewport's second line of text, the N-panel. The viewport hashes only what depsgraph.updates
names; F12 ignores geometry that only differs by render-time modifier levels."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SCENE = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=5.0)
floor = bpy.context.object
floor.name = "Floor"
floor.data.materials.append(principled("FloorMat", (0.8, 0.8, 0.8)))
box = cube("Box", 0.8, (-0.9, 0.0, 0.4))
other = cube("Other", 0.6, (1.0, 0.9, 0.3))
hidden = cube("Hidden", 0.6, (1.0, -1.0, 0.3))
hidden.visible_camera = False                 # not drawn, still casts light
ball = sphere("Ball", (0.0, 1.5, 0.5), subdivide=1)
ball.modifiers["Subdivision"].render_levels = 2   # F12 evaluates another mesh than the bake
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.7, 0.0, 0.6)
cam = aimed_camera((0.0, -0.5, 7.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = scene.lumen.engine.viewport_quality = "LOW"
scene.lumen.engine.render_frames = 1
scene.lumen.engine.bounces = 1
scene.render.resolution_x = scene.render.resolution_y = 64
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

def f12():
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    return dict(stale=R["stale"], gone=R["gone"], notes=R["notes"], hashed=R["stale_hashed"],
                seconds=R["stale_seconds"], extract=R["extract_seconds"])

def edit_vertex(obj):
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    co[2] += 0.2
    obj.data.vertices.foreach_set("co", co)
    obj.data.update()
"""

F12 = SCENE + """
out = {"baked": f12()}
np.save("baked.npy", engine.LAST_RENDER["combined"])
bpy.data.objects.remove(box)
out["deleted"] = f12()
np.save("deleted.npy", engine.LAST_RENDER["combined"])
res, err = bake()
assert err is None, err
out["rebaked"] = f12()
np.save("rebaked.npy", engine.LAST_RENDER["combined"])
scene.lumen.engine.render_quality = "OFF"
other.location.x -= 0.3                       # a move is not a change
out["moved"] = f12()
edit_vertex(other)
out["edited"] = f12()
floor.active_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
    0.2, 0.3, 0.8, 1.0)
new = cube("New", 0.4, (0.0, -1.5, 0.2))
out["more"] = f12()
emit(**out)
"""


def test_f12_drops_deleted_objects_and_names_changed_ones(tmp_path):
    run = run_python(F12, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    r = run.result
    # freshly baked: nothing listed, although F12 evaluates Ball at render levels
    assert r["baked"]["stale"] == [] and r["baked"]["gone"] == [], r["baked"]
    assert not any("changed since the bake" in n for n in r["baked"]["notes"])
    # deleted: it leaves the SDF scene; the camera-hidden cube stays
    assert r["deleted"]["gone"] == ["Box"] and r["deleted"]["stale"] == [], r["deleted"]
    baked, deleted, rebaked = (np.load(tmp_path / f"{k}.npy")[..., :3].mean(-1)
                               for k in ("baked", "deleted", "rebaked"))
    # where the box stood and where its shadow fell: the image after deletion is the image of
    # a scene baked without it (the box's shadow and bounce are gone from the next frame)
    region = np.abs(baked - rebaked) > 0.05
    assert region.sum() > 40, region.sum()
    assert np.abs(deleted - rebaked)[region].mean() < 0.1 * np.abs(baked - rebaked)[region].mean()
    assert np.abs(deleted - rebaked).mean() < 0.01
    assert r["rebaked"]["gone"] == [] and r["rebaked"]["stale"] == []
    # a move is not a change; an edited mesh, a material and a new object are
    assert r["moved"]["stale"] == [], r["moved"]
    assert r["edited"]["stale"] == ["Other"], r["edited"]
    assert "1 object changed since the bake (Other)" in " ".join(r["edited"]["notes"])
    assert sorted(r["more"]["stale"]) == ["Floor", "New", "Other"], r["more"]
    note = [n for n in r["more"]["notes"] if "changed since the bake" in n]
    assert len(note) == 1 and note[0].startswith("3 objects changed since the bake"), note


VIEWPORT = SCENE + """
import viewport_harness

calls = []
original = engine.draw_message
def recording(text, width, height, line=0):
    calls.append((text, line))
    original(text, width, height, line)
engine.draw_message = recording

steps = []
def step(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    steps.append(dict(stale=R["stale"], gone=R["gone"], hashed=R["stale_hashed"],
                      seconds=R["stale_seconds"], extract=R["extract_seconds"],
                      changes=R["changes"], messages=calls[:]))
    calls.clear()
    if i == 1:
        bpy.data.objects.remove(box)
    elif i == 2:
        edit_vertex(other)
    elif i == 3:
        floor.active_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
            0.2, 0.3, 0.8, 1.0)
    elif i == 4:
        cube("New", 0.4, (0.0, -1.5, 0.2))

viewport_harness.run(scene, engine.LumenGIRenderEngine, 64, 64, 6, step)
from lumen_gi.operators.panel import stale_lines
emit(steps=steps, panel=stale_lines(scene))
"""


def test_viewport_lists_changes_and_hashes_only_what_changed(tmp_path):
    run = run_python(VIEWPORT, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    steps, panel = run.result["steps"], run.result["panel"]
    print([(s["hashed"], round(s["seconds"] * 1e3, 2), round(s["extract"] * 1e3, 2))
           for s in steps])
    first, still, deleted, edited, material, added = steps
    # every baked object once (the harness evaluates at render settings: Ball is not judged)
    assert first["stale"] == [] and first["hashed"] == 4
    assert still["stale"] == [] and still["hashed"] == 0          # nothing changed: no hashing
    assert deleted["gone"] == ["Box"] and "objects" in deleted["changes"]
    assert deleted["hashed"] == 0 and deleted["stale"] == []
    assert edited["stale"] == ["Other"] and edited["hashed"] == 1
    assert material["stale"] == ["Floor", "Other"] and material["hashed"] == 1
    assert added["stale"] == ["Floor", "Other", "New"] and added["hashed"] == 0
    # the viewport says it on its own line, below 'refining n/N' when that is shown
    lines = {text: line for text, line in added["messages"]}
    assert lines.get("Lumen GI: 3 objects changed since the bake: press Bake") is not None, lines
    refining = [line for text, line in added["messages"] if "refining" in text]
    assert lines["Lumen GI: 3 objects changed since the bake: press Bake"] == len(refining)
    assert not any("changed" in text for text, _ in still["messages"])
    assert panel[0] == "3 objects changed since the bake:" and "Floor" in " ".join(panel)


CONVERTED = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=5.0)
bpy.ops.object.metaball_add(type='BALL', location=(0.0, 0.0, 0.8))
ball = bpy.context.object
bpy.ops.curve.primitive_bezier_circle_add(location=(1.0, 1.0, 0.5))
ring = bpy.context.object
ring.data.bevel_depth = 0.1
ring.data.render_resolution_u = 24          # finer in F12 than the viewport's 12
bpy.ops.object.text_add(location=(-2.0, -1.0, 0.1))
bpy.context.object.data.extrude = 0.1
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.rotation_euler = (0.7, 0.0, 0.6)
aimed_camera((0.0, -4.0, 5.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = 32
res, err = bake()
assert err is None, err
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
from lumen_gi.lumen_addon.cache import read_cache
out = dict(baked=[i.name for i in read_cache("cache").instances], stale=R["stale"],
           meta=(ball.data.resolution, ball.data.render_resolution))
ball.data.resolution = ball.data.render_resolution   # both now differ from the bake's
ring.data.render_resolution_u = 0
ring.data.resolution_u = 6
bpy.ops.render.render()
out["edited"] = engine.LAST_RENDER["stale"]
out["names"] = [ball.name, ring.name]
emit(**out)
"""


def test_metaball_curve_and_text_are_not_changed_by_their_render_resolution(tmp_path):
    # a metaball evaluates twice as fine in F12 as in the viewport the bake saw (and a curve
    # may): F12 listed the freshly baked metaball as "changed since the bake"
    res = run_python(CONVERTED, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    r = res.result
    assert r["meta"][0] != r["meta"][1], r["meta"]       # Blender's defaults differ
    assert len(r["baked"]) == 4, r["baked"]                  # plane, metaball, curve, text
    assert r["stale"] == [], r
    # with render and viewport resolutions equal, F12 judges their content again: both were
    # made coarser or finer than the bake
    assert sorted(n.split("/")[0] for n in r["edited"]) == sorted(r["names"]), r


HIDDEN = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=5.0)
eye = cube("Eye", 0.8, (-1.0, 0.0, 0.4))
eye.hide_set(True)                            # the outliner's eye: the viewport only
monitor = cube("Monitor", 0.8, (1.0, 0.0, 0.4))
monitor.hide_viewport = True                  # Disable in Viewports
gone = cube("NotRendered", 0.8, (0.0, 1.2, 0.4))
gone.hide_render = True
gone.hide_set(True)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.rotation_euler = (0.7, 0.0, 0.6)
cam = aimed_camera((0.0, -4.0, 5.0), (0.0, 0.0, 0.0))
bpy.data.objects["Plane"].data.materials.append(None)     # a warning F12 reports too
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = 32
res, err = bake()
assert err is None, err
from lumen_gi.lumen_addon.cache import read_cache
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
out = dict(baked=[i.name for i in read_cache("cache").instances], draws=R["gbuffer_draws"],
           notes=R["notes"])
cam.data.type = 'PANO'
bpy.ops.render.render()
out["pano_notes"] = engine.LAST_RENDER["notes"]
emit(**out)
"""


def test_f12_renders_what_the_viewport_hides_and_says_it_is_not_baked(tmp_path):
    # Cycles and EEVEE render objects hidden only in the viewport; F12 dropped them silently
    res = run_python(HIDDEN, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    r = res.result
    assert r["baked"] == ["Plane"], r                  # a viewport depsgraph does not hold them
    assert "hidden in the viewport, so not baked" in res.stdout      # the bake says so
    assert r["draws"] == 3, r                          # plane, Eye, Monitor; not NotRendered
    note = [n for n in r["notes"] if "hidden in the viewport" in n]
    assert len(note) == 1 and note[0].startswith("2 objects") and "Eye" in note[0] \
        and "Monitor" in note[0], r["notes"]
    assert not any("changed since the bake" in n for n in r["notes"]), r["notes"]
    # notes are sentences naming the object (a material warning was a Python tuple's repr)
    assert all(isinstance(n, str) for n in r["notes"]), r["notes"]
    assert "Plane: material slot 1 is empty; using default grey" in r["notes"], r["notes"]
    # a camera we cannot render as Cycles does is named
    assert any("'Cam' is panoramic" in n for n in r["pano_notes"]), r["pano_notes"]
