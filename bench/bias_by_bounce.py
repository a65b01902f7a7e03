"""Where the missing light goes: mean luminance of LUMEN_GI against Cycles, bounce by bounce.

    LUMEN_SHARED_MESHES=/work/shared/meshes .venv/bin/python bench/bias_by_bounce.py \
        [--scenes glow,window] [--size 64] [--cycles-samples 256] [--bounces 3] [--out DIR]

Per scene (bench/quality_scenes.py), the mean luminance (Rec.709) of
    cycles b     Cycles with max_bounces = diffuse_bounces = b (b = 0: direct light only), the
                 quality bench's other settings; cached in DIR keyed by the scene and settings
    ours OFF     GI Quality Off: direct light (lights, SDF-occluded sky) and emission
    ours k       GI Medium whose final gather (screen probes) reads a surface cache iterated
                 k times (blend 1: no over-relaxation; the first iteration's rays read the
                 cleared cache, so it holds direct light + emission, and each further one adds
                 a bounce), then render_frames gathers with the cache frozen. So ours k carries
                 light paths of k indirect bounces, like Cycles b = k, except for light from
                 emissive surfaces, which reaches a surface only through the gather (ours OFF
                 has none of it, Cycles 0 has it as direct light): there ours k matches
                 Cycles k - 1.
    ours default every setting at its default (what bench/quality.py's `lumen` renders)
and the ratio ours / Cycles - 1 against the matching Cycles column. Light lost in direct light
shows in OFF vs cycles 0, in the first bounce (screen probes, the cache's direct light and
emission) in 1 vs 1, in the bounce chain (cache radiosity) in the steps from k to k + 1.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

nan = float('nan')

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

import quality  # noqa: E402
import quality_scenes  # noqa: E402


def mean_lum(img) -> float:
    return float(quality.lum(np.asarray(img, np.float64)[..., :3]).mean())


def cycles_lum(scene, digest, bounces, samples, out, log) -> float:
    import bpy

    s = dict(quality.cycles_settings(samples, False), max_bounces=bounces,
             diffuse_bounces=bounces)
    key = hashlib.sha256(json.dumps(dict(scene=digest, cycles=s, version=bpy.app.version_string),
                                    sort_keys=True).encode()).hexdigest()[:16]
    path = out / f"bounce_{scene.name}_{bounces}_{key}.exr"
    if not path.exists():
        quality.apply_cycles(scene, s)
        quality.render(scene, path, log)
    return mean_lum(quality.read_exr(path)["Combined"])


def lumen_lum(scene, out, log, quality_name, cache_bounces=None) -> float:
    """cache_bounces None: the default schedule; else that many cache iterations (blend 1),
    then the gathered frames with the cache frozen (GISettings.render_schedule replaced)."""
    gs = sys.modules["lumen_gi"].gpu_shaders.gi_settings
    original = gs.GISettings.render_schedule

    def frozen(self):
        frames = max(self.render_frames, 1)
        return [(1.0, None)] * cache_bounces + [(None, 1.0 / (j + 1)) for j in range(frames)]

    settings = scene.lumen.engine
    saved = settings.render_quality
    settings.render_quality = quality_name
    if cache_bounces is not None:
        gs.GISettings.render_schedule = frozen
    try:
        scene.render.engine = "LUMEN_GI"
        path = out / f"lumen_{scene.name}.exr"
        _, passes = quality.render(scene, path, log)
        err = quality.lumen_error()
        if err:
            raise RuntimeError(err)
        return mean_lum(passes["Combined"])
    finally:
        gs.GISettings.render_schedule = original
        settings.render_quality = saved


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scenes", default="glow,window")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--cycles-samples", type=int, default=256)
    ap.add_argument("--bounces", type=int, default=3, help="highest bounce count compared")
    ap.add_argument("--direct-only", action="store_true", help="ours: GI Off only (with --bounces 0)")
    ap.add_argument("--gather", default="PROBES", help="ours: the final gather (PIXEL: 64 rays "
                    "per pixel per frame through the same cache, the screen probes' error apart)")
    ap.add_argument("--out", default=str(ROOT / "out" / "bias_by_bounce"))
    args = ap.parse_args(argv)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    log = quality.Log(out / "blender.log")

    import bpy
    import demo

    with log.quiet():
        demo.load_addon()
    table = []
    for name in [s for s in args.scenes.split(",") if s]:
        t0 = time.perf_counter()
        with log.quiet():
            scene = quality_scenes.build(name)
        quality.common_setup(scene, args.size)
        scene.lumen.bake.cache_dir = str(out / "lumen_cache" / name)
        digest = quality.scene_digest(scene)
        with log.quiet():
            if bpy.ops.lumen.bake() != {'FINISHED'}:
                raise RuntimeError(f"{name}: lumen.bake failed: {scene.lumen.last_bake.status}")
        quality.lumen_engine().KEEP_IMAGES = False
        scene.lumen.engine.gi_gather = args.gather
        cyc = [cycles_lum(scene, digest, b, args.cycles_samples, out, log)
               for b in range(args.bounces + 2)]
        cyc_full = cycles_lum(scene, digest, quality.CYCLES_BOUNCES["max_bounces"],
                              args.cycles_samples, out, log)
        ours = {"OFF": lumen_lum(scene, out, log, "OFF")}
        for k in range(1, args.bounces + 1):
            ours[k] = lumen_lum(scene, out, log, "MEDIUM", cache_bounces=k)
        ours["default"] = lumen_lum(scene, out, log, "MEDIUM") if not args.direct_only else nan
        rows = [("OFF", ours["OFF"], 0)] + [(k, ours[k], k) for k in range(1, args.bounces + 1)]
        quality.say(f"\n[{name}] {args.size} px, gather {args.gather}, Cycles {args.cycles_samples} spp "
                    f"({time.perf_counter() - t0:.0f} s)")
        quality.say(f"{'ours':>8s} {'lum':>9s} | {'cycles b':>8s} {'lum':>9s} {'ratio-1':>8s} | "
                    f"{'cycles b-1':>10s} {'lum':>9s} {'ratio-1':>8s}")
        for label, v, b in rows:
            prev = f"{b - 1:10d} {cyc[b - 1]:9.5f} {v / cyc[b - 1] - 1:+8.1%}" if b >= 1 else \
                f"{'':10s} {'':9s} {'':8s}"
            quality.say(f"{str(label):>8s} {v:9.5f} | {b:8d} {cyc[b]:9.5f} {v / cyc[b] - 1:+8.1%} | "
                        + prev)
            table.append(dict(scene=name, ours=label, lum=v, cycles_b=b, cycles=cyc[b]))
        quality.say(f"{'default':>8s} {ours['default']:9.5f} | {'12':>8s} {cyc_full:9.5f} "
                    f"{ours['default'] / cyc_full - 1:+8.1%} |")
        quality.say("cycles by bounces: " + ", ".join(f"{b}: {v:.5f}" for b, v in enumerate(cyc))
                    + f", 12: {cyc_full:.5f}")
        table.append(dict(scene=name, ours="default", lum=ours["default"], cycles_b=12,
                          cycles=cyc_full, cycles_by_bounce=cyc))
    (out / "bias_by_bounce.json").write_text(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
