"""The world as a light (operators/world_capture.py, lumen_addon/sky.py, glsl/sky_lib.glsl), F12
through bpy on llvmpipe, against closed forms.

A sky of radiance A above the horizon and B below, made of nodes (Generated coordinate ->
Separate XYZ -> Z > 0 -> Mix): no flat colour, so Cycles captures it. A sphere sees only the sky,
so every point of normal n receives E(n) = pi (A (1 + nz) + B (1 - nz)) / 2: the Diffuse Direct
pass (GI Off: the direct pass's SDF-occluded sky light) and the Diffuse Indirect pass (GI on: the
screen probes' rays that leave the scene) must both be E / pi, and the background the sky itself.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

A = (1.0, 0.6, 0.3)
B = (0.1, 0.2, 0.4)

SCENE = f"""
from lumen_gi.gpu_shaders import engine

def split_world(above, below):
    w = bpy.data.worlds.new("Split")
    bpy.context.scene.world = w
    if w.node_tree is None:
        w.use_nodes = True
    nt = w.node_tree
    tc = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    gt = nt.nodes.new("ShaderNodeMath")
    gt.operation = "GREATER_THAN"
    gt.inputs[1].default_value = 0.0
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    ins = {{s.identifier: s for s in mix.inputs}}
    ins["A_Color"].default_value = (*below, 1.0)
    ins["B_Color"].default_value = (*above, 1.0)
    nt.links.new(tc.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["Z"], gt.inputs[0])
    nt.links.new(gt.outputs[0], ins["Factor_Float"])
    out = {{s.identifier: s for s in mix.outputs}}["Result_Color"]
    nt.links.new(out, nt.nodes["Background"].inputs["Color"])
    return w

scene = empty_scene(voxel_density=24.0, cache_dir="cache")
bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.6)
bpy.context.object.data.materials.append(principled("Ball", (0.8, 0.8, 0.8)))
split_world({A}, {B})
cam = aimed_camera((0.0, -3.0, 0.0))
cam.data.lens = 55.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 48
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
out = {{}}
for quality in ("OFF", "LOW"):
    scene.lumen.engine.render_quality = quality
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(f"{{quality}}_direct.npy", R["direct"])
    np.save(f"{{quality}}_indirect.npy", R["indirect"])
    np.save(f"{{quality}}_combined.npy", R["combined"])
    out[quality] = R["notes"]
np.save("normal.npy", R["normal"])
np.save("position.npy", R["position"])
emit(notes=out)
"""


def expected(normal):
    nz = normal[..., 2:3]
    return (np.array(A) * (1 + nz) + np.array(B) * (1 - nz)) / 2


def test_split_sky_lights_a_sphere_with_the_closed_form(tmp_path):
    run = run_python(SCENE, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    hit = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    normal = np.load(tmp_path / "normal.npy")[..., :3]
    want = expected(normal)[hit]
    assert hit.mean() > 0.2
    stats = {}
    for quality, name in (("OFF", "direct"), ("LOW", "indirect")):
        got = np.load(tmp_path / f"{quality}_{name}.npy")[..., :3][hit]
        rel = np.abs(got / want - 1)
        stats[quality] = (got.mean(axis=0) / want.mean(axis=0), np.percentile(rel, 90))
    print(stats)
    for quality, (ratio, p90) in stats.items():
        assert np.all(np.abs(ratio - 1) < 0.03), quality
        assert p90 < 0.08, quality
    combined = np.load(tmp_path / "LOW_combined.npy")[..., :3]
    rows = np.arange(combined.shape[0])[:, None] * np.ones(combined.shape[1])
    # image rows run bottom to top (Blender's order): the top rows see the sky above
    top = ~hit & (rows >= combined.shape[0] - 6)
    bottom = ~hit & (rows < 6)
    np.testing.assert_allclose(combined[top].mean(axis=0), A, rtol=0.02)
    np.testing.assert_allclose(combined[bottom].mean(axis=0), B, rtol=0.02)


LIGHT_PATH = """
from lumen_gi.gpu_shaders import engine
scene = empty_scene(voxel_density=12.0, cache_dir="cache")
bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.6)
w = bpy.data.worlds.new("Trick")
scene.world = w
if w.node_tree is None:
    w.use_nodes = True
nt = w.node_tree
lp = nt.nodes.new("ShaderNodeLightPath")
mix = nt.nodes.new("ShaderNodeMix")
mix.data_type = "RGBA"
ins = {s.identifier: s for s in mix.inputs}
ins["A_Color"].default_value = (0.9, 0.8, 0.7, 1.0)      # what lights the scene
ins["B_Color"].default_value = (0.1, 0.2, 0.6, 1.0)      # what the camera sees
nt.links.new(lp.outputs["Is Camera Ray"], ins["Factor_Float"])
nt.links.new({s.identifier: s for s in mix.outputs}["Result_Color"], nt.nodes["Background"].inputs["Color"])
aimed_camera((0.0, -3.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "LOW"
scene.render.resolution_x = scene.render.resolution_y = 32
res, err = bake()
assert err is None, err
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
hit = R["position"][..., 3] > 0.5
emit(notes=R["notes"], lit=float(R["combined"][..., :3][hit].mean()))
"""


def test_a_world_node_the_capture_cannot_see_is_named_never_black(tmp_path):
    """A Light Path trick (one colour for camera rays, another for light): the capture sees what
    the camera sees, so the warning names the node; the sphere is lit all the same."""
    run = run_python(LIGHT_PATH, tmp_path, timeout=200)
    assert run.returncode == 0, run.explain()
    notes = run.result["notes"]
    print(run.result)
    assert any("'Light Path'" in n and "Trick" in n for n in notes), notes
    assert run.result["lit"] > 0.05
