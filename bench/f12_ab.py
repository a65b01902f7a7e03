"""Benchmark: two versions of the engine's GLSL (or a GISettings field), A/B in one process on F12
renders of bench/quality_scenes scenes, with the images compared exactly.

Each round renders every scene with A, then B (each version: every compiled shader freed, the
GLSL resolver pointed at its folder, one 32x32 warm-up render for compilation, then the timed F12
at --size). Prints per scene the median F12 seconds of A and B (wall, and the process's CPU
seconds, llvmpipe's threads included: on a shared machine the wall time of one render varies by
tens of percent with the other jobs, its CPU time much less), B/A, the per-pass CPU seconds that
changed most, and the largest absolute difference between the two Combined images (0: the
change is exact; the engine is deterministic, so any difference is the change's).
Why: bench/glsl_ab.py times the viewport; an F12 optimisation must keep F12's image.

    .venv/bin/python bench/f12_ab.py --b /tmp/variant [--a gpu_shaders/glsl] [--rounds 1]
                                     [--scenes cornell,window] [--size 128] [--setting FIELD=VALUE]
                                     [--setting-both FIELD=VALUE] [--show PASS]
                                     [--save DIR]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]


def timed_render():
    """(wall seconds, CPU seconds, {pass: CPU seconds}) of one F12 render: every compute
    dispatch timed by the process's CPU time (llvmpipe runs it before dispatch returns)."""
    import time

    import bpy
    import pass_profile

    timings = defaultdict(float)
    undo = pass_profile.timed_dispatches(timings, clock=time.process_time)
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        bpy.ops.render.render()
    finally:
        undo()
    return time.perf_counter() - wall, time.process_time() - cpu, timings


def baked_scene(name: str, cache_dir: str):
    """bench/quality_scenes scene `name`, baked into `cache_dir`, set to render with Lumen GI at
    100% (needs the add-on loaded: tools/demo.load_addon)."""
    import bpy
    import quality_scenes

    scene = quality_scenes.build(name)
    scene.lumen.bake.cache_dir = cache_dir
    if bpy.ops.lumen.bake() != {'FINISHED'}:
        raise SystemExit(f"{name}: bake failed: {scene.lumen.last_bake.status}")
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_percentage = 100
    return scene


def warm_then_time(scene, size: int):
    """A 32x32 F12 (shader compilation), then timed_render() at size x size."""
    import bpy

    scene.render.resolution_x = scene.render.resolution_y = 32
    bpy.ops.render.render()
    scene.render.resolution_x = scene.render.resolution_y = size
    return timed_render()


def main():
    import glsl_ab

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    glsl_ab.ab_arguments(ap, rounds=1)
    ap.add_argument("--scenes", default="cornell")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--show", action="append", default=[], metavar="PASS",
                    help="also print this pass's seconds (besides the six that changed most)")
    ap.add_argument("--save", metavar="DIR",
                    help="write each scene's Combined images to DIR/<scene>_a.npy, _b.npy")
    args = ap.parse_args()
    folders, settings_b, both = glsl_ab.ab_versions(args)

    import demo
    import numpy as np

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    engine.KEEP_IMAGES = True
    versions = glsl_ab.Versions(addon, settings_b, both)
    for name in args.scenes.split(","):
        seconds, cpus, passes = [[], []], [[], []], [defaultdict(list), defaultdict(list)]
        images = [None, None]
        with tempfile.TemporaryDirectory() as tmp:
            scene = baked_scene(name, tmp)
            for _ in range(args.rounds):
                for version, folder in enumerate(folders):
                    versions.use(version, folder)
                    try:
                        total, cpu, timings = warm_then_time(scene, args.size)
                    finally:
                        versions.settings_back()
                    R = engine.LAST_RENDER
                    if "error" in R:
                        raise SystemExit(R.get("traceback", R["error"]))
                    seconds[version].append(total)
                    cpus[version].append(cpu)
                    for k, v in timings.items():
                        passes[version][k].append(v)
                    images[version] = np.array(R["combined"], np.float64)
        versions.restore()
        a, b = (statistics.median(s) for s in seconds)
        ca, cb = (statistics.median(s) for s in cpus)
        diff = float(np.abs(images[0] - images[1]).max())
        if args.save:
            Path(args.save).mkdir(parents=True, exist_ok=True)
            for tag, image in zip("ab", images):
                np.save(Path(args.save) / f"{name}_{tag}.npy", image)
        print(f"[{name}] F12 {args.size}px: wall A {a:.2f} s, B {b:.2f} s, B/A {b / a:.3f}; "
              f"CPU A {ca:.2f} s, B {cb:.2f} s, B/A {cb / ca:.3f}; "
              f"max |Combined B - A| {diff:.3g}", flush=True)
        rows = []
        for k in set(passes[0]) | set(passes[1]):
            pa, pb = (statistics.median(p[k]) if p[k] else 0.0 for p in passes)
            rows.append((abs(pb - pa), k, pa, pb))
        top = sorted(rows, reverse=True)
        for _, k, pa, pb in top[:6] + [r for r in top[6:] if r[1] in args.show]:
            print(f"    {k:36s} {pa:8.2f} {pb:8.2f} CPU s  B/A {pb / pa if pa else 0:.3f}")


if __name__ == "__main__":
    main()
