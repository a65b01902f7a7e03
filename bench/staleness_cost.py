"""Benchmark: what the staleness check (lumen_addon/staleness.py) costs a viewport frame.

A scene of --objects unique subdivided spheres (about --triangles in all) is baked at a low voxel
density, then the engine's own view_draw runs headless (tools/viewport_harness.py) for a few
redraws: the first hashes every object, a still redraw hashes none, and a redraw after one
object's mesh was edited hashes that one. Printed per redraw: objects hashed, milliseconds of the
check, milliseconds of the extraction every frame does anyway (extract_scene), and what hashing
every object every frame would cost instead.

    .venv/bin/python bench/staleness_cost.py [--objects 8] [--triangles 1000000]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=8)
    ap.add_argument("--triangles", type=int, default=1_000_000)
    args = ap.parse_args(argv)

    import bpy

    import demo
    import viewport_harness
    demo.load_addon()
    from lumen_gi.gpu_shaders import engine
    from lumen_gi.lumen_addon.staleness import StaleCheck
    from lumen_gi.operators.extract import extract_scene

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.lumen.bake.voxel_density = 4.0
    scene.lumen.bake.cache_dir = str(Path(bpy.app.tempdir) / "staleness_cost")
    # a UV sphere of 32 x 16 has 960 triangles; each subdivision level multiplies by 4
    per = args.triangles / args.objects
    level = max(0, round(math.log(max(per / 960.0, 1.0), 4)))
    objs = []
    for i in range(args.objects):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(1.2 * i, 0.0, 0.5))
        obj = bpy.context.object
        obj.name = f"Sphere{i}"
        obj.scale.z = 1.0 + 0.01 * i          # unique meshes after the modifier is applied
        obj.modifiers.new("Subdivision", 'SUBSURF').levels = level
        obj.modifiers["Subdivision"].render_levels = level
        bpy.ops.object.modifier_apply(modifier="Subdivision")
        objs.append(obj)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.6 * args.objects, -8.0, 4.0)
    cam.rotation_euler = (1.1, 0.0, 0.0)
    scene.camera = cam
    scene.render.engine = "LUMEN_GI"
    scene.lumen.engine.render_quality = scene.lumen.engine.viewport_quality = "OFF"
    t = time.perf_counter()
    bpy.ops.lumen.bake()
    print(f"{args.objects} objects, {sum(len(o.data.loop_triangles) for o in objs):,} triangles, "
          f"baked in {time.perf_counter() - t:.1f} s")

    rows = []

    def step(i):
        R = engine.LAST_RENDER
        rows.append((R["stale_hashed"], R["stale_seconds"], R["extract_seconds"]))
        if i == 1:                             # edit one mesh: the next redraw hashes it alone
            co = np.empty(len(objs[0].data.vertices) * 3, np.float32)
            objs[0].data.vertices.foreach_get("co", co)
            co[2] += 0.01
            objs[0].data.vertices.foreach_set("co", co)
            objs[0].data.update()

    viewport_harness.run(scene, engine.LumenGIRenderEngine, 64, 64, 4, step)
    objects, _ = extract_scene(bpy.context.evaluated_depsgraph_get())
    bake = engine.scene_bake(scene)[0]
    t = time.perf_counter()
    StaleCheck().changed(bake, objects)
    every = time.perf_counter() - t
    print(f"{'redraw':8} {'hashed':>6} {'check ms':>9} {'extract ms':>11}")
    for i, (hashed, check, extract) in enumerate(rows):
        label = ("first", "still", "one edit", "still")[i]
        print(f"{label:8} {hashed:6d} {check * 1e3:9.2f} {extract * 1e3:11.1f}")
    print(f"hashing every object (what a check without memory would cost each frame): "
          f"{every * 1e3:.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
