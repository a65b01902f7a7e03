"""Benchmark: two versions of the engine's GLSL, A/B in one process, pass by pass (viewport frame).

Each version is a whole copy of gpu_shaders/glsl (copy the folder, edit the copy). The rounds
alternate A and B; each round frees every compiled shader, points the GLSL resolver at that
version's folder, runs the engine's own view_draw (tools/viewport_harness.py) on
bench/frame_time.py's scene for 1 + 2 redraws and keeps the 2 after the first (compilation).
Why: on a shared machine two runs minutes apart differ by up to 2x; alternating in one process
gives both versions the same load. Prints the median frame and per-pass milliseconds and B/A.
The Python side is this checkout's: only GLSL that binds the same inputs can be compared.
Found with it: gi_visible's corner test as twelve inlined SDF lookups cost 44% of the probe trace
(README, frame time).

    .venv/bin/python bench/glsl_ab.py --b /tmp/variant [--a gpu_shaders/glsl] [--rounds 2]
                                      [--viewport 640 360]
"""
from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

PASSES = ("screen_probe_trace", "screen_probe_integrate", "direct_light",
          "surface_cache_probe_trace", "screen_probe_links", "screen_probe_filter")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", default=str(ROOT / "gpu_shaders" / "glsl"), help="GLSL folder A")
    ap.add_argument("--b", required=True, help="GLSL folder B")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--viewport", type=int, nargs=2, default=(640, 360), metavar=("W", "H"))
    args = ap.parse_args()
    folders = [Path(args.a).resolve(), Path(args.b).resolve()]
    for f in folders:
        if not (f / "sdf_lib.glsl").is_file():
            raise SystemExit(f"{f}: not a copy of gpu_shaders/glsl (no sdf_lib.glsl)")

    import bpy
    import demo
    import frame_time
    import pass_profile
    import viewport_harness

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    include = importlib.import_module(f"{addon.__name__}.gpu_shaders.glsl_include")
    width, height = args.viewport
    results = {f: defaultdict(list) for f in folders}
    with tempfile.TemporaryDirectory() as tmp:
        scene = frame_time.build_scene(Path(tmp), width, 0)
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.engine = "LUMEN_GI"
        if bpy.ops.lumen.bake() != {'FINISHED'}:
            raise SystemExit("bake failed")
        for _ in range(args.rounds):
            for folder in folders:
                addon.gpu_shaders.free_shaders()
                include.files.__defaults__ = (folder,)     # the resolver's default folder
                include.source.__defaults__ = (folder,)
                timings = defaultdict(float)
                undo = pass_profile.timed_dispatches(timings)
                rows = []

                def on_redraw(i, rows=rows, timings=timings):
                    row = dict(timings)
                    row["(frame)"] = engine.LAST_RENDER.get("frame_seconds", 0.0)
                    rows.append(row)
                    timings.clear()
                try:
                    viewport_harness.run(scene, engine.LumenGIRenderEngine, width, height,
                                         redraws=3, on_redraw=on_redraw)
                finally:
                    undo()
                for row in rows[1:]:
                    for k, v in row.items():
                        results[folder][k].append(v)
    include.files.__defaults__ = include.source.__defaults__ = (include.GLSL,)
    print(f"viewport {width}x{height}, {args.rounds} rounds, medians (ms)")
    print(f"{'pass':32s} {'A':>10s} {'B':>10s} {'B/A':>7s}")
    for k in ("(frame)",) + PASSES:
        a, b = (statistics.median(results[f][k]) * 1000 if results[f][k] else 0.0
                for f in folders)
        print(f"{k:32s} {a:10.1f} {b:10.1f} {b / a if a else float('nan'):7.3f}")


if __name__ == "__main__":
    main()
