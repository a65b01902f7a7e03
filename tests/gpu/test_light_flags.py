"""Light settings an artist sets in Cycles' light panel: Cast Shadow off (a fill light lights
what is behind things) and a light hidden in the viewport only (F12 renders it, as Cycles does).
Both were ignored: every light cast shadows, and F12 dropped a light hidden by the eye. And
Object > Visibility > Ray Visibility > Diffuse off: Cycles' diffuse surfaces do not see the light
(no direct light from it, so no bounce either); it lit everything before."""
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=6.0)
cube("Box", 1.0, (0.0, 0.0, 0.5))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (-0.6, 0.0, 0.0)          # its shadow falls towards the camera
aimed_camera((0.0, -6.0, 6.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.lumen.engine.aa_samples = 1
scene.render.resolution_x = scene.render.resolution_y = 48
out = {"bake": bake()}
for name in ("shadow", "no_shadow", "eye_hidden", "no_diffuse"):
    sun.data.use_shadow = name != "no_shadow"
    if name == "eye_hidden":
        sun.hide_set(True)
    if name == "no_diffuse":
        sun.hide_set(False)
        sun.visible_diffuse = False
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(name + ".npy", R["direct"])
np.save("position.npy", R["position"])
np.save("normal.npy", R["normal"])
emit(**out)
"""


def test_cast_shadow_off_and_a_light_hidden_in_the_viewport(tmp_path):
    res = run_python(SNIPPET, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    pos, nor = np.load(tmp_path / "position.npy"), np.load(tmp_path / "normal.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 1e-3) & (nor[..., 2] > 0.99)
    unshadowed = 3.0 * math.cos(0.6) / math.pi          # Diffuse Direct = E / pi
    shadow, free, hidden = (np.load(tmp_path / f"{k}.npy")[..., 0][floor]
                            for k in ("shadow", "no_shadow", "eye_hidden"))
    assert (shadow < 0.2 * unshadowed).sum() > 20        # the box's shadow on the floor
    assert np.abs(free - unshadowed).max() < 0.01 * unshadowed, (free.min(), free.max())
    np.testing.assert_allclose(hidden, shadow, atol=1e-6)  # hidden by the eye: lights F12 still
    # Ray Visibility > Diffuse off: it lights no diffuse surface (Cycles), and we shade no other
    np.testing.assert_array_equal(np.load(tmp_path / "no_diffuse.npy")[..., :3], 0.0)
