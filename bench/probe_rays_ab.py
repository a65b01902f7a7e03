"""Diagnostic: the screen probes' rays one by one, without and with Lumen's screen trace.

One F12 of a bench/quality_scenes scene per version (A: screen_trace off, B: on; the same seed,
so the same probes, rays and surface cache in the first GI iteration), the first probe trace's
atlas captured texel by texel (radiance rgb, hit distance). Prints how much of the light the
rays that differ carry, split by whether they hit at the same distance (the same surface, read
differently) or not (another surface, the sky), and the largest of each.
Why: bench/quality.py's relMSE moves by tenths of a percent either way with the screen trace on,
less than seed to seed; the rays say where the two traces disagree (it found the corner rule:
tests/gpu/test_screen_trace_corners.py).

    .venv/bin/python bench/probe_rays_ab.py [--scene glow] [--seed 0] [--size 128] [--show 12]
"""
from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

TRACES = ("screen_probe_trace", "screen_probe_lumen_trace")
SAME_T = 0.02        # m: hits this close are taken as the same surface


def capture_first_trace(addon, render):
    """The out_image of the first probe-trace dispatch during render() (float32 [h, w, 4])."""
    compute = importlib.import_module(f"{addon.__name__}.gpu_shaders.compute")
    original = compute.Pass.run_groups
    got = {}

    def hooked(self, groups, **inputs):
        original(self, groups, **inputs)
        if self.name in TRACES and "atlas" not in got:
            got["atlas"] = compute.read(inputs["out_image"]).copy()

    compute.Pass.run_groups = hooked
    try:
        render()
    finally:
        compute.Pass.run_groups = original
    if "atlas" not in got:
        raise SystemExit("no screen-probe trace ran (GI off, or another gather?)")
    return got["atlas"]


def report(A, B, show: int):
    import numpy as np

    live = (A[..., 3] >= 0.0) & (B[..., 3] >= 0.0)
    ta, tb = A[..., 3][live], B[..., 3][live]
    La, Lb = A[..., :3][live].mean(-1), B[..., :3][live].mean(-1)
    total = max(float(La.sum()), 1e-12)
    dL = np.abs(Lb - La)
    print(f"rays {live.sum()}, mean radiance {La.mean():.4f}; |B - A| {dL.sum() / total:.5f} of "
          f"the light, B - A {(Lb - La).sum() / total:+.5f}")
    same = np.abs(ta - tb) < SAME_T
    for name, m in (("same distance", same), ("other distance", ~same)):
        print(f"  {name:15s} rays {m.sum():6d} ({m.mean() * 100:5.2f}%)  |B - A| "
              f"{dL[m].sum() / total:.5f}  B - A {(Lb - La)[m].sum() / total:+.5f}")
        dt = (tb - ta)[m]
        if m.any():
            print(f"      t B - A: mean {dt.mean() * 1e3:+.2f} mm, B farther {(dt > 0).mean() * 100:.1f}%"
                  f", nearer {(dt < 0).mean() * 100:.1f}%")
        for i in np.argsort(-dL[m])[:show]:
            print(f"      t {ta[m][i]:8.3f} -> {tb[m][i]:8.3f}   "
                  f"L {La[m][i]:8.4f} -> {Lb[m][i]:8.4f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="glow")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--show", type=int, default=12, help="largest differences printed per kind")
    args = ap.parse_args()

    import bpy
    import demo
    import f12_ab
    import glsl_ab

    addon = demo.load_addon()
    versions = glsl_ab.Versions(addon, {"screen_trace": 1}, {"seed": args.seed})
    atlases = []
    with tempfile.TemporaryDirectory() as tmp:
        scene = f12_ab.baked_scene(args.scene, tmp)
        scene.render.resolution_x = scene.render.resolution_y = args.size
        try:
            for version in (0, 1):
                versions.use(version, versions.include.GLSL)
                atlases.append(capture_first_trace(addon, bpy.ops.render.render))
        finally:
            versions.restore()
    print(f"{args.scene}, seed {args.seed}, {args.size} px: A screen trace off, B on")
    report(*atlases, args.show)


if __name__ == "__main__":
    main()
