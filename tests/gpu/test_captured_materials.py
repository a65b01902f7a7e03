"""A material the extraction cannot read node by node keeps its pattern: material_capture renders
it by Cycles over its UV square, and the G-buffer samples that swatch with the mesh's UVs. A
plane whose Base Color is a black-to-white Color Ramp along U (Texture Coordinate UV -> Separate
XYZ -> Color Ramp), seen from above, against Cycles' Diffuse + Glossy Color passes (what the
capture reads):

- our albedo follows Cycles' across the plane within 0.04 per pixel (a 32-pixel swatch,
  bilinear), from dark to light (a spread over 0.8);
Before this, the capture kept only the material's mean colour: the plane was flat 0.5 grey.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402

SIZE = 64

SNIPPET = f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=2.0)
mat = principled("Ramp")
nodes, links = mat.node_tree.nodes, mat.node_tree.links
coords = nodes.new("ShaderNodeTexCoord")
split = nodes.new("ShaderNodeSeparateXYZ")
ramp = nodes.new("ShaderNodeValToRGB")
links.new(coords.outputs["UV"], split.inputs[0])
links.new(split.outputs["X"], ramp.inputs["Fac"])
links.new(ramp.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
bpy.context.object.data.materials.append(mat)
cam = aimed_camera((0.0, 0.0, 6.0), (0.0, 0.0, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 2.2
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
render_lumen(save=("albedo", "position"))
render_cycles(4, exr="cycles.exr", passes=("use_pass_diffuse_color", "use_pass_glossy_color"))
"""


def test_a_captured_material_keeps_its_pattern(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    albedo = np.load(tmp_path / "albedo.npy")[..., :3]
    pos = np.load(tmp_path / "position.npy")
    ref = (read_pass(tmp_path / "cycles.exr", "Diffuse Color")
           + read_pass(tmp_path / "cycles.exr", "Glossy Color"))[::-1]
    on = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0]) < 0.95) & (np.abs(pos[..., 1]) < 0.95)
    assert on.sum() > 1000
    diff = np.abs(albedo - ref)[on]
    spread = albedo[on].max() - albedo[on].min()
    print("max |ours - cycles|", diff.max(), "mean", diff.mean(), "spread", spread)
    assert spread > 0.8
    assert diff.max() < 0.04
