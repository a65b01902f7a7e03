"""Cut-outs' shadows (leaves, a fence) against Cycles: two 1 m planes 1.5 m above a grey floor
under a 45-degree sun, one opaque, one cut into a 4 x 4 checker of holes by its Base Color image's
alpha, seen from above.

- under the cut-out the floor gets half the sun, as the mean of Cycles' checker of light and
  shadow there (within 0.1 of the open floor's light); before, the SDFs' whole card cast a
  full shadow (0.0x the sun's light);
- the opaque plane's shadow is as dark as Cycles' (the cut-out's change leaves it alone);
- the light the cut-out lets through is measured on the mesh: 0.5 of the checker's area
  (lumen_addon.materials.shadow_transmission).

And the GI rays: under a 4 x 4 m roof cut into the same checker, lit by a uniform sky alone
(no lights), the floor seen through its holes gets the sky's light through the others as
Cycles' does (gi_trace_lib.glsl gi_radiance_from goes on past a cut-out by its holes' share).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64

# a checker of holes (2x2 texels each) in a green leaf's Base Color image, its Alpha into the
# Principled BSDF's Alpha when `cut` (the cut-out)
CHECKER_LEAF = """
def checker_leaf(texels, cut=True):
    img = bpy.data.images.new("Cut", texels, texels, alpha=True)
    i = np.arange(texels) // 2
    px = np.zeros((texels, texels, 4), np.float32)
    px[..., 1] = 0.6
    px[..., 3] = ((i[:, None] + i[None, :]) % 2).astype(np.float32)
    img.pixels.foreach_set(px.ravel())
    img.pack()
    leaf = principled("Leaf", (0.1, 0.6, 0.1))
    nodes, links = leaf.node_tree.nodes, leaf.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = 'Closest'
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    if cut:
        links.new(tex.outputs["Alpha"], nodes["Principled BSDF"].inputs["Alpha"])
    return leaf, tex
"""

SNIPPET = CHECKER_LEAF + f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
leaf, tex = checker_leaf(8)
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-0.8, 0.0, 1.5))
bpy.context.object.name = "CutOut"
bpy.context.object.data.materials.append(leaf)
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.8, 0.0, 1.5))
bpy.context.object.name = "Opaque"
bpy.context.object.data.materials.append(principled("Board", (0.1, 0.6, 0.1)))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (np.radians(45.0), 0.0, 0.0)       # the light travels towards +y
cam = aimed_camera((0.0, 0.75, 8.0), (0.0, 0.75, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 4.0
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
res, err = bake()
assert err is None, err
render_lumen(save=("combined", "position"))
from lumen_gi.operators.extract import extract_scene
emit(transmission={{o.name: o.shadow_transmission
                   for o in extract_scene(bpy.context.evaluated_depsgraph_get())[0]}})
render_cycles(64)
"""


def test_cut_outs_let_their_holes_share_of_the_sun_through_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    print("shadow transmission:", run.result["transmission"])
    assert abs(run.result["transmission"]["CutOut"] - 0.5) < 0.02
    assert run.result["transmission"]["Opaque"] == 0.0
    ours = np.load(tmp_path / "combined.npy")[..., :3].mean(-1)
    ref = np.load(tmp_path / "cycles.npy")[..., :3].mean(-1)
    pos = np.load(tmp_path / "position.npy")
    x, y = pos[..., 0], pos[..., 1]
    floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 1e-3)
    band = (y > 1.1) & (y < 1.9)                       # the planes' shadows: y in [1, 2]
    regions = {"cut": floor & band & (np.abs(x + 0.8) < 0.4),
               "opaque": floor & band & (np.abs(x - 0.8) < 0.4),
               "open": floor & (y > -1.2) & (y < -0.6)}
    for name, m in regions.items():
        assert m.sum() > 20, name
    means = {k: (float(ours[m].mean()), float(ref[m].mean())) for k, m in regions.items()}
    share = {k: (v[0] / means["open"][0], v[1] / means["open"][1]) for k, v in means.items()}
    print("floor light over the open floor's, ours / cycles:", share)
    assert abs(share["cut"][1] - 0.5) < 0.12          # the scene is what it says
    assert abs(share["cut"][0] - share["cut"][1]) < 0.1
    assert share["opaque"][0] < 0.15 and share["opaque"][1] < 0.15


SKY_SNIPPET = CHECKER_LEAF + f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
leaf, tex = checker_leaf(16)
bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 1.0))
bpy.context.object.name = "Roof"
bpy.context.object.data.materials.append(leaf)
cam = aimed_camera((0.0, 0.0, 8.0), (0.0, 0.0, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 3.0
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
res, err = bake()
assert err is None, err
render_lumen(save=("combined", "position"), quality="MEDIUM")
render_cycles(128, bounces=4)
"""


def test_gi_rays_let_the_sky_through_a_cut_out_roof_as_cycles(tmp_path):
    run = run_python(SKY_SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    ours = np.load(tmp_path / "combined.npy")[..., :3].mean(-1)
    ref = np.load(tmp_path / "cycles.npy")[..., :3].mean(-1)
    pos = np.load(tmp_path / "position.npy")
    x, y = pos[..., 0], pos[..., 1]
    # the floor seen through the roof's holes, away from its edges (there the open sky comes in)
    under = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 1e-3) & (np.abs(x) < 1.2) \
        & (np.abs(y) < 1.2)
    assert under.sum() > 100
    got, want = float(ours[under].mean()), float(ref[under].mean())
    print("floor under the roof, ours / cycles:", got, want)
    assert abs(got / want - 1.0) < 0.15


VIEW_SNIPPET = CHECKER_LEAF + f"""
from lumen_gi.gpu_shaders import engine, direct_light
import viewport_harness

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
leaf, tex = checker_leaf(8, cut=False)
nodes, links = leaf.node_tree.nodes, leaf.node_tree.links
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.0, 0.0, 1.5))
bpy.context.object.data.materials.append(leaf)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (np.radians(45.0), 0.0, 0.0)
cam = aimed_camera((0.0, 0.75, 8.0), (0.0, 0.75, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 4.0
scene.world = bpy.data.worlds.new("World")
scene.world.color = (0.05, 0.05, 0.05)
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.viewport_quality = "LOW"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
settle = direct_light.Progressive.FRAMES + 2
shots = {{}}

def step(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if i == settle - 1:
        shots["opaque"] = (R["combined"].copy(), R["position"].copy())
        links.new(tex.outputs["Alpha"], nodes["Principled BSDF"].inputs["Alpha"])   # cut it
    if i == 2 * settle - 1:
        shots["cut"] = (R["combined"].copy(), R["position"].copy())

viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 2 * settle, step)
for name, (img, pos) in shots.items():
    np.save(name + ".npy", img)
    np.save(name + "_pos.npy", pos)
"""


def test_viewport_sees_a_material_become_a_cut_out(tmp_path):
    """The viewport, one engine instance: linking the leaf's image Alpha into its Alpha (an edit,
    no re-bake) lets half the sun through onto the floor under it within the progressive
    direct light's frames (shadow_pass reaches the object table, the cut-out variant compiles)."""
    run = run_python(VIEW_SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    share = {}
    for name in ("opaque", "cut"):
        img = np.load(tmp_path / f"{name}.npy")[..., :3].mean(-1)
        pos = np.load(tmp_path / f"{name}_pos.npy")
        x, y = pos[..., 0], pos[..., 1]
        floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 1e-3)
        under = floor & (y > 1.1) & (y < 1.9) & (np.abs(x) < 0.4)
        lit = floor & (y > -1.2) & (y < -0.6)
        assert under.sum() > 20 and lit.sum() > 20
        share[name] = float(img[under].mean() / img[lit].mean())
    print("floor under the leaf over the open floor, viewport:", share)
    assert share["opaque"] < 0.15
    assert 0.4 < share["cut"] < 0.65
