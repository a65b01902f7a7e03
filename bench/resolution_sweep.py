"""Benchmark: the viewport frame's cost against resolution, Lumen GI against EEVEE in one process.

The scene of bench/frame_time.py (floor, cube, sphere, cylinder, monkey; sun + point light). For
each size from 256x256 to 1920x1080: the engine's own view_draw (tools/viewport_harness.py: one GI
iteration per redraw, Combined drawn from the GPU) at Pixel Size 1 and 2, and EEVEE's 1-sample
render at the same size; medians of `--repeat` redraws after one warm-up, and the ratios.

    .venv/bin/python bench/resolution_sweep.py [--repeat 3] [--quality MEDIUM]
        [--sizes 256x256,640x360,1280x720,1920x1080]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quality", default="MEDIUM", choices=("LOW", "MEDIUM", "HIGH"))
    ap.add_argument("--sizes", default="256x256,640x360,1280x720,1920x1080")
    args = ap.parse_args()
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]

    import bpy
    import demo
    import frame_time
    import viewport_harness

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        demo.load_addon()
        from lumen_gi.gpu_shaders import engine

        scene = frame_time.build_scene(Path(tmp), 256)
        scene.lumen.bake.cache_dir = str(Path(tmp) / "cache")
        scene.lumen.bake.voxel_density = 16.0
        bpy.ops.lumen.bake()
        scene.lumen.engine.viewport_quality = args.quality
        eevee_id = [i.identifier for i in
                    bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
                    if i.identifier.startswith("BLENDER_EEVEE")][0]
        for w, h in sizes:
            row = {"size": f"{w}x{h}"}
            for ps in ("1", "2"):
                scene.render.preview_pixel_size = ps
                out = viewport_harness.run(scene, engine.LumenGIRenderEngine, w, h,
                                           redraws=args.repeat + 1)
                row["ps" + ps] = statistics.median(out["seconds"][1:])
                row["first" + ps] = out["seconds"][0]
            scene.render.engine = eevee_id
            scene.eevee.taa_render_samples = 1
            scene.render.resolution_x, scene.render.resolution_y = w, h
            scene.render.resolution_percentage = 100
            times = []
            for _ in range(args.repeat + 1):
                t = time.perf_counter()
                bpy.ops.render.render()
                times.append(time.perf_counter() - t)
            row["eevee"] = statistics.median(times[1:])
            rows.append(row)
            print(f"{row['size']:>10s}: view_draw PS1 {row['ps1'] * 1000:8.0f} ms (first "
                  f"{row['first1'] * 1000:.0f}), PS2 {row['ps2'] * 1000:8.0f} ms; {eevee_id} 1 "
                  f"sample {row['eevee'] * 1000:8.0f} ms; ratios PS1 {row['ps1'] / row['eevee']:.2f}, "
                  f"PS2 {row['ps2'] / row['eevee']:.2f}", flush=True)
    base, px0 = rows[0], sizes[0][0] * sizes[0][1]
    print("PS1 time against the first size:", ", ".join(
        f"{r['size']} {r['ps1'] / base['ps1']:.2f}x for {w * h / px0:.1f}x the pixels"
        for r, (w, h) in zip(rows, sizes)))


if __name__ == "__main__":
    main()
