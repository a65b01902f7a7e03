"""Benchmark: frame time against object count (issue 10: 1,000 objects at most twice 10).

Scene per N: a 20 x 20 m floor and N small icospheres (80 triangles) on a grid over it, half of
them unique meshes (each its own Mesh datablock, scaled differently so each bakes its own SDF),
half linked duplicates of those (obj.copy(): the same Mesh); five shared materials; a sun; a
camera above one side of the floor that sees most of them. Baked at `--density` voxels/m.
For N = 10, 100, 1000 (`--counts`) in one process, same resolution:
  viewport   the engine's own view_draw through tools/viewport_harness.py at `--size`^2, Pixel
             Size 1, viewport quality `--quality`: one warm-up redraw (first frame: everything
             extracted and uploaded) then `--repeat` still redraws, median, and the split of the
             last still frame from LAST_RENDER (extract, sync, G-buffer, direct, GI)
  F12        bpy.ops.render.render at `--size`^2, render_frames = bounces = 1 (one GI iteration),
             one warm-up then `--repeat` timed, median and split
and the ratios N=max / N=min. Shader compilation happens in the first N's warm-ups.

    .venv/bin/python bench/object_scaling.py [--counts 10 100 1000] [--size 128] [--repeat 3]
                                             [--quality MEDIUM] [--f12-max N]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

SPLIT = ("frame_seconds", "extract_seconds", "sync_seconds", "gbuffer_seconds", "direct_seconds",
         "gi_seconds")


def build_scene(n: int, size: int):
    import bmesh
    import bpy
    import mathutils
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mats = []
    for i, c in enumerate(((0.8, 0.8, 0.8), (0.8, 0.2, 0.2), (0.2, 0.7, 0.3), (0.2, 0.3, 0.8),
                           (0.8, 0.7, 0.2))):
        mat = bpy.data.materials.new(f"Mat{i}")
        mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*c, 1.0)
        mats.append(mat)
    floor_mesh = bpy.data.meshes.new("Floor")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=10.0)
    bm.to_mesh(floor_mesh)
    bm.free()
    floor_mesh.materials.append(mats[0])
    scene.collection.objects.link(bpy.data.objects.new("Floor", floor_mesh))
    base = bpy.data.meshes.new("Ico")
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=1, radius=0.25)
    bm.to_mesh(base)
    bm.free()
    unique = max(n // 2, 1)
    side = int(np.ceil(np.sqrt(n)))
    meshes = []
    for i in range(n):
        x = ((i % side) + 0.5) / side * 18.0 - 9.0
        y = ((i // side) + 0.5) / side * 18.0 - 9.0
        if i < unique:
            mesh = base.copy()
            mesh.name = f"Ico{i}"
            mesh.transform(mathutils.Matrix.Diagonal((1.0, 1.0, 1.0 + 0.5 * i / unique, 1.0)))
            mesh.materials.append(mats[1 + i % 4])
            meshes.append(mesh)
        else:
            mesh = meshes[i % unique]          # a linked duplicate
        obj = bpy.data.objects.new(f"Obj{i}", mesh)
        obj.location = (x, y, 0.3)
        scene.collection.objects.link(obj)
    bpy.data.meshes.remove(base)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.8)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    for obj in (sun, cam):
        scene.collection.objects.link(obj)
    cam.location = (0.0, -13.0, 9.0)
    cam.rotation_euler = (mathutils.Vector((0, -1.0, 0)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    scene.camera = cam
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.05, 0.05, 0.06)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def split(R) -> dict:
    return {k.replace("_seconds", ""): R.get(k, 0.0) * 1000 for k in SPLIT}


def measure(n: int, args, tmp: Path) -> dict:
    import bpy

    import viewport_harness
    from lumen_gi.gpu_shaders import engine

    scene = build_scene(n, args.size)
    scene.lumen.cache_dir = str(tmp / f"cache{n}")
    scene.lumen.voxel_density = args.density
    t = time.perf_counter()
    bpy.ops.lumen.bake()
    bake_seconds = time.perf_counter() - t
    scene.render.engine = "LUMEN_GI"
    scene.render.preview_pixel_size = "1"
    scene.lumen.gi_quality = scene.lumen.viewport_gi_quality = args.quality
    scene.lumen.render_frames = 1
    scene.lumen.bounces = 1
    rows = []

    def record(i):
        R = engine.LAST_RENDER
        if "error" in R:
            raise RuntimeError(R.get("traceback", R["error"]))
        rows.append(dict(split(R), meshes_read=R.get("meshes_read", -1),
                         draws=R.get("gbuffer_draws", 0), triangles=R.get("triangles", 0)))

    out = viewport_harness.run(scene, engine.LumenGIRenderEngine, args.size, args.size,
                               redraws=args.repeat + 1, on_redraw=record)
    view = dict(first=out["seconds"][0] * 1000,
                median=statistics.median(out["seconds"][1:]) * 1000, split=rows[-1],
                first_split=rows[0])
    if n > args.f12_max:
        return dict(n=n, bake=bake_seconds, view=view, f12=None, triangles=rows[-1]["triangles"])
    times = []
    for _ in range(args.repeat + 1):
        t = time.perf_counter()
        bpy.ops.render.render()
        times.append(time.perf_counter() - t)
        if "error" in engine.LAST_RENDER:
            raise RuntimeError(engine.LAST_RENDER.get("traceback"))
    R = engine.LAST_RENDER
    f12 = dict(median=statistics.median(times[1:]) * 1000, split=split(R),
               iterations=R.get("gi_iterations", 0), meshes_read=R.get("meshes_read", -1))
    return dict(n=n, bake=bake_seconds, view=view, f12=f12, triangles=R.get("triangles", 0))


def fmt(s: dict) -> str:
    return ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in s.items())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--counts", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quality", default="MEDIUM", choices=("OFF", "LOW", "MEDIUM", "HIGH"))
    ap.add_argument("--density", type=float, default=8.0, help="bake voxels per metre")
    ap.add_argument("--f12-max", type=int, default=1 << 30,
                    help="skip F12 above this many objects (a GI F12 of 1,000 takes hours)")
    args = ap.parse_args()

    import tempfile

    import demo

    results = []
    with tempfile.TemporaryDirectory() as tmp:
        demo.load_addon()
        for n in args.counts:
            r = measure(n, args, Path(tmp))
            results.append(r)
            v, f = r["view"], r["f12"]
            print(f"N={n:5d} ({r['triangles']} triangles, bake {r['bake']:.1f} s)", flush=True)
            print(f"  viewport {args.size}x{args.size}: first {v['first']:.1f} ms, still median "
                  f"{v['median']:.1f} ms; still split ms: {fmt(v['split'])}", flush=True)
            print(f"    first-frame split ms: {fmt(v['first_split'])}", flush=True)
            if f is not None:
                print(f"  F12 (1 GI iteration): median {f['median']:.1f} ms; split ms: "
                      f"{fmt(f['split'])}, meshes read {f['meshes_read']}", flush=True)
    lo, hi = results[0], results[-1]
    f12 = [r for r in results if r["f12"] is not None]
    print(f"ratio N={hi['n']} / N={lo['n']}: viewport still frame "
          f"{hi['view']['median'] / lo['view']['median']:.2f}" + (
              f", F12 N={f12[-1]['n']} / N={lo['n']} "
              f"{f12[-1]['f12']['median'] / lo['f12']['median']:.2f}" if len(f12) > 1 else ""))
    for key in ("extract", "sync", "gbuffer", "direct", "gi"):
        a, b = lo["view"]["split"][key], hi["view"]["split"][key]
        print(f"  viewport still {key:8s} {a:8.1f} -> {b:8.1f} ms")


if __name__ == "__main__":
    main()
