"""A scene of thousands of instances (a particle scatter) renders: the object, card and instance
tables were one texture column a row each, and past the GPU's largest texture side (16,384 on
llvmpipe: 3,000 scattered pebbles of 6 cards each) the upload failed and F12 drew nothing.
They are row tables now (packing.row_table, glsl/row_table_lib.glsl): 1,024 rows a line."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, radius=0.1, location=(0, 0, -5))
pebble = bpy.context.object
bpy.ops.mesh.primitive_plane_add(size=40.0)
emitter = bpy.context.object
emitter.modifiers.new("Scatter", 'PARTICLE_SYSTEM')
ps = emitter.particle_systems[0].settings
ps.type = 'HAIR'
ps.count = 3000
ps.render_type = 'OBJECT'
ps.instance_object = pebble
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.rotation_euler = (0.6, 0.3, 0.0)
aimed_camera((0.0, -3.0, 2.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.lumen.engine.aa_samples = 1
scene.render.resolution_x = scene.render.resolution_y = 32
out = {"bake": bake()}
bpy.ops.render.render()
R = engine.LAST_RENDER
out.update(error=R.get("error"), draws=R.get("gbuffer_draws"), triangles=R.get("triangles"))
from lumen_gi.lumen_addon.cache import read_cache
back = read_cache("cache")
out["instances"] = len(back.instances)
out["card_rows"] = int(sum(len(i.cards) for i in back.instances if i.cards is not None))
np.save("combined.npy", R["combined"])
np.save("position.npy", R["position"])
emit(**out)
"""


def test_thousands_of_instances_render(tmp_path):
    res = run_python(SNIPPET, tmp_path, timeout=600)
    assert res.returncode == 0, res.explain()
    r = res.result
    assert r["bake"][1] is None and r["error"] is None, r
    assert r["instances"] >= 3000, r
    print("card rows", r["card_rows"])
    assert r["card_rows"] > 16384, r     # past llvmpipe's largest texture side
    combined = np.load(tmp_path / "combined.npy")
    covered = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    assert np.isfinite(combined).all() and covered.mean() > 0.5
    assert combined[covered][:, :3].mean() > 0.05          # lit, not the black of a failure
