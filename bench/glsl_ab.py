"""Benchmark: two versions of the engine's GLSL or settings, A/B in one process, pass by pass.

Each version is a whole copy of gpu_shaders/glsl (copy the folder, edit the copy). The rounds
alternate A and B; each round frees every compiled shader, points the GLSL resolver at that
version's folder, runs the engine's own view_draw (tools/viewport_harness.py) on
bench/frame_time.py's scene for 1 + 2 redraws and keeps the 2 after the first (compilation).
Why: on a shared machine two runs minutes apart differ by up to 2x; alternating in one process
gives both versions the same load. Prints the median frame and per-pass milliseconds and B/A.
The Python side is this checkout's: only GLSL that binds the same inputs can be compared.
`--setting FIELD=VALUE` (repeatable) gives B a GISettings field of its own instead of (or as well
as) other GLSL, patched into gi_settings.from_scene for the viewport (e.g. adaptive_probes=0).
Found with it: gi_visible's corner test as twelve inlined SDF lookups cost 44% of the probe trace
(README, frame time).
`--objects N` renders bench/object_scaling.py's scene of N objects instead (baked at 8 voxels/m,
viewport quality MEDIUM, Pixel Size 1, as that bench does), `--redraws R` times R redraws after
the first (default 2; 4 covers one cycle of Spread Over 4): what grows with the object count,
A/B under the same load. `--cpu` times CPU seconds (time.process_time: llvmpipe's threads are
this process's) instead of wall seconds, which other jobs on a shared host move more.

    .venv/bin/python bench/glsl_ab.py --b /tmp/variant [--a gpu_shaders/glsl] [--rounds 2]
                                      [--viewport 640 360] [--setting FIELD=VALUE ...]
                                      [--objects 1000 --viewport 128 128 --redraws 4]
"""
from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

PASSES = ("screen_probe_trace", "screen_probe_integrate", "screen_probe_fallback", "direct_light",
          "surface_cache_probe_trace", "surface_cache_direct", "surface_cache_indirect",
          "screen_probe_links", "screen_probe_filter", "screen_probe_lumen_trace", "hzb_depth",
          "hzb_reduce")


def ab_arguments(ap, rounds: int):
    """The A/B options bench/glsl_ab.py and bench/f12_ab.py share: --a, --b, --setting, --rounds."""
    ap.add_argument("--a", default=str(ROOT / "gpu_shaders" / "glsl"), help="GLSL folder A")
    ap.add_argument("--b", default=None, help="GLSL folder B (default: A)")
    ap.add_argument("--setting", action="append", default=[], metavar="FIELD=VALUE",
                    help="a GISettings field B renders with (int, float or 0/1)")
    ap.add_argument("--setting-both", action="append", default=[], metavar="FIELD=VALUE",
                    help="a GISettings field both A and B render with (e.g. to compare two "
                         "versions of a pass that is off by default)")
    ap.add_argument("--rounds", type=int, default=rounds)


def parse_settings(items) -> dict:
    """{GISettings field: int or float} from FIELD=VALUE strings."""
    out = {}
    for item in items:
        field, _, value = item.partition("=")
        out[field] = float(value) if "." in value else int(value)
    return out


def ab_versions(args) -> tuple:
    """([GLSL folder A, B], {GISettings field: value} of B, of both) from ab_arguments' options,
    checked."""
    folders = [Path(args.a).resolve(), Path(args.b or args.a).resolve()]
    settings_b = parse_settings(args.setting)
    if folders[0] == folders[1] and not settings_b:
        raise SystemExit("nothing to compare: give --b or --setting")
    for f in folders:
        if not (f / "sdf_lib.glsl").is_file():
            raise SystemExit(f"{f}: not a copy of gpu_shaders/glsl (no sdf_lib.glsl)")
    return folders, settings_b, parse_settings(args.setting_both)


class Versions:
    """Switches the loaded add-on between version A and B: the GLSL folder its resolver reads
    (every compiled shader freed) and, for B (and for both: `both`), GISettings fields replaced
    in from_scene."""

    def __init__(self, addon, settings_b: dict, both: dict | None = None):
        import dataclasses

        self.addon = addon
        self.include = importlib.import_module(f"{addon.__name__}.gpu_shaders.glsl_include")
        self.gi_settings = importlib.import_module(f"{addon.__name__}.gpu_shaders.gi_settings")
        self.original = self.gi_settings.from_scene
        self.both = dict(both or {})
        self.settings_b = {**self.both, **settings_b}
        fields = {f.name for f in dataclasses.fields(self.gi_settings.GISettings)}
        for field in self.settings_b:
            if field not in fields:
                raise SystemExit(f"--setting {field}: not a GISettings field")

    def use(self, version: int, folder):
        import dataclasses

        extra, original = (self.settings_b if version else self.both), self.original
        self.gi_settings.from_scene = (lambda s, viewport=False, extra=extra: dataclasses.replace(
            original(s, viewport), **extra))
        self.addon.gpu_shaders.free_shaders()
        self.include.files.__defaults__ = (folder,)     # the resolver's default folder
        self.include.source.__defaults__ = (folder,)

    def settings_back(self):
        self.gi_settings.from_scene = self.original

    def restore(self):
        self.settings_back()
        self.include.files.__defaults__ = self.include.source.__defaults__ = (self.include.GLSL,)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ab_arguments(ap, rounds=2)
    ap.add_argument("--viewport", type=int, nargs=2, default=(640, 360), metavar=("W", "H"))
    ap.add_argument("--objects", type=int, default=0,
                    help="bench/object_scaling.py's scene of this many objects")
    ap.add_argument("--redraws", type=int, default=2, help="timed redraws after the first")
    ap.add_argument("--cpu", action="store_true",
                    help="CPU seconds (llvmpipe's threads included) instead of wall time: "
                         "less moved by other jobs on a shared host")
    args = ap.parse_args()
    folders, settings_b, both = ab_versions(args)

    import bpy
    import demo
    import frame_time
    import pass_profile
    import viewport_harness

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    versions = Versions(addon, settings_b, both)
    width, height = args.viewport
    results = [defaultdict(list), defaultdict(list)]
    with tempfile.TemporaryDirectory() as tmp:
        if args.objects:
            import object_scaling
            scene = object_scaling.build_scene(args.objects, width)
            scene.lumen.bake.cache_dir = str(Path(tmp) / "cache")
            scene.lumen.bake.voxel_density = 8.0
            scene.render.preview_pixel_size = "1"
            scene.lumen.engine.viewport_quality = "MEDIUM"
        else:
            scene = frame_time.build_scene(Path(tmp), width, 0)
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.engine = "LUMEN_GI"
        if bpy.ops.lumen.bake() != {'FINISHED'}:
            raise SystemExit("bake failed")
        for _ in range(args.rounds):
            for version, folder in enumerate(folders):
                versions.use(version, folder)
                timings = defaultdict(float)
                clock = time.process_time if args.cpu else time.perf_counter
                undo = pass_profile.timed_dispatches(timings, clock=clock)
                rows = []
                last = [clock()]

                def on_redraw(i, rows=rows, timings=timings, last=last, clock=clock):
                    if "error" in engine.LAST_RENDER:    # a version that fails is not timed
                        raise SystemExit(f"version {'AB'[version]} ({folder}): "
                                         f"{engine.LAST_RENDER.get('traceback') or engine.LAST_RENDER['error']}")
                    row = dict(timings)
                    now = clock()
                    row["(frame)"] = (now - last[0] if args.cpu
                                      else engine.LAST_RENDER.get("frame_seconds", 0.0))
                    last[0] = now
                    rows.append(row)
                    timings.clear()
                try:
                    viewport_harness.run(scene, engine.LumenGIRenderEngine, width, height,
                                         redraws=1 + args.redraws, on_redraw=on_redraw)
                finally:
                    undo()
                    versions.settings_back()
                for row in rows[1:]:
                    for k, v in row.items():
                        results[version][k].append(v)
    versions.restore()
    what = f"{args.objects} objects" if args.objects else "frame_time's scene"
    print(f"{what}, viewport {width}x{height}, {args.rounds} rounds x {args.redraws} redraws, "
          f"medians ({'CPU ' if args.cpu else ''}ms); B: "
          f"{folders[1] if folders[1] != folders[0] else 'same GLSL'} {settings_b or ''}")
    print(f"{'pass':32s} {'A':>10s} {'B':>10s} {'B/A':>7s}")
    for k in ("(frame)",) + PASSES:
        a, b = (statistics.median(r[k]) * 1000 if r[k] else 0.0 for r in results)
        print(f"{k:32s} {a:10.1f} {b:10.1f} {b / a if a else float('nan'):7.3f}")


if __name__ == "__main__":
    main()
