"""Surface attributes for the mesh cards: per-corner normals, UVs, material ids and materials
read from real Blender data, and every bad material falling back with a warning, never a crash."""
import textwrap

import numpy as np

from blender_runner import blender  # noqa: F401  (fixture)



def srgb_eotf(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


EXTRACT = """
from lumen_gi.operators.extract import extract_scene
def extract():
    objects, warnings = extract_scene(bpy.context.evaluated_depsgraph_get())
    return {o.name: o for o in objects}, warnings
def extract_cubes(mats):
    # a cube per material (named as its key, 3 m apart), then extract()
    for i, (name, mat) in enumerate(mats.items()):
        cube(name, location=(3.0 * i, 0.0, 0.0)).data.materials.append(mat)
    return extract()
"""


def test_principled_values_material_ids_and_flat_normals(blender):
    res = blender(EXTRACT + textwrap.dedent("""
        empty_scene()
        box = cube("Box")
        box.data.materials.append(principled("Blue", base=(0.1, 0.2, 0.7)))
        box.data.materials.append(principled("Lamp", base=(0.9, 0.9, 0.9), emission=(1.0, 0.5, 0.25),
                                             strength=3.0))
        mi = np.array([0, 1, 0, 1, 0, 0], np.int32)        # faces 1 and 3 glow
        box.data.polygons.foreach_set("material_index", mi)
        box.data.update()
        plain = cube("Plain", location=(3, 0, 0))           # no material slots at all
        objects, warnings = extract()
        o = objects["Box"]
        m = box.data
        emit(warnings=warnings,
             materials=[(x.name, list(x.base_color), list(x.emission_color), x.emission_strength,
                         x.base_color_texture is None, x.emission_texture is None)
                        for x in o.materials],
             ids=o.material_ids.tolist(),
             expected_ids=[m.polygons[t.polygon_index].material_index for t in m.loop_triangles],
             normals=o.normals.tolist(),
             face_normals=corner_values(m, lambda li: list(m.polygons[
                 next(t.polygon_index for t in m.loop_triangles if li in t.loops)].normal)).tolist(),
             shapes=[list(o.normals.shape), list(o.material_ids.shape)], uvs=o.uvs is None,
             plain=[len(objects["Plain"].materials), objects["Plain"].uvs is None,
                    sorted(set(objects["Plain"].material_ids.tolist()))])
    """))
    r = res.result
    assert r["warnings"] == []
    blue, lamp = r["materials"]
    assert blue[0] == "Blue" and np.allclose(blue[1], (0.1, 0.2, 0.7)) and blue[3] == 0.0
    assert lamp[0] == "Lamp" and np.allclose(lamp[2], (1.0, 0.5, 0.25)) and lamp[3] == 3.0
    assert blue[4] and blue[5] and lamp[4] and lamp[5]          # values, no textures
    assert r["ids"] == r["expected_ids"] and sorted(set(r["ids"])) == [0, 1]
    assert r["shapes"] == [[12, 3, 3], [12]]
    assert np.allclose(r["normals"], r["face_normals"], atol=1e-6)   # flat cube: face normals
    assert r["uvs"]                       # no texture: no UVs needed
    assert r["plain"] == [0, True, [0]]   # no slots: empty list -> the core's plain grey


def test_image_texture_pixels_linearised_and_uvs_of_the_texture_map(blender, tmp_path):
    png = tmp_path / "checker.png"
    res = blender(EXTRACT + textwrap.dedent(f"""
        empty_scene()
        img, px = checker_png({str(png)!r})
        bpy.ops.mesh.primitive_plane_add(size=2.0)
        plane = bpy.context.object; plane.name = "Plane"
        add_uv_map(plane, "Second", scale=(0.5, 0.25), offset=(0.1, 0.2))
        active_render = [l.name for l in plane.data.uv_layers if l.active_render]
        mat = principled("Checker", base=(0.3, 0.3, 0.3), emission=(1, 1, 1), strength=2.0)
        image_texture(mat, img, uv_map="Second")
        image_texture(mat, img, socket="Emission Color", uv_map="Second")   # converted once
        plane.data.materials.append(mat)

        bpy.ops.mesh.primitive_plane_add(size=2.0, location=(3, 0, 0))
        other = bpy.context.object; other.name = "Default"
        add_uv_map(other, "Second", scale=(2.0, 2.0))
        mat2 = principled("Default UV")
        image_texture(mat2, img)                               # no UV Map node: active render map
        other.data.materials.append(mat2)

        # A float image (scene-linear already) and a Non-Color byte image are taken as they are.
        flt = bpy.data.images.new("float", 2, 2, float_buffer=True)
        fpx = np.linspace(0.0, 4.0, 16, dtype=np.float32)
        flt.pixels.foreach_set(fpx)
        data_img = bpy.data.images.new("data", 2, 2)
        data_img.colorspace_settings.name = "Non-Color"
        dpx = (np.arange(16) / 255.0).astype(np.float32)
        data_img.pixels.foreach_set(dpx)
        bpy.ops.mesh.primitive_plane_add(location=(6, 0, 0))
        third = bpy.context.object; third.name = "Linear"
        mat3 = principled("Linear")
        image_texture(mat3, flt)
        third.data.materials.append(mat3)
        bpy.ops.mesh.primitive_plane_add(location=(9, 0, 0))
        fourth = bpy.context.object; fourth.name = "Data"
        mat4 = principled("Data")
        image_texture(mat4, data_img)
        fourth.data.materials.append(mat4)

        objects, warnings = extract()
        o, d, t, dt = objects["Plane"], objects["Default"], objects["Linear"], objects["Data"]
        m = o.materials[0]
        me = plane.data
        emit(warnings=warnings, filepath=img.filepath,
             tex=m.base_color_texture.tolist(), tex_dtype=str(m.base_color_texture.dtype),
             px=px.tolist(), same_array=m.emission_texture is m.base_color_texture,
             base=list(m.base_color), strength=m.emission_strength,
             uvs=o.uvs.tolist(),
             second=corner_values(me, lambda li: list(me.uv_layers["Second"].uv[li].vector)).tolist(),
             first=corner_values(me, lambda li: list(me.uv_layers[0].uv[li].vector)).tolist(),
             default_uvs=d.uvs.tolist(), active_render=active_render,
             default_expected=corner_values(other.data, lambda li: list(
                 other.data.uv_layers[active_render[0]].uv[li].vector)).tolist(),
             float_tex=t.materials[0].base_color_texture.ravel().tolist(), fpx=fpx.tolist(),
             data_tex=dt.materials[0].base_color_texture.ravel().tolist(), dpx=dpx.tolist())
    """))
    r = res.result
    assert r["warnings"] == []
    assert r["filepath"] == str(png)
    tex, px = np.array(r["tex"]), np.array(r["px"])
    assert tex.shape == (4, 8, 4) and r["tex_dtype"] == "float32"     # (H, W, C), row 0 = v 0
    expected = px.copy()
    expected[..., :3] = srgb_eotf(px[..., :3])                          # alpha stays linear
    assert np.allclose(tex, expected, atol=1e-6)
    assert np.allclose(tex[0, 0, :3], [0.0, 0.21586050, 1.0], atol=1e-6)
    assert r["same_array"] and r["strength"] == 2.0
    assert np.allclose(r["base"], 0.3)          # the value stays as the no-UV fallback
    # The UV Map node names "Second": those UVs, not the active render map's.
    assert np.array(r["uvs"]).shape == (2, 3, 2)
    assert np.allclose(r["uvs"], r["second"]) and not np.allclose(r["uvs"], r["first"])
    assert r["active_render"] == ["UVMap"]
    assert np.allclose(r["default_uvs"], r["default_expected"])
    assert np.allclose(r["float_tex"], r["fpx"]) and np.allclose(r["data_tex"], r["dpx"])


def test_corner_normals_of_smooth_sphere_are_unit_and_match_blender(blender):
    res = blender(EXTRACT + textwrap.dedent("""
        empty_scene()
        ball = sphere("Ball", subdivide=1)
        bpy.ops.object.shade_smooth()
        objects, warnings = extract()
        ev = ball.evaluated_get(bpy.context.evaluated_depsgraph_get())
        me = ev.to_mesh()
        expected = corner_values(me, lambda li: list(me.corner_normals[li].vector))
        flat = corner_values(me, lambda li: list(me.polygons[
            me.loop_triangles[0].polygon_index].normal))   # any face normal, to prove smoothness
        ev.to_mesh_clear()
        n = objects["Ball"].normals
        emit(shape=list(n.shape), normals=n.tolist(), expected=expected.tolist(),
             distinct=int(len(np.unique(n.reshape(-1, 3).round(5), axis=0))))
    """))
    r = res.result
    n = np.array(r["normals"])
    assert r["shape"] == [224, 3, 3]
    assert np.allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-5)
    assert np.allclose(n, r["expected"], atol=1e-6)
    # Smooth: corners of one vertex share its normal, so far fewer distinct normals than corners.
    assert r["distinct"] < 224 * 3 / 3


BAD = EXTRACT + """
empty_scene()
png_ok = PNG
def textured(name, image):
    mat = principled(name, base=(0.25, 0.5, 0.75))
    image_texture(mat, image)
    return mat

# 1. a textured material on a mesh without UVs
img, _ = checker_png(png_ok)
no_uv = cube("NoUV")
no_uv.data.uv_layers.remove(no_uv.data.uv_layers[0])
no_uv.data.materials.append(textured("Painted", img))
# 2. an image whose file is missing
gone = bpy.data.images.new("gone.png", 4, 4)
gone.source = 'FILE'
gone.filepath = MISSING
gone.reload()
lost = cube("Lost", location=(2, 0, 0))
lost.data.materials.append(textured("Lost Texture", gone))
# 3. surfaces the conversion does not read: a Toon BSDF, a node group, nothing connected
diffuse = principled("Toon Only"); replace_surface(diffuse, "ShaderNodeBsdfToon")
diffuse.diffuse_color = (0.1, 0.9, 0.2, 1.0)
group = principled("Grouped")
gtree = bpy.data.node_groups.new("My Shader Group", "ShaderNodeTree")
gtree.interface.new_socket("Shader", in_out='OUTPUT', socket_type='NodeSocketShader')
gnode = group.node_tree.nodes.new("ShaderNodeGroup"); gnode.node_tree = gtree
group.node_tree.links.new(gnode.outputs[0], group.node_tree.nodes["Material Output"].inputs["Surface"])
group.diffuse_color = (0.6, 0.1, 0.1, 1.0)
unlinked = principled("Unlinked")
for old in list(unlinked.node_tree.links): unlinked.node_tree.links.remove(old)
unlinked.diffuse_color = (0.3, 0.3, 0.9, 1.0)
ramp = principled("Ramp", base=(1, 0, 0))
ramp.node_tree.links.new(ramp.node_tree.nodes.new("ShaderNodeValToRGB").outputs["Color"],
                         ramp.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
ramp.diffuse_color = (0.4, 0.4, 0.0, 1.0)
odd = cube("Odd", location=(4, 0, 0))
for m in (diffuse, group, unlinked, ramp):
    odd.data.materials.append(m)
odd.data.polygons.foreach_set("material_index", [0, 1, 2, 3, 0, 0])
# 4. an empty material slot in use
holes = cube("Holes", location=(6, 0, 0))
holes.data.materials.append(principled("Fine"))
holes.data.materials.append(None)
holes.data.polygons.foreach_set("material_index", [0, 1, 1, 0, 0, 0])
# 5. a UV Map node naming a map the mesh lacks
renamed = cube("Renamed", location=(8, 0, 0))
mat = principled("Wants UV2"); image_texture(mat, img, uv_map="UV2")
renamed.data.materials.append(mat)
# the same broken material on a linked duplicate: one warning, both objects counted
dup = link(lost.copy()); dup.name = "Lost.dup"
"""


def bad_scene(tmp_path):
    return f"PNG = {str(tmp_path / 'ok.png')!r}\nMISSING = {str(tmp_path / 'gone.png')!r}\n" + BAD


def test_bad_materials_fall_back_with_warnings_naming_object_and_material(blender, tmp_path):
    res = blender(bad_scene(tmp_path) + """
objects, warnings = extract()
def mats(name):
    return [(m.name, [round(c, 4) for c in m.base_color], m.base_color_texture is None)
            for m in objects[name].materials]
emit(warnings=warnings, no_uv=[objects["NoUV"].uvs is None, mats("NoUV")],
     lost=mats("Lost"), odd=mats("Odd"), holes=mats("Holes"),
     renamed=objects["Renamed"].uvs is not None)
""")
    r = res.result
    text = "\n".join(f"{who}: {what}" for who, what in r["warnings"])

    def warned(obj, *words):
        lines = [f"{who}: {what}" for who, what in r["warnings"] if who.startswith(obj)]
        assert any(all(w in line for w in words) for line in lines), (obj, words, text)

    # 1. no UVs: texture kept for other meshes, this object gets uvs=None -> base colour value
    warned("NoUV", "material 'Painted'", "no", "UV map", "colour values")
    assert r["no_uv"] == [True, [["Painted", [0.25, 0.5, 0.75], False]]]
    # 2. missing file: the Base Color value, no texture; the image and its path are named
    warned("Lost (and 1 more objects)", "material 'Lost Texture'", "image 'gone.png'",
           "no pixel data", str(tmp_path / "gone.png"), "Base Color value")
    assert r["lost"] == [["Lost Texture", [0.25, 0.5, 0.75], True]]
    # 3. a shader the conversion does not read (or something but a texture feeding one): its
    # mean colours rendered by Cycles (material_capture); nothing connected: the viewport display
    # colour (there is nothing to render)
    print(r["odd"])
    warned("Odd", "material 'Toon Only'", "Toon BSDF", "rendered by Cycles")
    warned("Odd", "material 'Grouped'", "node group 'My Shader Group'", "rendered by Cycles")
    warned("Odd", "material 'Unlinked'", "Surface", "display colour")
    warned("Odd", "material 'Ramp'", "Base Color", "Color Ramp", "rendered by Cycles")
    names = [m[0] for m in r["odd"]]
    colours = {m[0]: np.array(m[1]) for m in r["odd"]}
    assert names == ["Toon Only", "Grouped", "Unlinked", "Ramp"]
    # the captured ones carry their swatch as a texture (their colours over the UV square)
    assert [m[2] for m in r["odd"]] == [False, False, True, False]
    assert np.allclose(colours["Unlinked"], (0.3, 0.3, 0.9))
    assert np.allclose(colours["Grouped"], 0.0)             # a group with no shader: black
    # the ramp's middle (0.5 grey) through the Principled BSDF: its diffuse and glossy colours
    assert np.allclose(colours["Ramp"], 0.5, atol=0.03), colours["Ramp"]
    assert np.allclose(colours["Toon Only"], colours["Toon Only"][0]) and colours["Toon Only"][0] > 0.3
    # 4. an empty slot: default grey
    warned("Holes", "material slot 2 is empty", "grey")
    assert r["holes"][1] == ["(empty slot 2)", [0.8, 0.8, 0.8], True]
    # 5. a missing named UV map: the active render map instead
    warned("Renamed", "material 'Wants UV2'", "'UV2'", "'UVMap'")
    assert r["renamed"]
    assert len(r["warnings"]) == 8, text     # one per problem, however many objects share it


def test_bad_materials_through_the_operator_report_warnings_and_bake(blender, tmp_path):
    cache = tmp_path / "cache"
    res = blender(bad_scene(tmp_path) + f"""
bpy.context.scene.lumen.bake.cache_dir = {str(cache)!r}
bpy.context.scene.lumen.bake.voxel_density = 4.0
result, error = bake()
emit(result=result, error=error, status=bpy.context.scene.lumen.last_bake.status)
""")
    r = res.result
    assert r["result"] == ["FINISHED"], (r["error"], res.explain())
    warnings = [line for line in res.stdout.splitlines() if line.startswith("Warning: ")]
    for start, words in (("Warning: NoUV: ", "material 'Painted'"),
                         ("Warning: Lost (and 1 more objects): ", "material 'Lost Texture'"),
                         ("Warning: Odd: ", "material 'Grouped'"),
                         ("Warning: Holes: ", "material slot 2")):
        assert any(w.startswith(start) and words in w for w in warnings), (start, warnings)
    assert "8 material warnings" in r["status"], r["status"]


SEE_THROUGH_CASES = """
empty_scene()

def principled_with(name, **inputs):
    m = principled(name, base=(0.2, 0.4, 0.6))
    bsdf = m.node_tree.nodes["Principled BSDF"]
    for k, v in inputs.items():
        bsdf.inputs[k].default_value = v
    return m

def surface(name, kind):
    m = principled(name)
    replace_surface(m, kind)
    return m

def mixed(name, fac, clear_first=False, light_path=None, image=None):
    m = principled(name, base=(0.2, 0.4, 0.6))
    nodes, links = m.node_tree.nodes, m.node_tree.links
    mix = nodes.new("ShaderNodeMixShader")
    clear = nodes.new("ShaderNodeBsdfTransparent")
    bsdf = nodes["Principled BSDF"]
    a, b = (clear, bsdf) if clear_first else (bsdf, clear)
    links.new(a.outputs[0], mix.inputs[1])
    links.new(b.outputs[0], mix.inputs[2])
    mix.inputs[0].default_value = fac
    if light_path is not None:
        links.new(nodes.new("ShaderNodeLightPath").outputs[light_path], mix.inputs[0])
    if image is not None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = image
        links.new(tex.outputs["Alpha"], mix.inputs[0])
    links.new(mix.outputs[0], nodes["Material Output"].inputs["Surface"])
    return m

img, _ = checker_png(Path("checker.png").resolve())
cases = {
    "Opaque": principled_with("Opaque"),
    "Glass": principled_with("Glass", **{"Transmission Weight": 1.0}),
    "MetalGlass": principled_with("MetalGlass", **{"Transmission Weight": 1.0, "Metallic": 1.0}),
    "HalfGlass": principled_with("HalfGlass", **{"Transmission Weight": 1.0, "Metallic": 0.5}),
    "Faded": principled_with("Faded", Alpha=0.2),
    "Veiled": principled_with("Veiled", Alpha=0.7),
    "GlassBSDF": surface("GlassBSDF", "ShaderNodeBsdfGlass"),
    "Refraction": surface("Refraction", "ShaderNodeBsdfRefraction"),
    "Transparent": surface("Transparent", "ShaderNodeBsdfTransparent"),
    "Translucent": surface("Translucent", "ShaderNodeBsdfTranslucent"),
    "Holdout": surface("Holdout", "ShaderNodeHoldout"),
    "MixFade": mixed("MixFade", 0.8),
    "MixFadeFlipped": mixed("MixFadeFlipped", 0.8, clear_first=True),
    "ShadowTrick": mixed("ShadowTrick", 0.0, light_path="Is Shadow Ray"),
    "CameraTrick": mixed("CameraTrick", 1.0, light_path="Is Camera Ray"),
    "CutOut": mixed("CutOut", 0.0, image=img),
}
frame = principled("Frame", base=(0.5, 0.5, 0.5))
for i, (name, mat) in enumerate(cases.items()):
    ob = cube(name, location=(3.0 * i, 0.0, 0.0))
    ob.data.materials.append(frame)
    ob.data.materials.append(mat)
    ob.data.polygons.foreach_set("material_index", np.array([0, 0, 0, 0, 1, 1], np.int32))
    ob.data.update()
pane = cube("Pane", location=(0.0, 5.0, 0.0))           # all glass: nothing left to draw
pane.data.materials.append(cases["Glass"])
objects, warnings = extract()
emit(objects={n: [len(o.triangles), len(o.vertices), int(o.triangles.max()),
                  len(o.normals), len(o.material_ids), sorted(set(o.material_ids.tolist())),
                  [round(m.opacity, 6) for m in o.materials],
                  list(o.materials[1].base_color), bool(o.materials[1].holdout)]
                 for n, o in objects.items()},
     warnings=warnings)
"""


def test_see_through_materials_leave_their_faces_out(blender):
    """Glass (Transmission Weight, a Glass or Refraction BSDF), Alpha and Transparent BSDF mixes
    are see-through, as Cycles lets light through them: their faces leave the mesh (a cube's two
    faces of such a material: 12 -> 8 triangles), the frame's faces stay, an all-glass object
    leaves the scene without an error, and what the preview cannot follow (a cut-out) stays
    opaque with a warning naming it."""
    res = blender("from pathlib import Path\n" + EXTRACT + SEE_THROUGH_CASES)
    r = res.result
    objects = r["objects"]
    print(objects)
    print(r["warnings"])
    opacity = {"Opaque": 1.0, "Glass": 0.0, "MetalGlass": 1.0, "HalfGlass": 0.5, "Faded": 0.2,
               "Veiled": 0.7, "GlassBSDF": 0.0, "Refraction": 0.0, "Transparent": 0.0,
               "Translucent": 1.0, "Holdout": 1.0, "MixFade": 0.2, "MixFadeFlipped": 0.8,
               "ShadowTrick": 0.0, "CameraTrick": 1.0, "CutOut": 1.0}
    assert "Pane" not in objects
    for name, want in opacity.items():
        tris, verts, top, normals, ids, used, opacities, base, held = objects[name]
        assert held == (name == "Holdout"), name
        assert abs(opacities[1] - want) < 1e-6, (name, opacities)
        clear = want <= 0.5
        assert tris == (8 if clear else 12), name
        assert normals == ids == tris and top == verts - 1, name   # every vertex kept is used
        assert verts == 8 and used == ([0] if clear else [0, 1]), name
        if name in ("MixFade", "MixFadeFlipped", "CameraTrick", "Glass", "Faded"):
            assert np.allclose(base, (0.2, 0.4, 0.6)), (name, base)  # the Principled side's
    messages = {who: m for who, m in r["warnings"]}
    assert "cut-outs are read only from the Alpha" in messages["CutOut"], messages
    assert "Translucent" in messages and "rendered by Cycles" in messages["Translucent"]
    # a Holdout shader is not see-through (Cycles' alpha 0 there is no window): a holdout
    # (rgba 0 for the camera, tests/gpu/test_ray_visibility.py) that absorbs light (black)
    assert "Holdout" not in messages
    assert np.allclose(objects["Holdout"][7], 0.0)
    assert not any(n in messages for n in ("Glass", "GlassBSDF", "ShadowTrick", "MixFade", "Pane"))


SHADER_MIXES = """
from lumen_gi.operators.material_nodes import material_emits
empty_scene()
img, px = checker_png(Path("checker.png").resolve())

def tree(name):
    m = principled(name)
    nodes = m.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    return m, nodes, m.node_tree.links

def out(m, node):
    m.node_tree.links.new(node.outputs[0], m.node_tree.nodes["Material Output"].inputs["Surface"])

def diffuse(nodes, rgb):
    d = nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*rgb, 1.0)
    return d

def emission(nodes, rgb, strength):
    e = nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*rgb, 1.0)
    e.inputs["Strength"].default_value = strength
    return e

def combine(m, kind, a, b, fac=None):
    nodes, links = m.node_tree.nodes, m.node_tree.links
    node = nodes.new(kind)
    first = 1 if fac is not None else 0
    links.new(a.outputs[0], node.inputs[first])
    links.new(b.outputs[0], node.inputs[first + 1])
    if fac is not None:
        node.inputs[0].default_value = fac
    return node

mats = {}
m, nodes, links = tree("Diffuse"); out(m, diffuse(nodes, (0.1, 0.5, 0.9))); mats["Diffuse"] = m
m, nodes, links = tree("DiffuseTex")
d = diffuse(nodes, (0.1, 0.5, 0.9))
tex = nodes.new("ShaderNodeTexImage"); tex.image = img
links.new(tex.outputs["Color"], d.inputs["Color"]); out(m, d); mats["DiffuseTex"] = m
m, nodes, links = tree("Lamp"); out(m, emission(nodes, (1.0, 0.5, 0.25), 5.0)); mats["Lamp"] = m
m, nodes, links = tree("LampTex")
e = emission(nodes, (1.0, 1.0, 1.0), 2.0)
tex = nodes.new("ShaderNodeTexImage"); tex.image = img
links.new(tex.outputs["Color"], e.inputs["Color"]); out(m, e); mats["LampTex"] = m
m, nodes, links = tree("Half")
out(m, combine(m, "ShaderNodeMixShader", diffuse(nodes, (0.8, 0.0, 0.0)),
               diffuse(nodes, (0.0, 0.0, 0.8)), fac=0.25)); mats["Half"] = m
m, nodes, links = tree("GlowingWall")
out(m, combine(m, "ShaderNodeAddShader", diffuse(nodes, (0.6, 0.6, 0.6)),
               emission(nodes, (0.0, 1.0, 0.0), 3.0))); mats["GlowingWall"] = m
m, nodes, links = tree("DimLamp")
out(m, combine(m, "ShaderNodeMixShader", diffuse(nodes, (0.5, 0.5, 0.5)),
               emission(nodes, (1.0, 1.0, 1.0), 4.0), fac=0.5)); mats["DimLamp"] = m
m, nodes, links = tree("Toon"); out(m, nodes.new("ShaderNodeBsdfToon")); mats["Toon"] = m
m, nodes, links = tree("TexMix")                # a texture mixed with a plain colour
d = diffuse(nodes, (0.1, 0.5, 0.9))
tex = nodes.new("ShaderNodeTexImage"); tex.image = img
links.new(tex.outputs["Color"], d.inputs["Color"])
out(m, combine(m, "ShaderNodeMixShader", d, diffuse(nodes, (0.8, 0.0, 0.0)), fac=0.5))
mats["TexMix"] = m
equivalent = principled("PrincipledLamp", base=(0.0, 0.0, 0.0), emission=(1.0, 0.5, 0.25),
                        strength=5.0)
mats["PrincipledLamp"] = equivalent
objects, warnings = extract_cubes(mats)
def fields(o):
    m = o.materials[0]
    return [list(m.base_color), m.base_color_texture is not None, list(m.emission_color),
            m.emission_strength, m.emission_texture is not None, m.opacity, o.uvs is not None]
emit(mats={n: fields(objects[n]) for n in mats}, warnings=warnings,
     emits={n: material_emits(m) for n, m in mats.items()})
"""


def test_diffuse_emission_mix_and_add_shaders_are_read(blender):
    """A Diffuse BSDF's Color, an Emission shader's Color and Strength (values or an Image
    Texture), and Mix and Add Shaders of them, as Cycles weighs them: a lamp made with an
    Emission shader is the same material as a black Principled BSDF emitting the same light
    (before, such a lamp fell back to its grey display colour and lit nothing)."""
    res = blender("from pathlib import Path\n" + EXTRACT + SHADER_MIXES)
    r = res.result
    m, emits = r["mats"], r["emits"]
    print(m)
    print(r["warnings"])

    def close(a, b):
        return np.allclose(a, b, atol=1e-6)

    assert close(m["Diffuse"][0], (0.1, 0.5, 0.9)) and m["Diffuse"][3] == 0.0
    assert m["DiffuseTex"][1] and m["DiffuseTex"][6]               # the texture, and UVs for it
    assert m["Lamp"] == m["PrincipledLamp"]                        # the same material
    assert close(m["Lamp"][0], 0.0) and close(m["Lamp"][2], (1.0, 0.5, 0.25))
    assert m["Lamp"][3] == 5.0 and m["Lamp"][5] == 1.0
    assert m["LampTex"][4] and m["LampTex"][3] == 2.0 and m["LampTex"][6]
    assert close(m["Half"][0], (0.6, 0.0, 0.2))                    # 0.75 red + 0.25 blue
    assert close(m["GlowingWall"][0], 0.6) and close(m["GlowingWall"][2], (0.0, 1.0, 0.0))
    assert m["GlowingWall"][3] == 3.0
    # half a diffuse grey, half an emitter: half the albedo and half the light
    assert close(m["DimLamp"][0], 0.25) and close(m["DimLamp"][2], 1.0)
    assert m["DimLamp"][3] == 2.0
    assert emits == {"Diffuse": False, "DiffuseTex": False, "Lamp": True, "LampTex": True,
                     "Half": False, "GlowingWall": True, "DimLamp": True, "Toon": False,
                     "TexMix": False, "PrincipledLamp": True}
    assert m["TexMix"][1]                                          # the texture is kept
    messages = {who: what for who, what in r["warnings"]}
    assert sorted(messages) == ["TexMix", "Toon"], messages
    assert "blends a texture" in messages["TexMix"]
    assert "Toon BSDF" in messages["Toon"] and "rendered by Cycles" in messages["Toon"]


GROUPED = """
from lumen_gi.operators import material_capture as mc
empty_scene()
calls = []
real_capture = mc.capture
def counted(materials):
    calls.append(sorted(m.name for m in materials))
    return real_capture(materials)
mc.capture = counted

def grouped(name, **inputs):
    mat = principled(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    tree = bpy.data.node_groups.new(name + " Group", "ShaderNodeTree")
    tree.interface.new_socket("Shader", in_out='OUTPUT', socket_type='NodeSocketShader')
    out = tree.nodes.new("NodeGroupOutput")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    for k, v in inputs.items():
        bsdf.inputs[k].default_value = v
    tree.links.new(bsdf.outputs[0], out.inputs[0])
    node = nodes.new("ShaderNodeGroup")
    node.node_tree = tree
    links.new(node.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat, bsdf

lamp, lamp_bsdf = grouped("Lamp", **{"Base Color": (0.2, 0.5, 0.1, 1.0),
                                     "Emission Color": (1.0, 0.5, 0.25, 1.0),
                                     "Emission Strength": 4.0})
glass, _ = grouped("GroupGlass", **{"Transmission Weight": 1.0})
plain = principled("Plain", base=(0.2, 0.5, 0.1))
attr = principled("Attr")                   # vertex colours through a Mix: captured
mix = attr.node_tree.nodes.new("ShaderNodeMix")
mix.data_type = 'RGBA'
mix.blend_type = 'MULTIPLY'
mix.inputs["Factor"].default_value = 1.0
mix.inputs[7].default_value = (1.0, 1.0, 1.0, 1.0)           # B: white
attr.node_tree.links.new(attr.node_tree.nodes.new("ShaderNodeVertexColor").outputs["Color"],
                         mix.inputs[6])                        # A: the colour attribute
attr.node_tree.links.new(mix.outputs[2], attr.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
for i, mat in enumerate((lamp, glass, plain, attr)):
    cube(mat.name, location=(3.0 * i, 0.0, 0.0)).data.materials.append(mat)
objects, warnings = extract()
def read(name):
    m = objects[name].materials[0]
    emitted = (np.asarray(m.emission_texture).reshape(-1, 3).mean(0) * m.emission_strength
               if m.emission_texture is not None
               else np.asarray(m.emission_color) * m.emission_strength)
    tex = (np.asarray(m.base_color_texture).reshape(-1, 3).mean(0).tolist()
           if m.base_color_texture is not None else None)
    return [list(m.base_color), emitted.tolist(), 1.0, m.opacity, tex,
            (np.asarray(m.emission_color) * m.emission_strength).tolist()]
first = {"Lamp": read("Lamp"), "Plain": read("Plain"), "Attr": read("Attr")}
first_calls = list(calls)
objects, _ = extract()                        # remembered: no new capture
again_calls = list(calls)
lamp_bsdf.inputs["Base Color"].default_value = (0.9, 0.1, 0.1, 1.0)     # an edit in the group
objects, _ = extract()
emit(first=first, glass="GroupGlass" in objects, first_calls=first_calls, again_calls=again_calls,
     edited=read("Lamp"), calls=calls, warnings=warnings)
"""


def test_a_material_the_extraction_cannot_read_is_rendered_by_cycles(blender):
    """A Principled BSDF inside a node group (as asset libraries ship them): its colours are
    rendered by Cycles once (material_capture), every such material in one image, remembered
    until the material is edited (a colour attribute reads 0.8 grey). The emission is the Principled's own to 1e-3; the albedo is
    the Diffuse + Glossy Color passes (within 0.04 of the Base Color: the dielectric's white
    specular); glass in a group is see-through (its faces are left out)."""
    res = blender(EXTRACT + GROUPED)
    r = res.result
    print(r)
    lamp = r["first"]["Lamp"]
    assert np.allclose(np.array(lamp[1]) * lamp[2], (4.0, 2.0, 1.0), rtol=1e-3)
    assert np.allclose(lamp[0], (0.2, 0.5, 0.1), atol=0.04), lamp[0]
    assert np.allclose(lamp[4], lamp[0], atol=1e-5)     # its swatch texture's mean is the mean
    # a mesh without UVs reads the mean emission (colour x strength), not the texture's scale
    assert np.allclose(lamp[5], (4.0, 2.0, 1.0), rtol=1e-3), lamp[5]
    assert lamp[3] == 1.0
    assert r["first"]["Plain"][0] == [0.2, 0.5, 0.1] or np.allclose(r["first"]["Plain"][0],
                                                                    (0.2, 0.5, 0.1))
    assert not r["glass"]                          # all glass: left out
    # one capture for both grouped materials; none when nothing changed; one after the edit
    assert r["first_calls"] == [["Attr", "GroupGlass", "Lamp"]], r["first_calls"]
    # a Color Attribute into Base Color reads grey 0.8 on the swatch (not black)
    assert np.allclose(r["first"]["Attr"][0], 0.8, atol=0.04), r["first"]["Attr"]
    assert r["again_calls"] == r["first_calls"]
    assert r["calls"][1:] == [["Lamp"]] and np.allclose(r["edited"][0], (0.9, 0.1, 0.1),
                                                        atol=0.04)
    messages = [what for who, what in r["warnings"] if who == "Lamp"]
    assert messages and "node group 'Lamp Group'" in messages[0], r["warnings"]
    assert "rendered by Cycles" in messages[0]


COLOUR_ATTRIBUTES = """
empty_scene()
box = cube("Box")
mesh = box.data
rng = np.random.default_rng(3)
corner = mesh.color_attributes.new("Paint", 'BYTE_COLOR', 'CORNER')
corner_px = rng.random((len(mesh.loops), 4)).astype(np.float32)
corner.data.foreach_set("color", corner_px.ravel())
point = mesh.attributes.new("Tint", 'FLOAT_COLOR', 'POINT')
point_px = rng.random((len(mesh.vertices), 4)).astype(np.float32)
point.data.foreach_set("color", point_px.ravel())
face = mesh.attributes.new("Grade", 'FLOAT', 'FACE')
face_px = rng.random(len(mesh.polygons)).astype(np.float32)
face.data.foreach_set("value", face_px)
mesh.color_attributes.default_color_name = "Paint"     # the render colour attribute

def reading(name, node="ShaderNodeVertexColor", shader=None):
    m = principled(name)
    nodes, links = m.node_tree.nodes, m.node_tree.links
    n = nodes.new(node)
    if node == "ShaderNodeVertexColor":
        n.layer_name = name if name != "Default" else ""
    else:
        n.attribute_name = name
    target = nodes["Principled BSDF"]
    if shader is not None:
        target = nodes.new(shader)
        links.new(target.outputs[0], nodes["Material Output"].inputs["Surface"])
    links.new(n.outputs["Color"], target.inputs["Base Color" if shader is None else "Color"])
    return m

mats = [reading("Paint"), reading("Tint", "ShaderNodeAttribute", "ShaderNodeBsdfDiffuse"),
        reading("Grade", "ShaderNodeAttribute"), reading("Default"), reading("Missing"),
        principled("Plain", base=(0.1, 0.2, 0.3))]
for m in mats:
    mesh.materials.append(m)
mesh.polygons.foreach_set("material_index", np.array([0, 1, 2, 3, 4, 5], np.int32))
mesh.update()
objects, warnings = extract()
o = objects["Box"]
m = box.data
emit(colors=o.colors.tolist(), ids=o.material_ids.tolist(),
     flags=[x.vertex_colors for x in o.materials],
     corner=corner_values(m, lambda li: list(m.color_attributes["Paint"].data[li].color[:3])).tolist(),
     point=corner_values(m, lambda li: list(m.attributes["Tint"].data[m.loops[li].vertex_index].color[:3])).tolist(),
     face=[m.attributes["Grade"].data[t.polygon_index].value for t in m.loop_triangles],
     warnings=warnings)
"""


def test_colour_attributes_into_base_color_are_read_per_corner(blender):
    """A Color Attribute node (or an Attribute node's Color) straight into Base Color or a
    Diffuse BSDF's Color: the mesh's colours per triangle corner, from the corner, point or
    face domain, byte colours linearised as Blender reads them (the reference: a Python loop
    over the loops); a missing attribute is black, as in Cycles, with a warning."""
    res = blender(EXTRACT + COLOUR_ATTRIBUTES)
    r = res.result
    colors, ids = np.array(r["colors"]), np.array(r["ids"])
    assert r["flags"] == [True, True, True, True, True, False]
    corner, point, face = np.array(r["corner"]), np.array(r["point"]), np.array(r["face"])
    for slot, want in ((0, corner), (1, point), (3, corner)):    # 3: the render attribute
        sel = ids == slot
        assert sel.sum() == 2
        np.testing.assert_allclose(colors[sel], want[sel], atol=1e-6)
    sel = ids == 2
    np.testing.assert_allclose(colors[sel], np.repeat(face[sel][:, None, None], 3, 1) *
                               np.ones((1, 3, 3)), atol=1e-6)
    assert np.all(colors[ids == 4] == 0.0)
    messages = [what for who, what in r["warnings"]]
    assert any("'Missing'" in w and "black" in w for w in messages), messages
    assert len(messages) == 1, messages


BUMPS = """
empty_scene()
img, px = checker_png(Path("checker.png").resolve())

def bumped(name, output="Color", invert=False, distance=0.5, source=None, chained=False):
    m = principled(name)
    nodes, links = m.node_tree.nodes, m.node_tree.links
    bsdf = nodes["Principled BSDF"]
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = distance
    bump.inputs["Strength"].default_value = 0.75
    bump.invert = invert
    height = nodes.new(source).outputs[0] if source else tex.outputs[output]
    links.new(height, bump.inputs["Height"])
    if chained:
        nmap = nodes.new("ShaderNodeNormalMap")
        links.new(nmap.outputs["Normal"], bump.inputs["Normal"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return m

mats = {"Bump": bumped("Bump"), "Inverted": bumped("Inverted", invert=True, distance=2.0),
        "AlphaBump": bumped("AlphaBump", output="Alpha"),
        "NoiseBump": bumped("NoiseBump", source="ShaderNodeTexNoise"),
        "Chained": bumped("Chained", chained=True)}
objects, warnings = extract_cubes(mats)
def fields(o):
    m = o.materials[0]
    h = m.normal_texture
    return dict(bump=m.bump, strength=m.normal_strength,
                height=None if h is None else np.asarray(h).tolist(),
                base=np.asarray(m.base_color_texture).tolist(),
                tangents=o.tangents is not None)
emit(mats={n: fields(objects[n]) for n in mats}, warnings=warnings)
"""


def test_bump_node_heights_are_read_scaled_by_distance(blender):
    """A Bump node's Height from an Image Texture: its Color's luminance (or its Alpha) times
    Distance, negated by Invert, with the Strength (gbuffer.glsl bumped); a Bump whose Height
    is anything else is left out with a warning; no tangents are computed for a bump."""
    res = blender("from pathlib import Path\n" + EXTRACT + BUMPS)
    m, warnings = res.result["mats"], res.result["warnings"]
    base = np.asarray(m["Bump"]["base"], np.float64)
    lum = base[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    assert m["Bump"]["bump"] and m["Bump"]["strength"] == 0.75 and not m["Bump"]["tangents"]
    np.testing.assert_allclose(m["Bump"]["height"], 0.5 * lum, atol=1e-6)
    np.testing.assert_allclose(m["Inverted"]["height"], -2.0 * lum, atol=1e-6)
    assert m["AlphaBump"]["bump"]
    np.testing.assert_allclose(m["AlphaBump"]["height"], 0.5 * base[..., 3], atol=1e-6)
    assert not m["NoiseBump"]["bump"] and m["NoiseBump"]["height"] is None
    assert m["Chained"]["bump"]
    messages = {}
    for who, what in warnings:
        messages.setdefault(who, []).append(what)
    assert any("Bump Height is driven by a Noise Texture" in w for w in messages["NoiseBump"])
    assert any("normal into the Bump node" in w for w in messages["Chained"])
    assert "Bump" not in messages and "Inverted" not in messages
