"""Benchmark: does the still viewport converge to the F12 image on every quality scene, and how fast?

Issue 9 asks that the viewport, left still, converge to the same image as F12 (relMSE under
0.01); issue 10 that a viewport redraw be cheap (GISettings.split spreads each refinement step
over redraws). Per bench/quality_scenes scene at --size, default settings (viewport quality =
render quality): one F12 render, then the engine's own view_draw (tools/viewport_harness.py, a
still scene camera) until it says it is done ("refining n/N" and the anti-aliasing samples) or
--max-redraws, reading Combined back after every redraw (engine.KEEP_IMAGES: a bench-only cost,
not counted in the redraw times). Prints per scene: redraws to convergence, relMSE of the
viewport against F12 at the first redraw, at a quarter, half and the end of its history, and
at the end; the median redraw time and F12's time.

    .venv/bin/python bench/viewport_convergence.py [--size 128] [--scenes cornell,thin]
                                                   [--max-redraws 120] [--split 1] [--keep DIR]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]


def rel_mse(a, b) -> float:
    a, b = np.asarray(a, np.float64)[..., :3], np.asarray(b, np.float64)[..., :3]
    return float(((a - b) ** 2).mean() / max((b ** 2).mean(), 1e-30))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--scenes", default="cornell,window,thin,yard,glow,imported,textured")
    ap.add_argument("--max-redraws", type=int, default=120)
    ap.add_argument("--split", type=int, default=None,
                    help="the scenes' Viewport > Spread over (viewport_split: 1, 4 or 16; default "
                    "the property's default)")
    ap.add_argument("--keep", default=None,
                    help="a folder: save F12's and the last redraw's direct, indirect and combined "
                    "as <scene>_<f12|viewport>_<pass>.npy (to see where they differ)")
    args = ap.parse_args()

    import bpy
    import demo
    import quality_scenes
    import viewport_harness

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes.split(","):
            try:
                scene = quality_scenes.build(name)
            except FileNotFoundError as exc:
                print(f"[{name}] skipped: {exc}")
                continue
            scene.render.resolution_x = scene.render.resolution_y = args.size
            scene.render.resolution_percentage = 100
            scene.lumen.bake.cache_dir = str(Path(tmp) / name)
            if bpy.ops.lumen.bake() != {'FINISHED'}:
                raise SystemExit(f"[{name}] bake failed")
            scene.render.engine = "LUMEN_GI"
            if args.split is not None:
                scene.lumen.engine.viewport_split = str(args.split)
            engine.KEEP_IMAGES = True
            bpy.ops.render.render()                   # warm-up (compilation)
            t = time.perf_counter()
            bpy.ops.render.render()
            f12_seconds = time.perf_counter() - t
            R = engine.LAST_RENDER
            if "error" in R:
                raise SystemExit(R.get("traceback", R["error"]))
            f12 = R["combined"].copy()
            passes = ("direct", "indirect", "combined")
            if args.keep:
                Path(args.keep).mkdir(parents=True, exist_ok=True)
                for k in passes:
                    np.save(Path(args.keep) / f"{name}_f12_{k}.npy", R[k])
            trail = []

            def on_redraw(i, trail=trail):
                R = engine.LAST_RENDER
                if "error" in R:
                    raise RuntimeError(R.get("traceback", R["error"]))
                aa = R.get("aa_progress") or (0, 0)
                trail.append(dict(err=rel_mse(R["combined"], f12), gi=R.get("gi_progress"),
                                  done=bool(R.get("gi_converged")) and aa[0] >= aa[1]))
                return None

            out = viewport_harness.run(scene, engine.LumenGIRenderEngine, args.size, args.size,
                                       redraws=args.max_redraws, on_redraw=on_redraw,
                                       until=lambda i: trail and trail[-1]["done"])
            engine.KEEP_IMAGES = False
            if args.keep:
                for k in passes:
                    np.save(Path(args.keep) / f"{name}_viewport_{k}.npy", engine.LAST_RENDER[k])
            n = len(trail)
            hist = trail[0]["gi"][1] if trail[0]["gi"] else n
            at = {k: trail[min(int(k * hist), n) - 1]["err"] for k in (0.25, 0.5, 1.0)}
            done = next((i + 1 for i, r in enumerate(trail) if r["done"]), None)
            row = dict(scene=name, redraws=done, first=trail[0]["err"], q=at[0.25], h=at[0.5],
                       full=at[1.0], end=trail[-1]["err"],
                       redraw_ms=statistics.median(out["seconds"][1:]) * 1000,
                       f12_s=f12_seconds)
            rows.append(row)
            print(f"[{name}] {row}", flush=True)
    print(f"\nstill viewport against F12, {args.size}x{args.size}, default settings "
          f"(relMSE of the viewport's Combined against F12's)")
    print(f"{'scene':10s} {'done at':>8s} {'first':>8s} {'1/4 h':>8s} {'1/2 h':>8s} "
          f"{'history':>8s} {'end':>8s} {'redraw ms':>10s} {'F12 s':>7s}")
    for r in rows:
        print(f"{r['scene']:10s} {str(r['redraws']):>8s} {r['first']:8.4f} {r['q']:8.4f} "
              f"{r['h']:8.4f} {r['full']:8.4f} {r['end']:8.4f} {r['redraw_ms']:10.1f} "
              f"{r['f12_s']:7.2f}")


if __name__ == "__main__":
    main()
