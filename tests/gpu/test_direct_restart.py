"""After an object moves, the viewport's progressive direct light starts again only in the pixels
the move reaches (direct_light.Progressive, glsl/direct_restart.comp.glsl): the G-buffer pixels
that changed and those whose shadow rays pass where the scene SDF changed. Its converged image
must be the one a fresh viewport computes for the moved scene (a pixel left out would keep its
old shadow), and the restart must leave most of the view as it was. A selection click restarts
nothing; Film > Transparent, every pixel."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64

SNIPPET = f"""
from lumen_gi.gpu_shaders import engine, direct_light

scene = empty_scene(voxel_density=12.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=16.0)
floor = bpy.context.object
floor.data.materials.append(principled("FloorMat", (0.8, 0.8, 0.8)))
boxes = []
for k, (x, y, s) in enumerate([(-4.5, -3.0, 0.5), (4.5, -3.0, 0.5), (-4.5, 3.6, 0.5),
                               (4.5, 3.6, 0.5), (0.0, 0.3, 1.0)]):
    b = cube(f"Box{{k}}", s, (x, y, 0.5 * s))
    b.data.materials.append(principled(f"BoxMat{{k}}", (0.9, 0.3, 0.1)))
    boxes.append(b)
lamp = link(bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT")))
lamp.data.energy = 200.0
lamp.data.shadow_soft_size = 0.3
lamp.location = (-4.0, 0.0, 1.5)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 2.0
sun.rotation_euler = (1.05, 0.0, 0.5)
scene.world = bpy.data.worlds.new("World")   # GI Off: the direct pass brings the sky, by cones
bg = scene.world.node_tree.nodes.get("Background") if scene.world.node_tree else None
if bg is not None:
    bg.inputs["Color"].default_value = (0.3, 0.4, 0.6, 1.0)
cam = aimed_camera((0.0, -11.0, 11.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.lumen.engine.viewport_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

import viewport_harness
frames = direct_light.Progressive.FRAMES

def case(tag):
    log = []
    def redraw(i):
        R = engine.LAST_RENDER
        assert "error" not in R, R.get("error")
        log.append(R.get("direct_restart"))
        np.save(f"{{tag}}_direct_{{i}}.npy", R["direct"])
        np.save(f"{{tag}}_parts_{{i}}.npy", R["direct_parts"])
        if i == 2:
            boxes[0].select_set(True)         # a selection click: no restart
        if i == frames:
            boxes[-1].location.x += 0.6     # the middle box moves (its shadows with it)
        if i == 2 * frames + 1:
            scene.render.film_transparent = not scene.render.film_transparent   # all again
    viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 2 * frames + 3,
                         redraw)
    scene.render.film_transparent = False
    def fresh_redraw(i):
        np.save(f"{{tag}}_fresh_{{i}}.npy", engine.LAST_RENDER["direct"])
    viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, frames + 1,
                         fresh_redraw)
    return log

logs = {{"lamp": case("lamp")}}
lamp.hide_render = True                  # the sun alone, with GI (which brings the sky)
scene.lumen.engine.viewport_quality = "LOW"
logs["sun"] = case("sun")
emit(frames=frames, logs=logs)
"""


def test_a_move_restarts_only_the_pixels_it_reaches(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    frames = run.result["frames"]
    for tag, log in run.result["logs"].items():
        assert log[0] == "full" and log[1:frames + 1] == [None] * frames, (tag, log)
        assert log[frames + 1] == "local", (tag, log)      # the redraw after the move
        assert log[2 * frames + 2] == "full", (tag, log)   # Film > Transparent toggled
        load = lambda name: np.load(tmp_path / f"{tag}_{name}.npy")[..., :3]   # noqa: E731
        before = load(f"direct_{frames}")
        first = load(f"direct_{frames + 1}")
        after = load(f"direct_{2 * frames + 1}")
        fresh = load(f"fresh_{frames}")
        scale = float(fresh.mean())
        assert scale > 0.01
        # converged: the same image as a viewport that never saw the box elsewhere (a pixel
        # whose shadow cone crosses the box's old or new place but was kept would show the old
        # shadow)
        err = np.abs(after - fresh).max()
        assert err < 1e-5 * max(float(fresh.max()), 1.0), (tag, err)
        moved = np.abs(before - fresh).max(axis=-1) > 1e-3 * scale
        assert moved.sum() > 40, (tag, "the move changed too little of the view to tell")
        # the first redraw after the move started again (its mean holds 1 part, the others
        # all of them) every pixel the move changed ...
        parts = np.load(tmp_path / f"{tag}_parts_{frames + 1}.npy").reshape(*before.shape[:2], -1)
        again = parts[..., 0] < 1.5
        assert np.isin(parts[..., 0], (1.0, float(frames))).all()
        assert again[moved].all(), (tag, int((moved & ~again).sum()))
        # ... and not the whole view: with the sun, the region whose grid cells changed (on this
        # sparse floor the box's whole reach, 2 m around it) and its shadow, 30% (measured); a
        # lamp just above the grid's box sees that region across most of the floor (78%)
        assert 0 < again.mean() < (0.9 if tag == "lamp" else 0.4), (tag, again.mean())
        # a pixel not started again kept its mean to the bit
        np.testing.assert_array_equal(first[~again], before[~again])
