"""Benchmark: where a viewport frame's time goes, pass by pass, against EEVEE's one-sample frame.

bench/frame_time.py's scene (optionally with --extra-objects), the engine's own view_draw at W x H
(tools/viewport_harness.py: offscreen, duck-typed context, one GI iteration per redraw), and every
compute dispatch timed by shader. Why this works: Mesa llvmpipe runs a compute dispatch on the CPU
before `gpu.compute.dispatch` returns (checked below: the dispatch's time grows with its size),
so the wall time around it is the pass's time; on a real GPU it would only be the submission.
EEVEE renders the same camera at W x H with 1 render sample in the same process.

    .venv/bin/python bench/pass_profile.py [--viewport 640 360] [--redraws 4] [--pixel-size 1]
                                           [--quality MEDIUM] [--extra-objects N]
    .venv/bin/python bench/pass_profile.py --f12 --scene thin [--size 128] [--toggle screen_trace]

With --f12, one F12 render of a bench/quality_scenes scene (or frame_time's) at --size, every
setting at its default, timed the same way (no EEVEE run).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]


def shader_names() -> dict:
    """{id(shader): name} over every module's shader cache (compute.Pass caches by pass name)."""
    import importlib

    base = "lumen_gi.gpu_shaders"          # tools/demo.load_addon's package name
    names = {}
    for mod_name in ("compute", "global_sdf", "resources", "gbuffer"):
        mod = importlib.import_module(f"{base}.{mod_name}")
        for cache in (getattr(mod, "_SHADERS", None), getattr(mod, "_SHADER", None)):
            for key, sh in (cache or {}).items():
                names[id(sh)] = f"{mod_name}:{key}" if mod_name != "compute" else str(key)
    return names


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--viewport", type=int, nargs=2, default=(640, 360), metavar=("W", "H"))
    ap.add_argument("--redraws", type=int, default=4)
    ap.add_argument("--pixel-size", default="1", choices=("1", "2", "4", "8"))
    ap.add_argument("--quality", default="MEDIUM", choices=("LOW", "MEDIUM", "HIGH"))
    ap.add_argument("--extra-objects", type=int, default=0)
    ap.add_argument("--f12", action="store_true", help="profile one F12 render instead")
    ap.add_argument("--scene", default="", help="a bench/quality_scenes scene (default: frame_time's)")
    ap.add_argument("--size", type=int, default=128, help="--f12: image side")
    ap.add_argument("--toggle", default="", metavar="SETTING",
                    help="--f12: a bool of scene.lumen.engine (e.g. screen_trace): one render "
                    "with it off and one on (after a warm-up of each), pass by pass side by side")
    args = ap.parse_args()
    if args.f12:
        return profile_f12(args)

    import bpy
    import gpu
    import demo
    import frame_time
    import viewport_harness

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    width, height = args.viewport
    with tempfile.TemporaryDirectory() as tmp:
        scene = frame_time.build_scene(Path(tmp), width, args.extra_objects)
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.engine = "LUMEN_GI"
        if bpy.ops.lumen.bake() != {'FINISHED'}:
            raise SystemExit("bake failed")
        scene.lumen.engine.viewport_quality = args.quality
        scene.render.preview_pixel_size = args.pixel_size

        per_draw = []          # [{pass: seconds}] per redraw
        timings = defaultdict(float)
        real_dispatch = gpu.compute.dispatch
        names = {}

        def timed_dispatch(sh, *groups):
            t = time.perf_counter()
            real_dispatch(sh, *groups)
            key = names.get(id(sh))
            if key is None:
                names.update(shader_names())
                key = names.get(id(sh), "?")
            timings[key] += time.perf_counter() - t

        def on_redraw(i):
            R = engine.LAST_RENDER
            row = dict(timings)
            row["(gbuffer draw)"] = R.get("gbuffer_seconds", 0.0)
            row["(extract + sync)"] = R.get("extract_seconds", 0.0) + R.get("sync_seconds", 0.0)
            row["(frame total)"] = R.get("frame_seconds", 0.0)
            per_draw.append(row)
            timings.clear()

        gpu.compute.dispatch = timed_dispatch
        try:
            out = viewport_harness.run(scene, engine.LumenGIRenderEngine, width, height,
                                       redraws=args.redraws + 1, on_redraw=on_redraw)
        finally:
            gpu.compute.dispatch = real_dispatch
        draw_seconds = out["seconds"]
        steady = per_draw[1:] or per_draw
        keys = sorted({k for row in steady for k in row},
                      key=lambda k: -statistics.median(r.get(k, 0.0) for r in steady))
        eevee_id = [i.identifier for i in
                    bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
                    if i.identifier.startswith("BLENDER_EEVEE")][0]
        scene.render.engine = eevee_id
        scene.eevee.taa_render_samples = 1
        eevee = []
        for _ in range(args.redraws + 1):
            t = time.perf_counter()
            bpy.ops.render.render()
            eevee.append(time.perf_counter() - t)

    ours = statistics.median(draw_seconds[1:])
    ev = statistics.median(eevee[1:])
    print(f"viewport {width}x{height}, Pixel Size {args.pixel_size}, {args.quality}, "
          f"{len(scene.objects)} objects; medians of {len(steady)} redraws after the first")
    print(f"{'pass':40s} {'ms':>9s} {'share':>7s}")
    total = statistics.median(r.get("(frame total)", 0.0) for r in steady)
    for k in keys:
        ms = statistics.median(r.get(k, 0.0) for r in steady) * 1000
        if ms >= 0.05:
            print(f"{k:40s} {ms:9.1f} {ms / max(total * 1000, 1e-9):7.1%}")
    print(f"view_draw (median) {ours * 1000:.1f} ms; EEVEE 1 sample at {width}x{height} "
          f"{ev * 1000:.1f} ms; ratio {ours / ev:.2f} (target: 0.5)")


def timed_dispatches(timings: dict, clock=time.perf_counter):
    """Patch gpu.compute.dispatch to add each dispatch's seconds to timings[shader name] (by
    `clock`: wall time, or time.process_time for the CPU llvmpipe's threads spent); returns
    the function that undoes it."""
    import gpu

    real, names = gpu.compute.dispatch, {}

    def timed(sh, *groups):
        t = clock()
        real(sh, *groups)
        key = names.get(id(sh))
        if key is None:
            names.update(shader_names())
            key = names.get(id(sh), "?")
        timings[key] += clock() - t

    gpu.compute.dispatch = timed
    return lambda: setattr(gpu.compute, "dispatch", real)


def profile_f12(args):
    import bpy
    import demo
    import frame_time
    import quality_scenes

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    with tempfile.TemporaryDirectory() as tmp:
        if args.scene:
            scene = getattr(quality_scenes, "build_" + args.scene)()
        else:
            scene = frame_time.build_scene(Path(tmp), args.size, args.extra_objects)
        scene.render.resolution_x = scene.render.resolution_y = args.size
        scene.render.resolution_percentage = 100
        scene.lumen.bake.cache_dir = tmp
        if bpy.ops.lumen.bake() != {'FINISHED'}:
            raise SystemExit("bake failed")
        scene.render.engine = "LUMEN_GI"
        if args.toggle:
            return toggle_f12(args, scene, engine)
        bpy.ops.render.render()                       # warm-up: shader compilation
        total, timings = timed_render()
    R = engine.LAST_RENDER
    print(f"F12 {args.size}x{args.size} of {args.scene or 'frame_time'}: {total * 1000:.0f} ms, "
          f"{R.get('gi_iterations')} GI iterations, surface-cache tiles relit "
          f"{R.get('gi_sc_tiles')}; GI timings (ms): "
          f"{ {k: round(v * 1000) for k, v in R.get('gi_timings', {}).items()} }")
    for k, v in sorted(timings.items(), key=lambda kv: -kv[1]):
        if v * 1000 >= 0.05:
            print(f"{k:40s} {v * 1000:9.1f} {v / total:7.1%}")


def timed_render():
    """(seconds, {pass: seconds}) of one F12 render."""
    import bpy

    timings = defaultdict(float)
    undo = timed_dispatches(timings)
    t = time.perf_counter()
    try:
        bpy.ops.render.render()
    finally:
        undo()
    return time.perf_counter() - t, timings


def toggle_f12(args, scene, engine):
    """--toggle: the same F12 with scene.lumen.engine.<args.toggle> off, then on."""
    import bpy

    settings = scene.lumen.engine
    if not isinstance(getattr(settings, args.toggle, None), bool):
        raise SystemExit(f"--toggle {args.toggle}: not a bool setting of scene.lumen.engine")
    runs = {}
    for on in (False, True):
        setattr(settings, args.toggle, on)
        bpy.ops.render.render()                       # warm-up: shader compilation
        runs[on] = timed_render() + (dict(engine.LAST_RENDER.get("gi_timings", {})),)
    (t0, p0, g0), (t1, p1, g1) = runs[False], runs[True]
    print(f"F12 {args.size}x{args.size} of {args.scene or 'frame_time'}, {args.toggle} off / on: "
          f"{t0 * 1000:.0f} / {t1 * 1000:.0f} ms (x{t0 / t1:.2f}); screen probes "
          f"{g0.get('probes', 0) * 1000:.0f} / {g1.get('probes', 0) * 1000:.0f} ms")
    for k in sorted(set(p0) | set(p1), key=lambda k: -max(p0.get(k, 0), p1.get(k, 0))):
        a, b = p0.get(k, 0.0), p1.get(k, 0.0)
        if max(a, b) * 1000 >= 0.05:
            print(f"{k:40s} {a * 1000:9.1f} {b * 1000:9.1f}")


if __name__ == "__main__":
    main()
