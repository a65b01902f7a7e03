"""One object scaled to 0 must not break the render of everything else ("Lumen GI: Singular
matrix" before): it is left out, named in a warning, and the image equals the image without it."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
wall = cube("Wall", 1.0, (0.0, 0.0, 0.5))
ghost = cube("Ghost", 1.0, (1.0, 1.0, 0.5))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.6, 0.3, 0.0)
cam = aimed_camera((0.0, -5.0, 4.0), (0.0, 0.0, 0.3))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = 48

out = {}
ghost.scale = (0.0, 0.0, 0.0)
out["bake_scaled"] = bake()           # baked with the object at scale 0
bpy.ops.render.render()
R = engine.LAST_RENDER
out["error"] = R.get("error")
out["notes"] = R.get("notes", [])
np.save("scaled.npy", R["combined"])
bpy.data.objects.remove(ghost)
out["bake_without"] = bake()
bpy.ops.render.render()
np.save("without.npy", engine.LAST_RENDER["combined"])
emit(**out)
"""


def test_scale_zero_object_is_left_out_and_named(tmp_path):
    res = run_python(SNIPPET, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    r = res.result
    assert r["bake_scaled"][1] is None and r["bake_without"][1] is None, r
    assert r["error"] is None, r["error"]
    assert any(n.startswith("Ghost:") and "cannot be inverted" in n for n in r["notes"]), r["notes"]
    a, b = np.load(tmp_path / "scaled.npy"), np.load(tmp_path / "without.npy")
    assert np.abs(a[..., :3] - b[..., :3]).max() < 1e-4, np.abs(a - b).max()
