"""The settings' groups (scene.lumen.bake / .engine / .last_bake): every default stated once (the
dataclass's), files saved with the old flat layout open with nothing lost, every property has a
tooltip and a line in the README's Scripting section."""
import math
import re
import textwrap

from blender_runner import ROOT, blender  # noqa: F401  (fixture)

DEFAULTS = """
from dataclasses import fields
from lumen_gi.gpu_shaders import gi_methods, gi_settings
from lumen_gi.lumen_addon.bake import BakeSettings, ObjectInput
from lumen_gi.operators import properties
from lumen_gi.operators.bake_op import settings_from

scene = bpy.context.scene
bpy.ops.mesh.primitive_cube_add()
obj = bpy.context.object
GI, METHOD, BAKE = gi_settings.GISettings(), gi_methods.MethodSettings(), BakeSettings()
# property -> (where its default is stated, that default); the rest are same-named fields
ALIASES = {"viewport_quality": ("GISettings.quality", GI.quality),
           "render_quality": ("GISettings.quality", GI.quality),
           "gi_gather": ("GISettings.gather", GI.gather),
           "gi_method": ("MethodSettings.method", METHOD.method),
           "cache_texels_per_frame": ("gi_settings.CACHE_TEXELS_PER_FRAME",
                                      gi_settings.CACHE_TEXELS_PER_FRAME),
           "viewport_split": ("gi_settings.VIEWPORT_SPLIT", str(gi_settings.VIEWPORT_SPLIT)),
           "cache_dir": ("properties.DEFAULT_CACHE_DIR", properties.DEFAULT_CACHE_DIR)}
NO_DATACLASS = {"debug_view"}           # only the UI has it; the engine's fallback is COMBINED
OBJECT = {f.name: f.default for f in fields(ObjectInput)}

def rna_default(group, name):
    p = group.bl_rna.properties[name]
    return p.default if p.type != 'FLOAT' or p.array_length == 0 else tuple(p.default_array)

rows, unmapped = [], []
for gname, group, sources in (("bake", scene.lumen.bake, (("BakeSettings", BAKE),)),
                              ("engine", scene.lumen.engine,
                               (("GISettings", GI), ("MethodSettings", METHOD))),
                              ("object", obj.lumen, (("ObjectInput", None),))):
    for p in group.bl_rna.properties:
        name = p.identifier
        if name in ("rna_type", "name") or name in NO_DATACLASS:
            continue
        if name in ALIASES:
            where, value = ALIASES[name]
        elif gname == "object" and name in OBJECT:
            where, value = "ObjectInput." + name, OBJECT[name]
        else:
            hit = [(f"{label}.{name}", getattr(dc, name)) for label, dc in sources
                   if dc is not None and hasattr(dc, name)]
            if not hit:
                unmapped.append(f"{gname}.{name}")
                continue
            where, value = hit[0]
        rows.append((f"{gname}.{name}", where, rna_default(group, name), value,
                     getattr(group, name)))

from dataclasses import asdict
method, notes = gi_methods.from_scene(scene.lumen.engine)
# what the engine and the bake get from a new scene, beside the dataclasses' defaults
emit(rows=rows, unmapped=unmapped, notes=notes,
     gi=[asdict(gi_settings.from_scene(scene.lumen.engine)), asdict(gi_settings.settings())],
     gi_viewport=[asdict(gi_settings.from_scene(scene.lumen.engine, viewport=True)),
                  asdict(gi_settings.settings(split=gi_settings.VIEWPORT_SPLIT,
                                              sc_tiles=GI.sc_tiles // gi_settings.VIEWPORT_SPLIT))],
     method=[asdict(method), asdict(METHOD)], bake=[asdict(settings_from(scene)), asdict(BAKE)],
     groups=sorted(p.identifier for p in scene.lumen.bl_rna.properties
                   if p.identifier not in ("rna_type", "name")))
"""


def test_every_property_default_is_its_dataclass_default(blender):
    r = blender(DEFAULTS).result
    assert r["unmapped"] == [], f"properties with no dataclass default: {r['unmapped']}"
    same = lambda a, b: (math.isclose(a, b, rel_tol=1e-6) if isinstance(a, float) else a == b)
    wrong = [(name, where, prop, dc) for name, where, prop, dc, _ in r["rows"]
             if not same(prop, dc)]
    assert not wrong, f"property default != dataclass default: {wrong}"
    assert not [row for row in r["rows"] if not same(row[4], row[3])]   # a new scene reads them
    assert len(r["rows"]) >= 5 + 13 + 2                              # bake, engine, object
    for what in ("gi", "gi_viewport", "method", "bake"):
        got, want = r[what]
        assert got.keys() == want.keys() and all(same(want[k], got[k]) for k in want), (what, got)
    assert r["notes"] == []
    assert r["groups"] == ["bake", "engine", "last_bake"]           # nothing left flat


# The flat layout of `scene.lumen` before the groups (operators/properties.py at 6b9083b), as
# its .blend files store it: its own PropertyGroup, no add-on loaded. Enum items in their order
# then (stored as the item's index).
OLD_LAYOUT = """
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty
Q = [(k, k, "") for k in ("OFF", "LOW", "MEDIUM", "HIGH")]
VIEWS = [(k, k, "") for k in ("COMBINED", "DEPTH", "STEPS", "NORMAL", "ALBEDO", "DIRECT",
         "INDIRECT", "SSGI_HITS", "RSM_FLUX", "HYBRID", "SC_FINAL", "SC_ALBEDO", "SC_NORMAL",
         "SC_DIRECT", "SC_INDIRECT", "CARDS", "SC_UPDATES", "PROBES", "PROBE_FALLBACK",
         "VOXEL_LIGHTING")]

class LumenSceneSettings(bpy.types.PropertyGroup):
    voxel_density: FloatProperty(default=20.0)
    max_resolution: IntProperty(default=126)
    texel_density: FloatProperty(default=20.0)
    texel_budget: IntProperty(default=2048 * 2048)
    cache_dir: StringProperty(default="//lumen_cache/{{scene}}", subtype='DIR_PATH')
    last_objects: IntProperty()
    last_unique_meshes: IntProperty()
    last_bricks: IntProperty()
    last_bytes: IntProperty()
    last_reused: IntProperty()
    last_cards: IntProperty()
    last_texels: IntProperty()
    last_coverage: FloatProperty(subtype='FACTOR')
    last_seconds: FloatProperty()
    last_status: StringProperty()
    debug_view: EnumProperty(items=VIEWS, default='COMBINED')
    gi_quality: EnumProperty(items=Q, default='MEDIUM')
    viewport_gi_quality: EnumProperty(items=Q, default='MEDIUM')
    gi_gather: EnumProperty(items=[(k, k, "") for k in ("PROBES", "PIXEL")], default='PROBES')
    gi_method: EnumProperty(items=[(k, k, "") for k in ("LUMEN", "SSGI", "RSM", "LPV", "VXGI")],
                            default='LUMEN')
    ssgi_rays: IntProperty(default=4)
    ssgi_steps: IntProperty(default=50)
    ssgi_thickness: FloatProperty(default=0.1, subtype='DISTANCE', unit='LENGTH')
    ssgi_reuse: IntProperty(default=1)
    rsm_resolution: IntProperty(default=256)
    rsm_samples: IntProperty(default=64)
    bounces: IntProperty(default=3)
    cache_texels_per_frame: IntProperty(default=0)
    render_frames: IntProperty(default=8)

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.utils.register_class(LumenSceneSettings)
bpy.types.Scene.lumen = PointerProperty(type=LumenSceneSettings)
a = bpy.context.scene
a.name = "A"
b = bpy.data.scenes.new("B")
for scene, values in ((a, {OLD_A}), (b, {OLD_B})):
    for k, v in values.items():
        setattr(scene.lumen, k, v)
stored = {{k: type(a.lumen[k]).__name__ for k in a.lumen.keys()}}
bpy.ops.wm.save_as_mainfile(filepath={path!r})
emit(stored=stored)
"""

# Every old setting away from its default, two scenes apart.
OLD_A = dict(voxel_density=7.5, max_resolution=64, texel_density=33.0, texel_budget=65536,
             cache_dir="//caches/a", last_objects=11, last_unique_meshes=7, last_bricks=1234,
             last_bytes=987654, last_reused=3, last_cards=42, last_texels=55555,
             last_coverage=0.75, last_seconds=12.5, last_status="Baked 11 objects",
             debug_view="VOXEL_LIGHTING", gi_quality="HIGH", viewport_gi_quality="LOW",
             gi_gather="PIXEL", gi_method="RSM", ssgi_rays=9, ssgi_steps=77, ssgi_thickness=0.25,
             ssgi_reuse=2, rsm_resolution=512, rsm_samples=99, bounces=5,
             cache_texels_per_frame=8192, render_frames=21)
OLD_B = dict(gi_quality="OFF", viewport_gi_quality="HIGH", gi_method="VXGI", debug_view="SC_UPDATES",
             voxel_density=3.0)
NEW_NAMES = {"viewport_gi_quality": "engine.viewport_quality", "gi_quality": "engine.render_quality"}


def new_name(old: str) -> str:
    if old in NEW_NAMES:
        return NEW_NAMES[old]
    if old.startswith("last_"):
        return "last_bake." + old[len("last_"):]
    bake = ("voxel_density", "max_resolution", "texel_density", "texel_budget", "cache_dir")
    return ("bake." if old in bake else "engine.") + old


READ_NEW = """
def snapshot():
    out = {}
    for scene in bpy.data.scenes:
        vals = {}
        for g in ("bake", "engine", "last_bake"):
            group = getattr(scene.lumen, g)
            for p in group.bl_rna.properties:
                if p.identifier not in ("rna_type", "name"):
                    v = getattr(group, p.identifier)
                    vals[g + "." + p.identifier] = round(v, 6) if isinstance(v, float) else v
        out[scene.name] = dict(values=vals, keys=sorted(scene.lumen.keys()))
    return out
"""


def expected(old: dict) -> dict:
    return {new_name(k): round(v, 6) if isinstance(v, float) else v for k, v in old.items()}


def test_a_file_saved_with_the_flat_layout_opens_with_every_setting_in_its_group(blender,
                                                                                  tmp_path):
    path = tmp_path / "old_layout.blend"
    old = blender(OLD_LAYOUT.format(OLD_A=OLD_A, OLD_B=OLD_B, path=str(path)),
                  load_addon=False).result
    # the old storage: enums as ints, floats, ints, strings (what the migration must read)
    assert old["stored"]["gi_quality"] == "int" and old["stored"]["debug_view"] == "int"
    assert old["stored"]["voxel_density"] == "float" and old["stored"]["cache_dir"] == "str"
    assert len(old["stored"]) == len(OLD_A) == 29

    saved = tmp_path / "migrated.blend"
    r = blender(READ_NEW + textwrap.dedent(f"""
        bpy.ops.wm.open_mainfile(filepath={str(path)!r})          # load_post moves them
        first = snapshot()
        bpy.ops.wm.save_as_mainfile(filepath={str(saved)!r})
        bpy.ops.wm.open_mainfile(filepath={str(saved)!r})         # nothing left to move
        emit(first=first, again=snapshot())
    """)).result
    for name, old_values in (("A", OLD_A), ("B", OLD_B)):
        got = r["first"][name]
        assert got["keys"] == ["bake", "engine", "last_bake"], got["keys"]   # old keys deleted
        want = expected(old_values)
        wrong = {k: (got["values"][k], v) for k, v in want.items() if got["values"][k] != v}
        assert not wrong, f"scene {name}: (got, saved) {wrong}"
        assert r["again"][name] == got
    # B's untouched settings keep their defaults, A's values did not leak into B
    assert r["first"]["B"]["values"]["engine.render_frames"] == 8
    assert r["first"]["B"]["values"]["bake.cache_dir"] == "//lumen_cache/{scene}"

    # enabled after the file is already open (no load_post): register moves them
    late = blender(READ_NEW + textwrap.dedent(f"""
        bpy.ops.wm.open_mainfile(filepath={str(path)!r})
        import demo
        demo.load_addon()
        emit(now=snapshot())
    """), load_addon=False).result
    assert late["now"]["A"]["values"] == r["first"]["A"]["values"]


def test_every_property_has_a_tooltip_and_a_readme_line(blender):
    """Plain-language tooltips: every property and enum item says something (what it does to
    the image and the time); the README's Scripting section names every property."""
    r = blender("""
        out = {}
        for owner, groups in (("scene.lumen", ("bake", "engine", "last_bake")),
                              ("object.lumen", ("",))):
            base = bpy.context.scene.lumen if owner == "scene.lumen" else None
            for g in groups:
                rna = (getattr(base, g).bl_rna if base is not None else
                       bpy.types.Object.bl_rna.properties["lumen"].fixed_type)
                for p in rna.properties:
                    if p.identifier in ("rna_type", "name"):
                        continue
                    items = ({i.identifier: i.description for i in p.enum_items}
                             if p.type == 'ENUM' else {})
                    out[f"{owner}.{g}.{p.identifier}".replace("..", ".")] = dict(
                        name=p.name, description=p.description, items=items)
        emit(props=out)
    """).result["props"]
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Scripting"):readme.index("\n## ", readme.index("## Scripting") + 5)]
    for full, p in r.items():
        *group, name = full.split(".")
        assert len(p["description"]) >= 20 and len(p["name"]) <= 24, (full, p)
        assert not re.search(r"\^3|mip|clipmap|SH\b", p["description"]), (full, p["description"])
        for item, text in p["items"].items():
            assert len(text) >= 8, (full, item)
        # its group's heading, then the property in a table row or sentence after it
        heading = "\n`" + ".".join(group) + "`"
        assert heading in section, heading
        part = section[section.index(heading) + 1:]
        ends = [part.find(h) for h in ("\n`scene.lumen", "\n`object.lumen", "\nHeadless")]
        part = part[:min(e for e in ends if e > 0)]          # up to the next group's heading
        assert f"`{name}`" in part, f"README Scripting does not document {full}"
