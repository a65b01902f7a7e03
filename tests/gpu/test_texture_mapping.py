"""A Mapping node between the UVs and an Image Texture (tiling, offset, rotation: how tiled
floors are set up, and how the glTF importer writes KHR_texture_transform), against Cycles: two
planes seen from above, a two-colour checker image sampled Closest, one through a Point Mapping
(Location, a Z Rotation, Scale 3 x 2), one through a Texture Mapping (its inverse).

- our G-buffer albedo shows the same checker as Cycles' Diffuse Color pass: each pixel
  classified by the nearer of the two colours agrees on over 90% of the planes' pixels (edges
  differ: our filter is bilinear);
Before, the Mapping node was ignored with a warning: one tile of the checker over the plane
(agreement near a coin's 50%).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 96
A, B = (0.8, 0.2, 0.1), (0.1, 0.3, 0.8)

SNIPPET = f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
img = bpy.data.images.new("Checker", 8, 8, alpha=False, float_buffer=True)
i = np.arange(8) // 4
check = ((i[:, None] + i[None, :]) % 2).astype(bool)
px = np.ones((8, 8, 4), np.float32)
px[..., :3] = np.where(check[..., None], {A!r}, {B!r})
img.pixels.foreach_set(px.ravel())

def mapped(name, kind):
    mat = principled(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = 'Closest'
    m = nodes.new("ShaderNodeMapping")
    m.vector_type = kind
    m.inputs["Location"].default_value = (0.1, 0.2, 0.0)
    m.inputs["Rotation"].default_value = (0.0, 0.0, 0.5)
    m.inputs["Scale"].default_value = (3.0, 2.0, 1.0)
    links.new(nodes.new("ShaderNodeTexCoord").outputs["UV"], m.inputs["Vector"])
    links.new(m.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return mat

for x, kind in ((-1.1, 'POINT'), (1.1, 'TEXTURE')):
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(x, 0.0, 0.0))
    bpy.context.object.data.materials.append(mapped(kind, kind))
cam = aimed_camera((0.0, 0.0, 8.0), (0.0, 0.0, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 4.6
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

R = render_lumen(save=("albedo", "position"))
emit(notes=R.get("notes", []))
render_cycles(1, exr="cycles.exr", passes=("use_pass_diffuse_color",))
"""


def diffuse_color(path):
    import OpenImageIO as oiio
    first = oiio.ImageBuf(str(path))
    for k in range(first.nsubimages):
        buf = oiio.ImageBuf(str(path), k, 0)
        if "Diffuse Color" in buf.spec().channelnames[0]:
            return buf.get_pixels(oiio.FLOAT)[::-1]       # rows bottom first, as ours
    raise AssertionError("no Diffuse Color pass")


def test_mapping_node_tiles_and_turns_the_texture_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    assert not any("Mapping" in n for n in run.result["notes"]), run.result["notes"]
    albedo = np.load(tmp_path / "albedo.npy")[..., :3]
    pos = np.load(tmp_path / "position.npy")
    ref = diffuse_color(tmp_path / "cycles.exr")[..., :3]
    a, b = np.array(A), np.array(B)

    def is_a(img):
        return np.linalg.norm(img - a, axis=-1) < np.linalg.norm(img - b, axis=-1)

    for centre in (-1.1, 1.1):
        on = (pos[..., 3] > 0.5) & (np.abs(pos[..., 0] - centre) < 0.95) & (np.abs(pos[..., 1]) < 0.95)
        # Cycles' diffuse colour is the base colour times the dielectric's diffuse share: the
        # classes compare by hue, which that factor does not change
        agree = (is_a(albedo) == is_a(ref))[on].mean()
        print("plane", centre, "pixels", on.sum(), "agreement", agree)
        assert on.sum() > 500 and agree > 0.9
