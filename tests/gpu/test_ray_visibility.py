"""Ray visibility as Cycles has it. Holdouts (Object > Visibility > Holdout, a holdout collection
in the view layer): Cycles and EEVEE render such an object transparent (rgba 0) where it is the nearest surface, hiding what is
behind it, while it still casts shadows and bounces light. Our F12 against Cycles' on the same
scene (llvmpipe through bpy): a floor under a sun, a cube held out by its own flag, one by its
collection, one by its material (a Holdout shader: drawn black before), and a plain one.

- where a held-out cube is nearest, our Combined is exactly rgba 0 (Film > Transparent off), and
  that region matches Cycles' transparent one;
- the plain cube is drawn as before (alpha 1) and the floor around the cubes too; through the
  Indirect Only cube the camera sees the floor, in ours as in Cycles';
- the held-out cube's shadow stays on the floor (dark against the sunlit floor beside it), in
  ours as in Cycles';
- where the shadowless cube's shadow would be, the floor is as bright as the sunlit floor.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64

SNIPPET = f"""
import mathutils
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
own = cube("Own", 1.0, (0.0, 0.0, 0.5))
own.data.materials.append(principled("Own", (0.8, 0.1, 0.1)))
own.is_holdout = True
held = bpy.data.collections.new("Held")
scene.collection.children.link(held)
by_collection = cube("ByCollection", 1.0, (2.0, 0.5, 0.5))
for c in list(by_collection.users_collection):
    c.objects.unlink(by_collection)
held.objects.link(by_collection)
by_collection.data.materials.append(principled("Coll", (0.1, 0.8, 0.1)))
bpy.context.view_layer.layer_collection.children["Held"].holdout = True
indirect = bpy.data.collections.new("Indirect")
scene.collection.children.link(indirect)
ghost = cube("Ghost", 1.0, (2.2, -2.0, 0.5))
for c in list(ghost.users_collection):
    c.objects.unlink(ghost)
indirect.objects.link(ghost)
ghost.data.materials.append(principled("Ghost", (0.9, 0.05, 0.05)))
bpy.context.view_layer.layer_collection.children["Indirect"].indirect_only = True
shadowless = cube("Shadowless", 1.0, (0.0, 2.5, 0.5))
shadowless.data.materials.append(principled("Shadowless", (0.8, 0.8, 0.1)))
shadowless.visible_shadow = False
shader = cube("HoldoutShader", 1.0, (-2.2, -2.0, 0.5))
held_mat = bpy.data.materials.new("HoldoutShader")
held_mat.use_nodes = True
nodes = held_mat.node_tree.nodes
nodes.remove(nodes["Principled BSDF"])
held_mat.node_tree.links.new(nodes.new("ShaderNodeHoldout").outputs[0],
                             nodes["Material Output"].inputs["Surface"])
shader.data.materials.append(held_mat)
plain = cube("Plain", 1.0, (-2.0, 0.5, 0.5))
plain.data.materials.append(principled("Plain", (0.1, 0.1, 0.8)))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.data.angle = 0.0
sun.rotation_euler = (0.0, 0.6, 0.0)          # light from +x and above: shadows towards -x
aimed_camera((0.0, -7.0, 5.0), (0.0, 1.0, 0.3))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
res, err = bake()
assert err is None, err

scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.aa_samples = 1
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
np.save("lumen.npy", R["combined"])
np.save("position.npy", R["position"])
np.save("view_proj.npy", R["view_proj"])

scene.render.engine = "CYCLES"
scene.cycles.samples = 16
scene.cycles.device = "CPU"
scene.render.filter_size = 0.01
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_mode = "RGBA"
scene.render.filepath = str(__import__("pathlib").Path("cycles.exr").resolve())
bpy.ops.render.render(write_still=True)
img = bpy.data.images.load(scene.render.filepath)
px = np.empty(len(img.pixels), np.float32)
img.pixels.foreach_get(px)
np.save("cycles.npy", px.reshape({SIZE}, {SIZE}, 4))
emit(sun=list(sun.matrix_world.to_3x3() @ mathutils.Vector((0.0, 0.0, 1.0))))
"""


def _pixel(view_proj, p):
    h = np.asarray(view_proj) @ np.array([*p, 1.0])
    xy = (h[:2] / h[3] * 0.5 + 0.5) * SIZE
    return int(xy[1]), int(xy[0])                 # row, column (row 0 at the bottom)


def test_holdout_indirect_only_and_shadow_visibility_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    ours = np.load(tmp_path / "lumen.npy")
    pos = np.load(tmp_path / "position.npy")
    ref = np.load(tmp_path / "cycles.npy")
    vp = np.load(tmp_path / "view_proj.npy")

    held = np.abs(pos[..., 3] - 0.25) < 1e-6            # the G-buffer's holdout pixels
    surface = pos[..., 3] > 0.5
    theirs = ref[..., 3] < 0.5                          # Cycles: transparent there
    print("holdout pixels ours", held.sum(), "cycles", theirs.sum(), "both", (held & theirs).sum())
    assert held.sum() > 30
    np.testing.assert_array_equal(ours[held], 0.0)      # rgba 0, Film > Transparent off
    assert (ours[~held][:, 3] == 1.0).all()             # everything else opaque
    iou = (held & theirs).sum() / max((held | theirs).sum(), 1)
    assert iou > 0.85, iou

    # each cube's top centre: the held-out ones rgba 0, the plain one drawn
    for name, top, transparent in (("Own", (0.0, 0.0, 1.0), True),
                                   ("ByCollection", (2.0, 0.5, 1.0), True),
                                   ("HoldoutShader", (-2.2, -2.0, 1.0), True),
                                   ("Plain", (-2.0, 0.5, 1.0), False)):
        r, c = _pixel(vp, top)
        print(name, "ours", ours[r, c], "cycles", ref[r, c])
        assert bool(held[r, c]) == transparent and bool(theirs[r, c]) == transparent, name
        if not transparent:
            assert surface[r, c] and ours[r, c, 2] > ours[r, c, 0]          # blue

    # an Indirect Only collection's cube: the camera sees the floor through it, as in Cycles
    r, c = _pixel(vp, (2.2, -2.0, 1.0))
    print("Ghost ours", ours[r, c], pos[r, c], "cycles", ref[r, c])
    assert surface[r, c] and abs(pos[r, c, 2]) < 1e-3                  # the floor behind it
    for img in (ours, ref):
        assert img[r, c, 3] == 1.0 and abs(img[r, c, 0] - img[r, c, 1]) < 0.1 * img[r, c, 1]

    # the held-out cube's shadow on the floor: the sun's ray through the cube's centre
    sun = np.array(run.result["sun"])                   # towards the sun
    centre = np.array([0.0, 0.0, 0.5])
    shadow = centre - sun * (centre[2] / sun[2])
    shadow[0] -= 0.4                                    # into the shadow, away from the cube
    lit = np.array([0.0, -2.5, 0.0])
    rs, cs = _pixel(vp, shadow)
    rl, cl = _pixel(vp, lit)
    assert surface[rs, cs] and surface[rl, cl]
    lum = lambda img, r, c: float(img[r, c, :3].mean())   # noqa: E731
    print("shadow / lit: ours", lum(ours, rs, cs), lum(ours, rl, cl),
          "cycles", lum(ref, rs, cs), lum(ref, rl, cl))
    assert lum(ref, rs, cs) < 0.5 * lum(ref, rl, cl)       # (the configuration)
    assert lum(ours, rs, cs) < 0.5 * lum(ours, rl, cl)

    # a cube that casts no shadow (Visibility > Ray Visibility > Shadow off): the floor where
    # its shadow would be is as bright as the sunlit floor, in ours as in Cycles'; the cube
    # itself is drawn
    centre = np.array([0.0, 2.5, 0.5])
    spot = centre - sun * (centre[2] / sun[2])
    spot[0] -= 0.4
    rn, cn = _pixel(vp, spot)
    rt, ct = _pixel(vp, (0.0, 2.5, 1.0))
    assert surface[rn, cn] and abs(pos[rn, cn, 2]) < 1e-3 and surface[rt, ct]
    print("no shadow / lit: ours", lum(ours, rn, cn), lum(ours, rl, cl),
          "cycles", lum(ref, rn, cn), lum(ref, rl, cl))
    for img in (ref, ours):
        assert lum(img, rn, cn) > 0.8 * lum(img, rl, cl)
