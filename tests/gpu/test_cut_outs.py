"""Cut-outs (a Base Color image's Alpha into the Principled BSDF's Alpha, or a Mix Shader with a
Transparent BSDF by that Alpha: leaves, fences, decals), against Cycles: a red plane cut into a
4 x 4 checker of holes above a grey floor, seen from above.

- where the image's alpha is under 0.5 our G-buffer shows the floor, where it is over, the
  plane; the holes match Cycles' (the floor's grey showing through the red) in over 85% of the
  plane's pixels (intersection over union; edges differ by the filters);
- the Mix Shader form cuts the same holes as the Principled form;
- a texture of one-texel holes seen minified keeps half its pixels (the alpha test reads the
  base level; the mip levels' mean alpha, near 0.5, drew 79% of them; Cycles' point samples of
  such a texture alias, so it is no reference here).
Before, a cut-out was drawn opaque: the camera saw a red square.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64

SNIPPET = f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
img = bpy.data.images.new("Cut", 8, 8, alpha=True)
i = np.arange(8) // 2
alpha = ((i[:, None] + i[None, :]) % 2).astype(np.float32)
px = np.zeros((8, 8, 4), np.float32)
px[..., 0] = 0.9
px[..., 1] = 0.05
px[..., 2] = 0.05
px[..., 3] = alpha
img.pixels.foreach_set(px.ravel())
img.pack()

def cut_material(name, mix):
    mat = principled(name, (0.9, 0.05, 0.05))
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = 'Closest'
    bsdf = nodes["Principled BSDF"]
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    if mix:
        m = nodes.new("ShaderNodeMixShader")
        links.new(tex.outputs["Alpha"], m.inputs[0])
        links.new(nodes.new("ShaderNodeBsdfTransparent").outputs[0], m.inputs[1])
        links.new(bsdf.outputs[0], m.inputs[2])
        links.new(m.outputs[0], nodes["Material Output"].inputs["Surface"])
    else:
        links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    return mat

bpy.ops.mesh.primitive_plane_add(size=2.0, location=(-1.2, 0.0, 1.0))
bpy.context.object.data.materials.append(cut_material("Leaf", mix=False))
bpy.ops.mesh.primitive_plane_add(size=2.0, location=(1.2, 0.0, 1.0))
bpy.context.object.data.materials.append(cut_material("Fence", mix=True))
fine = bpy.data.images.new("Fine", 64, 64, alpha=True)       # holes of one texel: minified
k = np.arange(64)
fpx = np.zeros((64, 64, 4), np.float32)
fpx[..., 1] = 0.9
fpx[..., 3] = ((k[:, None] + k[None, :]) % 2).astype(np.float32)
fine.pixels.foreach_set(fpx.ravel())
fine.pack()
leaves = cut_material("Leaves", mix=False)
leaves.node_tree.nodes["Image Texture"].image = fine
bpy.ops.mesh.primitive_plane_add(size=1.6, location=(0.0, 1.8, 1.0))
bpy.context.object.data.materials.append(leaves)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.0, 0.0, 0.0)
cam = aimed_camera((0.0, 0.0, 8.0), (0.0, 0.0, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 5.0
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

render_lumen(save=("position", "view_proj"))
render_cycles(4)
"""


def test_cut_outs_show_what_is_behind_their_holes_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    pos = np.load(tmp_path / "position.npy")
    ref = np.load(tmp_path / "cycles.npy")
    surface = pos[..., 3] > 0.5
    assert surface.all()
    on_plane = pos[..., 2] > 0.5                        # ours: the plane drawn there
    red = ref[..., 0] > 2.0 * ref[..., 1]               # Cycles: the red plane
    for centre in (-1.2, 1.2):
        x, y = pos[..., 0], pos[..., 1]
        inside = (np.abs(x - centre) < 0.95) & (np.abs(y) < 0.95)   # the plane's square
        ours, theirs = on_plane & inside, red & inside
        iou = (ours & theirs).sum() / max((ours | theirs).sum(), 1)
        print("plane at", centre, "ours", ours.sum(), "cycles", theirs.sum(), "iou", iou)
        assert 0.35 < ours.sum() / inside.sum() < 0.65  # half of it is holes
        assert iou > 0.85
    # a texture of one-texel holes seen minified (2.5 texels a pixel): its mip levels' mean
    # alpha, near 0.5, drew 79% of the pixels; the base level's alpha keeps half
    inside = (np.abs(pos[..., 0]) < 0.75) & (np.abs(pos[..., 1] - 1.8) < 0.75)
    leaves = on_plane & inside
    print("minified leaves: ours", leaves.sum() / inside.sum())
    assert 0.3 < leaves.sum() / inside.sum() < 0.7
