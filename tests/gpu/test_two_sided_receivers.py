"""A surface baked two-sided (an open mesh: a floor plane, an imported room's single-sided walls)
receives its direct light in full: its field |d| - half a voxel reads a flat 0 over a whole
voxel when the surface lies midway between two SDF samples, and shadow cones once took that
plateau for an occluder on the receiver itself (the floor of the `imported` benchmark room got
no direct light). Sun at 50 degrees on a lone plane: Diffuse Direct = E cos / pi everywhere."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import math
from lumen_gi.gpu_shaders import engine
scene = empty_scene(voxel_density=20.0, cache_dir="cache")
results = {}
for label, z in (("on_sample", 0.0), ("midway", 0.025)):
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 0.0))
    plane = bpy.context.object
    # a second plane far below fixes the SDF grid's origin, so the first one's height
    # decides where it falls between samples
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, -1.0 - z))
    sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40.0), 0.0, 0.0)
    aimed_camera((0.0, -0.5, 3.0), (0.0, 0.0, 0.0))
    scene.render.engine = "LUMEN_GI"
    scene.lumen.engine.render_quality = "OFF"
    scene.render.resolution_x = scene.render.resolution_y = 48
    res, err = bake()
    assert err is None, err
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    hit = R["position"][..., 3] > 0.5
    d = R["direct"][..., 0][hit]
    results[label] = dict(mean=float(d.mean()), low=float((d < 0.9 * d.max()).mean()),
                          notes=R["notes"])
emit(results=results, expected=3.0 * math.cos(math.radians(40.0)) / math.pi)
"""


def test_a_two_sided_floor_gets_all_its_direct_light(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=200)
    assert run.returncode == 0, run.explain()
    want = run.result["expected"]
    print(run.result)
    for label, r in run.result["results"].items():
        assert abs(r["mean"] / want - 1) < 0.02, (label, r, want)
        assert r["low"] < 0.01, (label, r)
