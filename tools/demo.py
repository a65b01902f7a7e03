"""Bake a scene with the Lumen GI add-on, export the cache and render the preview, headlessly.

    .venv/bin/python tools/demo.py [scene.blend] [--out DIR] [--voxel-density N] [--size W H]

Without a .blend it builds a small demo scene in code: a floor with a colour-grid texture, a red
box, a subdivided UV sphere with two linked duplicates (one shared bake), a glowing torus, a thin
two-sided wall and a sun. The
add-on is loaded straight from this repository (as package `lumen_gi`), `lumen.bake` and
`lumen.export_cache` run exactly as from the N-panel, the exported cache is read back and
validated, a table of what was baked is printed, and the scene camera's view is rendered with
the Lumen GI engine (F12's passes) to `<out>/preview.png` (skipped with a note when the scene has
no camera). Exits 1 with the error on failure.
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_addon(name: str = "lumen_gi"):
    """Import the repository root as the add-on package `name` and register it."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(
        name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    module.register()
    return module


def build_demo_scene(*, sphere_segments: int = 16, sphere_rings: int = 8, factory_reset: bool = True):
    """Replace the current file with the demo scene; returns the scene. factory_reset=False
    empties the current scene instead (factory settings would also reset the preferences and
    so disable an installed extension)."""
    import bpy

    if factory_reset:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    else:
        for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.lights, bpy.data.cameras,
                           bpy.data.materials, bpy.data.images):
            for block in list(collection):
                collection.remove(block)
    scene = bpy.context.scene

    def material(name, base=(0.8, 0.8, 0.8), emission=(0.0, 0.0, 0.0), strength=0.0, image=None):
        mat = bpy.data.materials.new(name)
        if mat.node_tree is None:   # Blender 4.2 to 4.5 start without nodes (5.0 on: always)
            mat.use_nodes = True
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = (*base, 1.0)
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
        if image is not None:   # an Image Texture straight into Base Color, default UV map
            tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
            tex.image = image
            mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        return mat

    bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0, 0, 0))
    bpy.context.object.name = "Floor"
    grid = bpy.data.images.new("Floor Grid", 256, 256)
    grid.generated_type = 'COLOR_GRID'
    bpy.context.object.data.materials.append(material("Floor", image=grid))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-1.5, 0.5, 0.5))
    bpy.context.object.name = "Box"
    bpy.context.object.data.materials.append(material("Red", base=(0.8, 0.05, 0.05)))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=sphere_segments, ring_count=sphere_rings,
                                         radius=0.5, location=(0.5, -1.0, 0.5))
    sphere = bpy.context.object
    sphere.name = "Sphere"
    sphere.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    for i in range(2):   # linked duplicates: same mesh data, same modifier -> one bake
        dup = sphere.copy()
        dup.name = f"Sphere.dup{i + 1}"
        dup.location = (1.7 + 1.1 * i, -1.0, 0.5)
        scene.collection.objects.link(dup)
    bpy.ops.mesh.primitive_torus_add(major_radius=0.6, minor_radius=0.2, location=(0.5, 1.2, 0.2))
    bpy.context.object.name = "Torus"
    bpy.context.object.data.materials.append(
        material("Glow", base=(0.9, 0.9, 0.9), emission=(1.0, 0.6, 0.2), strength=5.0))
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-2.5, -1.0, 1.0),
                                     rotation=(0.0, math.pi / 2, 0.0))
    wall = bpy.context.object
    wall.name = "Wall"
    wall.scale = (2.0, 3.0, 1.0)
    wall.lumen.two_sided = True

    light = bpy.data.lights.new("Sun", 'SUN')
    light.energy = 3.0
    sun = bpy.data.objects.new("Sun", light)
    sun.rotation_euler = (0.6, 0.2, 0.8)
    scene.collection.objects.link(sun)

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (7.5, -7.5, 5.0)
    cam.rotation_euler = (math.radians(63), 0.0, math.radians(45))
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def summary(bake) -> str:
    """One row per object: mesh hash, mip-0 resolution, bricks kept/total (all mips), bytes, and
    the mesh cards: how many, their atlas texels and the share of the surface they see."""
    rows = [("object", "mesh", "resolution", "bricks", "bytes", "cards", "texels", "coverage")]
    seen, seen_cards = set(), set()
    cards = getattr(bake, "cards", None) or {}
    for inst in bake.instances:
        stats = bake.meshes[inst.mesh].stats()
        kept = sum(s["bricks_kept"] for s in stats)
        total = sum(s["bricks_total"] for s in stats)
        nbytes = sum(s["bytes"] for s in stats)
        shared = inst.mesh in seen
        seen.add(inst.mesh)
        ckey = getattr(inst, "cards", "")
        mc = cards.get(ckey)
        card_cols = (("-", "-", "-") if mc is None else
                     (str(len(mc.cards)), "(shared)" if ckey in seen_cards else f"{mc.texels:,}",
                      f"{mc.coverage:.1%}"))
        seen_cards.add(ckey)
        rows.append((inst.name, inst.mesh[:12], "x".join(map(str, stats[0]["resolution"])),
                     f"{kept}/{total}", "(shared)" if shared else f"{nbytes:,}") + card_cols)
    t = bake.stats()
    rows.append(("total", f"{t['unique_meshes']} meshes", f"{t['objects']} objects",
                 f"{t['bricks']}", f"{t['bytes']:,}", str(t.get("cards", "-")),
                 f"{t['texels']:,}" if "texels" in t else "-",
                 f"{t['coverage']:.1%} min" if "coverage" in t else "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) if i < 3 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))
             for r in rows]
    lines.insert(1, "-" * len(lines[0]))
    lines.insert(len(lines) - 1, "-" * len(lines[0]))
    lines.append(f"baked in {t['seconds']:.2f} s ({t['reused']} meshes reused)")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("blend", nargs="?", help="a .blend to bake (default: built-in demo scene)")
    parser.add_argument("--out", default="out", help="output folder (default ./out)")
    parser.add_argument("--voxel-density", type=float, help="override the scene's voxel density")
    parser.add_argument("--size", type=int, nargs=2, default=(320, 240), metavar=("W", "H"),
                        help="preview image size (default 320 240)")
    args = parser.parse_args(argv)

    import bpy

    if args.blend:
        path = Path(args.blend).resolve()
        if not path.is_file():
            print(f"error: {path}: no such .blend file", file=sys.stderr)
            return 1
        bpy.ops.wm.open_mainfile(filepath=str(path))
        addon = load_addon()
        scene = bpy.context.scene
    else:
        addon = load_addon()
        scene = build_demo_scene()
    if args.voxel_density:
        scene.lumen.bake.voxel_density = args.voxel_density
    out = Path(args.out).resolve() / "cache"

    from lumen_gi.lumen_addon.cache import CacheError, read_cache   # the package loaded above

    try:
        for op, kwargs in ((bpy.ops.lumen.bake, {}), (bpy.ops.lumen.export_cache, {"filepath": str(out)})):
            result = op(**kwargs)
            if result != {'FINISHED'}:
                raise RuntimeError(f"{op.idname_py()} returned {result}: "
                                   f"{scene.lumen.last_bake.status}")
        read_cache(out)   # what was exported reads back and validates
    except (RuntimeError, CacheError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    bake = addon.operators.bake_op.LAST_BAKES[scene.name]
    print(summary(bake))
    for name, message in bake.warnings:
        print(f"warning: {name}: {message}")
    print(f"cache: {out}")
    return render_preview(addon, scene, out.parent / "preview.png", args.size)


def render_preview(addon, scene, path: Path, size) -> int:
    """F12 with the Lumen GI engine into `path`; 1 if the engine reported an error."""
    import bpy

    if scene.camera is None:
        print("preview: skipped (the scene has no camera)")
        return 0
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(path)
    engine = addon.gpu_shaders.engine
    engine.LAST_RENDER.clear()
    bpy.ops.render.render(write_still=True)
    if engine.LAST_RENDER.get("error"):
        print(f"error: preview render: {engine.LAST_RENDER['error']}", file=sys.stderr)
        return 1
    print(f"preview: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
