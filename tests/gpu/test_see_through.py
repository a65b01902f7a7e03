"""See-through surfaces as Cycles has them: glass (Transmission Weight 1) and a Transparent BSDF
let light and the camera through. One object holds an opaque frame and a glass pane (two
material slots) above a sunlit floor; our F12 against Cycles' with the pane made a Transparent
BSDF (which Cycles lets shadow rays through exactly; its glass passes the sun only as caustics,
which converge slowly):

- the frame casts its shadow, in ours as in Cycles';
- under the pane the floor is as bright as the open floor, in ours as in Cycles' (before, the
  pane was opaque to the preview: a glass window kept the sun out of the room);
- the camera sees the floor through the pane, as Cycles' does.
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

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
glass = principled("Glass", (0.9, 0.9, 0.9))
glass.node_tree.nodes["Principled BSDF"].inputs["Transmission Weight"].default_value = 1.0
frame = cube("Frame", 1.0, (-0.6, 0.0, 1.5))
frame.scale = (1.0, 1.6, 0.1)
frame.data.materials.append(principled("FrameMat", (0.6, 0.3, 0.1)))
pane = cube("Pane", 1.0, (0.6, 0.0, 1.5))
pane.scale = (1.0, 1.6, 0.02)
pane.data.materials.append(glass)
bpy.ops.object.select_all(action="DESELECT")
frame.select_set(True)
pane.select_set(True)
bpy.context.view_layer.objects.active = frame
bpy.ops.object.join()                       # one object, two material slots
window = bpy.context.object
window.name = "Window"
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.data.angle = 0.0
sun.rotation_euler = (0.0, 0.3, 0.0)
aimed_camera((0.0, -6.0, 7.0), (0.0, 0.0, 0.5))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
res, err = bake()
assert err is None, err

render_lumen(save=("combined", "position", "view_proj"))
replace_surface(glass, "ShaderNodeBsdfTransparent")
render_cycles(16)
emit(sun=list(sun.matrix_world.to_3x3() @ mathutils.Vector((0.0, 0.0, 1.0))),
     baked=sorted(o.name for o in bpy.context.scene.objects if o.type == "MESH"))
"""


def _pixel(view_proj, p):
    h = np.asarray(view_proj) @ np.array([*p, 1.0])
    xy = (h[:2] / h[3] * 0.5 + 0.5) * SIZE
    return int(xy[1]), int(xy[0])                 # row, column (row 0 at the bottom)


def test_glass_lets_the_sun_and_the_camera_through_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    ours = np.load(tmp_path / "combined.npy")
    pos = np.load(tmp_path / "position.npy")
    ref = np.load(tmp_path / "cycles.npy")
    vp = np.load(tmp_path / "view_proj.npy")
    sun = np.array(run.result["sun"])                   # towards the sun
    lum = lambda img, r, c: float(img[r, c, :3].mean())   # noqa: E731

    def floor_under(centre):                            # the sun's ray through it, on the floor
        return np.asarray(centre) - sun * (centre[2] / sun[2])

    open_floor = _pixel(vp, (0.0, -2.6, 0.0))
    under_frame = _pixel(vp, floor_under((-0.6, 0.0, 1.5)))
    under_pane = _pixel(vp, floor_under((0.6, 0.0, 1.5)))
    for where in (open_floor, under_frame, under_pane):
        assert pos[where][3] > 0.5 and abs(pos[where][2]) < 1e-3, where     # the floor
    values = {k: (lum(ours, *p), lum(ref, *p)) for k, p in
              (("open", open_floor), ("frame", under_frame), ("pane", under_pane))}
    print("ours / cycles", values)
    for i in (0, 1):                                   # ours, then Cycles'
        assert values["frame"][i] < 0.4 * values["open"][i]
        assert values["pane"][i] > 0.85 * values["open"][i]
    assert abs(values["pane"][0] / values["pane"][1] - 1.0) < 0.15

    # the camera through the pane's centre: the floor, in ours as in Cycles' (whose floor there
    # is as bright as ours)
    r, c = _pixel(vp, (0.6, 0.0, 1.51))
    print("through the pane: ours", ours[r, c], pos[r, c], "cycles", ref[r, c])
    assert pos[r, c, 3] > 0.5 and abs(pos[r, c, 2]) < 1e-3
    assert ours[r, c, 3] == 1.0
    assert abs(lum(ours, r, c) / lum(ref, r, c) - 1.0) < 0.2
    # the frame is drawn
    r, c = _pixel(vp, (-0.6, 0.0, 1.55))
    assert pos[r, c, 3] > 0.5 and abs(pos[r, c, 2] - 1.55) < 0.02
