"""The viewport's scene extraction follows the depsgraph (operators/extract.py ExtractionCache,
gpu_shaders/mesh_batches.py): through the engine's real view_draw (tools/viewport_harness.py,
one engine instance for all redraws), a moved object, a moved vertex, an added modifier, a
changed material colour, an added and a deleted object each show in the next frame's G-buffer
(world position and albedo at a pixel, under an orthographic top view where a pixel's world
x, y are known), each re-reads only the mesh it concerns, and a still frame reads no mesh and
uploads nothing (the instance table neither)."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64          # 4 m ortho view: 1/16 m a pixel

SNIPPET = f"""
from lumen_gi.gpu_shaders import engine
import viewport_harness

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
floor = bpy.context.object
floor.name = "Floor"
floor.data.materials.append(principled("FloorMat", (0.5, 0.5, 0.5)))
box = cube("Box", 0.8, (-1.0, 0.0, 0.4))
box.data.materials.append(principled("BoxMat", (0.9, 0.05, 0.05)))
other = cube("Other", 0.6, (1.0, 0.9, 0.3))
other.data.materials.append(principled("OtherMat", (0.05, 0.05, 0.9)))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 4.0
cam.location = (0.0, 0.0, 10.0)
scene.camera = cam
scene.render.engine = "LUMEN_GI"
scene.render.preview_pixel_size = "1"
scene.lumen.engine.render_quality = scene.lumen.engine.viewport_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err

def at(img, x, y):
    i, j = int((x + 2.0) * {SIZE} / 4.0), int((y + 2.0) * {SIZE} / 4.0)
    return [float(v) for v in img[j, i, :3]]       # row 0 is the bottom row (y = -2)

PROBES = dict(box=(-1.0, 0.0), box_moved=(0.0, -1.0), other=(1.0, 0.9), array=(1.6, 0.9),
              new=(0.0, 1.3))
LABELS = ("first", "moved", "vertex", "modifier", "material", "added", "deleted", "still")
frames = {{}}

def step(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    frames[LABELS[i]] = dict(
        read=R["meshes_read"], built=R["gbuffer_batches_built"],
        table=R["instance_table_uploaded"], draws=R["gbuffer_draws"], stale=R["stale"],
        reused=R["gbuffer_reused"], frame_reused=R["reused_frame"],
        walked=R["extraction_walked"],
        pos={{k: at(R["position"], *p) for k, p in PROBES.items()}},
        alb={{k: at(R["albedo"], *p) for k, p in PROBES.items()}})
    label = LABELS[i]
    if label == "first":
        box.location = (0.0, -1.0, 0.4)
    elif label == "moved":
        co = np.empty(len(other.data.vertices) * 3, np.float32)
        other.data.vertices.foreach_get("co", co)
        co[2::3] += 0.3                              # every vertex up: the top at z = 0.9
        other.data.vertices.foreach_set("co", co)
        other.data.update()
    elif label == "vertex":
        mod = other.modifiers.new("Array", 'ARRAY')  # a second copy 0.6 m along +x
        mod.count = 2
    elif label == "modifier":
        box.active_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (
            0.1, 0.8, 0.2, 1.0)
    elif label == "material":
        new = cube("New", 0.4, (0.0, 1.3, 0.2))
        new.data.materials.append(principled("NewMat", (0.9, 0.8, 0.1)))
    elif label == "added":
        bpy.data.objects.remove(box)

viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, len(LABELS), step)
emit(frames=frames)
"""


def test_viewport_frames_follow_the_depsgraph(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    f = run.result["frames"]
    for label, fr in f.items():
        print(label, {k: fr[k] for k in ("read", "built", "table", "draws")})
    red, green = [0.9, 0.05, 0.05], [0.1, 0.8, 0.2]
    grey, blue, yellow = [0.5] * 3, [0.05, 0.05, 0.9], [0.9, 0.8, 0.1]

    def close(a, b, tol=1e-4):
        return np.allclose(a, b, atol=tol)

    first = f["first"]
    assert first["read"] == 3 and first["built"] == 3 and first["table"]
    assert close(first["alb"]["box"], red) and close(first["pos"]["box"][2], 0.8)
    assert close(first["alb"]["box_moved"], grey) and close(first["pos"]["box_moved"][2], 0.0)
    # a moved object: nothing read or built, the instance table re-uploaded, and no walk over
    # the instances (only its matrix read: ExtractionCache.mark_moved); every other edit walks
    moved = f["moved"]
    assert moved["read"] == 0 and moved["built"] == 0 and moved["table"]
    assert not moved["walked"] and all(f[k]["walked"] for k in list(f)[2:-1]), \
        {k: f[k]["walked"] for k in f}
    assert close(moved["alb"]["box"], grey) and close(moved["pos"]["box"][2], 0.0)
    assert close(moved["alb"]["box_moved"], red) and close(moved["pos"]["box_moved"][2], 0.8)
    # a moved vertex: that mesh alone is read again
    vertex = f["vertex"]
    assert vertex["read"] == 1 and vertex["built"] == 1 and not vertex["table"]
    assert close(vertex["pos"]["other"][2], 0.9) and close(vertex["alb"]["other"], blue)
    assert close(vertex["alb"]["array"], grey)
    # an added modifier: the array's second copy shows
    modifier = f["modifier"]
    assert modifier["read"] == 1 and close(modifier["alb"]["array"], blue)
    assert close(modifier["pos"]["array"][2], 0.9)
    # a material colour: the box (and only its mesh) read again, its new colour drawn
    material = f["material"]
    assert material["read"] == 1 and close(material["alb"]["box_moved"], green)
    # an added object is read and drawn; a deleted one leaves the G-buffer
    added = f["added"]
    assert added["read"] == 1 and close(added["alb"]["new"], yellow)
    assert close(added["pos"]["new"][2], 0.4)
    assert "New" in added["stale"]
    deleted = f["deleted"]
    assert deleted["read"] == 0 and deleted["table"]
    assert close(deleted["alb"]["box_moved"], grey) and close(deleted["pos"]["box_moved"][2], 0.0)
    # a still frame reads no mesh, builds no batch, uploads no instance table; it is the last
    # frame again (converged: no pass run) or draws no G-buffer (the same view of the same
    # instances: tests/gpu/test_screen_trace.py's still viewport)
    still = f["still"]
    assert still["read"] == 0 and still["built"] == 0 and not still["table"]
    assert still["alb"] == deleted["alb"] and still["pos"] == deleted["pos"]
    assert still["frame_reused"] or (still["reused"] and still["draws"] == 0), still
    # every change above drew the G-buffer again (a material colour: the same instances, the
    # same view, new batches)
    for label in list(f)[:-1]:
        assert not f[label]["frame_reused"] and not f[label]["reused"] \
            and f[label]["draws"] > 0, (label, f[label])


INSTANCES = f"""
from lumen_gi.gpu_shaders import engine, gbuffer
from lumen_gi.operators.extract import extract_scene
import viewport_harness

scene = empty_scene(voxel_density=6.0, cache_dir="cache")
scatter = geometry_nodes_scatter("Scatter")         # a plane and 4 icospheres on its corners
scatter.data.materials.append(principled("ScatterMat", (0.2, 0.6, 0.3)))
parts = bpy.data.collections.new("Parts")
scene.collection.children.link(parts)
part = cube("Part", 0.5, (0.0, 0.0, 0.25))
part.data.materials.append(principled("PartMat", (0.8, 0.3, 0.1)))
for c in part.users_collection:
    c.objects.unlink(part)
parts.objects.link(part)
bpy.context.view_layer.layer_collection.children["Parts"].exclude = True
first = collection_instancer("InstA", parts, (0.5, 0.5, 0.0))
second = collection_instancer("InstB", parts, (-0.6, 0.4, 0.0))
solo = cube("Solo", 0.6, (0.3, -0.8, 0.3))
solo.rotation_euler = (0.0, 0.0, 0.5)
solo.scale = (1.0, -1.0, 1.5)                        # mirrored: normals must still face out
bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=0.8,
                                location=(-0.9, -0.6, 0.1))
wavy = bpy.context.object                            # displaced in world coordinates: a move
wavy.name = "Wavy"                                   # changes its shape (a geometry update)
wave = wavy.modifiers.new("Displace", 'DISPLACE')
wave.texture = bpy.data.textures.new("Wave", 'CLOUDS')
wave.texture.noise_scale = 0.2
wave.texture_coords = 'GLOBAL'
wave.strength = 0.3
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
aimed_camera((3.0, -4.0, 5.0), (0.0, 0.0, 0.0))
scene.render.engine = "LUMEN_GI"
scene.render.preview_pixel_size = "1"
scene.lumen.engine.render_quality = scene.lumen.engine.viewport_quality = "OFF"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
out = []

def step(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    objects, _ = extract_scene(bpy.context.evaluated_depsgraph_get())
    old = gbuffer.render_gbuffer(objects, R["view_proj"], {SIZE}, {SIZE})
    ref = {{k: gbuffer.read_texture(old["textures"][k], {SIZE}, {SIZE})
           for k in ("position", "normal", "albedo")}}
    both = (ref["position"][..., 3] > 0.5) & (R["position"][..., 3] > 0.5)
    differ = (ref["position"][..., 3] > 0.5) != (R["position"][..., 3] > 0.5)
    out.append(dict(
        objects=len(objects), triangles=R["triangles"], old_triangles=old["triangles"],
        draws=R["gbuffer_draws"], read=R["meshes_read"], covered=int(both.sum()),
        coverage_differs=int(differ.sum()),
        position=float(np.abs(R["position"] - ref["position"])[both, :3].max()),
        normal=float(np.abs(R["normal"] - ref["normal"])[both, :3].max()),
        albedo=float(np.abs(R["albedo"] - ref["albedo"])[both, :3].max()),
        changed=int((np.abs(R["position"] - out[-1]["pos"]).max(-1) > 0.05).sum()) if out else 0,
        walked=R["extraction_walked"],
        pos=R["position"].copy()))
    if i == 0:
        first.location.x += 0.3                      # move a whole collection instance
    elif i == 1:
        scatter.location.y += 0.3                    # move a geometry-nodes scatter (its
                                                     # instances too: it is no is_instancer)
    elif i == 2:
        wavy.location.x += 0.25                      # its displacement moves across it

viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 4, step)
emit(frames=[{{k: v for k, v in fr.items() if k != "pos"}} for fr in out])
"""


def test_instanced_gbuffer_equals_the_world_space_one(tmp_path):
    """Collection instances, geometry-nodes instances and a mirrored object: the instanced
    G-buffer (local-space batches, matrices on the GPU) equals the world-space one built from
    extract_scene (gbuffer.render_gbuffer), before and after an instancer moved, after a
    geometry-nodes scatter moved (not an `is_instancer`, yet its instances move with it) and
    after a mesh displaced in world coordinates moved (Blender flags that as a geometry update:
    its mesh is read again, not only its matrix)."""
    run = run_python(INSTANCES, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    frames = run.result["frames"]
    print(frames)
    for fr in frames:
        assert fr["objects"] == 9                 # plane, 4 icospheres, 2 parts, Solo, Wavy
        assert fr["triangles"] == fr["old_triangles"] > 0
        assert fr["covered"] > 500 and fr["coverage_differs"] <= 3
        assert fr["position"] < 1e-4 and fr["normal"] < 1e-3 and fr["albedo"] < 1e-6
    assert frames[0]["draws"] == 5 and frames[1]["read"] == 0   # plane, ico, part, Solo, Wavy
    assert frames[1]["changed"] > 20                                 # the instance moved
    assert frames[1]["walked"]            # an instancer moved: its instances walked again
    assert frames[2]["changed"] > 20 and frames[2]["walked"]     # the scatter and its spheres
    assert frames[3]["changed"] > 5 and frames[3]["walked"]      # Wavy, re-read
    assert frames[3]["read"] == 1

