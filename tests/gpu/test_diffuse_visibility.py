"""Ray Visibility > Diffuse off, as Cycles has it: GI rays pass the object as if it were not there
(no bounce light from it, nor occlusion of the others'), while the camera sees it, the sun's
shadow rays stop at it, and it is lit. Our F12 on llvmpipe through bpy.

A grey wall and a grey floor under a white sun, black world, and two red cubes in the sun, one
beside the wall and one beyond the mesh SDFs' 1.8 m (its light reaches the wall through the
global SDF and the voxel lighting): their bounce light tints the wall red (red over green 1.71).
With their diffuse visibility off, nothing red is left for GI rays to see, so the wall's
indirect light is grey: red over green 1 within 1e-3 (1.0000; before the voxel lighting's
tiles left them out, the far cube's light stayed in its voxels: 1.0078). The near cube is still
drawn red either way.
The viewport, one engine instance: unticking Diffuse (an edit, no re-bake) takes the red out of
the wall's indirect light within the redraws that follow (over 90% of it in 24 redraws; the far
cube's part goes with the voxel lighting's level-by-level updates).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SCENE = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=9.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
wall = cube("Wall", 1.0, (-1.0, 0.0, 1.0))
wall.scale = (0.1, 3.0, 2.0)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
wall.data.materials.append(principled("Wall", (0.8, 0.8, 0.8)))
red = cube("Red", 0.8, (-0.4, 0.0, 0.4))
red.data.materials.append(principled("Red", (0.9, 0.05, 0.05)))
far = cube("Far", 1.6, (1.0, 2.6, 0.8))                 # beyond the mesh SDFs' 1.8 m
far.data.materials.append(red.data.materials[0])
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.data.angle = 0.0
sun.rotation_euler = (0.5, 0.0, 0.4)
aimed_camera((2.5, -1.8, 1.6), (-0.8, 0.0, 0.7))
scene.world = bpy.data.worlds.new("World")
scene.world.use_nodes = True
scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
scene.render.resolution_x = scene.render.resolution_y = 64
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "LOW"
"""
# F12 with the cubes seen, then unseen by diffuse rays: each one's images as <key>_<seen>.npy
RENDERS = """
for seen in (True, False):
    red.visible_diffuse = far.visible_diffuse = seen
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    for key in ("indirect", "combined", "position", "normal"):
        np.save(f"{key}_{seen}.npy", R[key])
emit(ok=True)
"""


VIEW_SNIPPET = SCENE + """
from lumen_gi.gpu_shaders import engine
import viewport_harness

SETTLE = 24
tints = []

def step(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if i % SETTLE == SETTLE - 1:
        pos, nrm = R["position"], R["normal"]
        wall = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0] + 0.95) < 0.02) & (nrm[..., 0] > 0.9)
        e = R["indirect"][wall][:, :3].mean(0)
        tints.append(float(e[0] / e[1]))
        red.visible_diffuse = far.visible_diffuse = False     # untick Diffuse

viewport_harness.run(scene, engine.LumenGIRenderEngine, 64, 64, 2 * SETTLE, step)
emit(tints=tints)
"""


def test_diffuse_visibility_off_hides_the_object_from_gi(tmp_path):
    run = run_python(SCENE + RENDERS, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    pos = np.load(tmp_path / "position_True.npy")
    nrm = np.load(tmp_path / "normal_True.npy")
    wall = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0] + 0.95) < 0.02) & (nrm[..., 0] > 0.9) \
        & (pos[..., 2] > 0.05) & (np.abs(pos[..., 1]) < 1.2)
    cube = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0] + 0.4) <= 0.41) & (np.abs(pos[..., 1]) <= 0.41) \
        & (pos[..., 2] > 0.01) & (pos[..., 2] <= 0.81)
    assert wall.sum() > 100 and cube.sum() > 30
    tint = {}
    for seen in (True, False):
        e = np.load(tmp_path / f"indirect_{seen}.npy")[wall][:, :3].mean(0)
        tint[seen] = e[0] / e[1]
        print("wall indirect (r, g, b) with the cube", "seen" if seen else "unseen", e,
              "red / green", tint[seen])
        c = np.load(tmp_path / f"combined_{seen}.npy")[cube][:, :3].mean(0)
        print("  the cube drawn", c)
        assert c[0] > 5 * c[1]                        # drawn red either way
    assert tint[True] > 1.1                           # the cube's bounce light, seen
    assert abs(tint[False] - 1.0) < 1e-3              # nothing red for GI rays to see


def test_viewport_sees_diffuse_visibility_unticked(tmp_path):
    run = run_python(VIEW_SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    seen, unseen = run.result["tints"]
    print("viewport, wall indirect red / green: seen", seen, "unticked", unseen)
    assert seen > 1.1
    assert abs(unseen - 1.0) < 0.1 * (seen - 1.0)     # the red mostly gone, still converging


RSM_SNIPPET = SCENE + 'scene.lumen.engine.gi_method = "RSM"\n' + RENDERS


def test_reflective_shadow_maps_bounce_nothing_off_an_unseen_object(tmp_path):
    """GI Method RSM (and LPV, which injects the same maps): the light's map draws an object
    diffuse rays do not see black, so it bounces nothing (red over green 1 on the wall), while
    it still stops the light (rsm.light_view)."""
    run = run_python(RSM_SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    pos = np.load(tmp_path / "position_True.npy")
    nrm = np.load(tmp_path / "normal_True.npy")
    wall = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0] + 0.95) < 0.02) & (nrm[..., 0] > 0.9)
    tint = {}
    for seen in (True, False):
        e = np.load(tmp_path / f"indirect_{seen}.npy")[wall][:, :3].mean(0)
        tint[seen] = e[0] / e[1]
        print("RSM: wall indirect", e, "red / green", tint[seen])
    assert tint[True] > 1.1
    assert abs(tint[False] - 1.0) < 1e-3
