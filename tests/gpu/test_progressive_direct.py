"""The viewport's progressive direct light (gpu_shaders/direct_light.py: Progressive): each
redraw evaluates a part of every light's samples and of the sky cones, their running mean after
Progressive.FRAMES redraws is F12's direct light exactly, a still view then runs no direct pass,
and a moved light starts again from its first part."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 48

SNIPPET = f"""
from lumen_gi.gpu_shaders import engine, direct_light

scene = empty_scene(voxel_density=12.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=6.0)
floor = bpy.context.object
floor.data.materials.append(principled("FloorMat", (0.8, 0.8, 0.8)))
box = cube("Box", 0.8, (-0.6, 0.0, 0.4))
box.data.materials.append(principled("BoxMat", (0.9, 0.3, 0.1)))
lamp = link(bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT")))
lamp.data.energy = 300.0
lamp.data.shadow_soft_size = 0.5        # a wide penumbra: 8 samples that differ
lamp.location = (0.6, -0.4, 1.8)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 1.5
sun.rotation_euler = (0.6, 0.2, 0.0)
scene.world = bpy.data.worlds.new("World")   # GI Off: the direct pass brings the sky, by cones
scene.world.color = (0.3, 0.4, 0.6)
bg = scene.world.node_tree.nodes.get("Background") if scene.world.node_tree else None
if bg is not None:
    bg.inputs["Color"].default_value = (0.3, 0.4, 0.6, 1.0)
cam = aimed_camera((0.0, -4.5, 3.5), (0.0, 0.0, 0.3))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.lumen.engine.viewport_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
np.save("f12.npy", R["direct"])

import viewport_harness
frames = direct_light.Progressive.FRAMES
parts = []
walked = []
def redraw(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("error")
    parts.append(R["direct_part"])
    walked.append(R["extraction_walked"])
    np.save(f"direct_{{i}}.npy", R["direct"])
    if i == frames + 1:
        lamp.location.x -= 0.5
viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, frames + 3, redraw)
emit(frames=frames, parts=[list(p) if p else None for p in parts], walked=walked)
"""


def test_progressive_direct_light_is_f12s_and_then_free(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    frames, parts = run.result["frames"], run.result["parts"]
    assert frames >= 2
    # redraws 0 .. frames-1 each evaluate a new part, covering every stratum once
    assert parts[:frames] == [[k * (8 // frames), 8 // frames] for k in range(frames)], parts
    # converged: the next still redraw runs no direct pass ...
    assert parts[frames] is None and parts[frames + 1] is None, parts
    # ... and after the lamp moved (edited in redraw frames + 1) the next one starts again
    assert parts[frames + 2] == [0, 8 // frames], parts
    # a moved light is read again without walking the meshes (ExtractionCache.mark_lights)
    assert run.result["walked"][frames + 2] is False, run.result["walked"]
    f12 = np.load(tmp_path / "f12.npy")[..., :3]
    first = np.load(tmp_path / "direct_0.npy")[..., :3]
    done = np.load(tmp_path / f"direct_{frames - 1}.npy")[..., :3]
    kept = np.load(tmp_path / f"direct_{frames + 1}.npy")[..., :3]
    moved = np.load(tmp_path / f"direct_{frames + 2}.npy")[..., :3]
    scale = float(f12.mean())
    assert scale > 0.01
    # one part alone is an estimate of the same light (noisier in the penumbra) ...
    assert abs(float(first.mean()) / scale - 1.0) < 0.05
    assert np.abs(first - f12).max() > 1e-3 * scale, "the first part already had every sample"
    # ... the mean of all parts is F12's pass to float rounding, and it is kept as it is
    assert np.abs(done - f12).max() < 1e-4 * max(float(f12.max()), 1.0), np.abs(done - f12).max()
    assert np.array_equal(kept, done)
    assert np.abs(moved - done).max() > 0.01 * scale, "the moved lamp did not reach the viewport"
