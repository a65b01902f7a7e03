"""Benchmark: mesh cards of the shared meshes (placement, capture, coverage).

For each mesh in ../shared/meshes, scaled so its longest side gets --texels texels, print cards,
texels, coverage, seconds of the whole card bake (placement + capture + coverage), texels per
second, and, as the baseline measured in the same run, the time of the bare Embree ray cast of
the same texel rays (no interpolation, no materials): the ratio shows what the capture adds.

    ./lumen bench card_capture [--texels 128 256] [--meshes spot dragon] [--repeat 3]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lumen_addon import cards as cardlib  # noqa: E402
from lumen_addon.obj import load_obj  # noqa: E402

MESHES = ROOT.parent / "shared" / "meshes"


def bare_rays(mc: cardlib.MeshCards, vertices, triangles) -> float:
    """Seconds to cast every texel ray of these cards with Embree and nothing else."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(triangles, np.int32))
    rays = []
    for c in mc.cards:
        w, h = c.resolution
        iu, iv = cardlib.PLANE[c.axis]
        o = np.zeros((w * h, 3), np.float32)
        ts = c.texel_size()
        o[:, iu] = np.tile(c.rect_min[0] + (np.arange(w) + 0.5) * ts[0], h)
        o[:, iv] = np.repeat(c.rect_min[1] + (np.arange(h) + 0.5) * ts[1], w)
        o += (cardlib.AXES[c.axis] * c.near).astype(np.float32)
        rays.append((o, np.repeat(cardlib.AXES[c.axis][None].astype(np.float32), len(o), 0),
                     np.full(len(o), c.far - c.near, np.float32)))
    t0 = time.perf_counter()
    for o, d, far in rays:
        scene.run(o, d, dists=far, output=1)
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--texels", type=int, nargs="+", default=[128, 256],
                    help="texels along the mesh's longest side")
    ap.add_argument("--meshes", nargs="+", default=None)
    ap.add_argument("--repeat", type=int, default=3, help="best of N timings")
    args = ap.parse_args(argv)
    if not MESHES.is_dir():
        print(f"SKIP: {MESHES} not found (the shared test meshes live beside the checkout)")
        return 0
    names = args.meshes or sorted(p.stem for p in MESHES.glob("*.obj"))
    head = (f"{'mesh':16s} {'tris':>7s} {'side':>5s} {'cards':>5s} {'texels':>8s} {'coverage':>9s} "
            f"{'seconds':>8s} {'Mtexel/s':>9s} {'rays s':>7s} {'ours/rays':>9s}")
    print(head)
    print("-" * len(head))
    for name in names:
        v, t = load_obj(MESHES / f"{name}.obj")
        extent = float((v.max(0) - v.min(0)).max())
        for side in args.texels:
            best = float("inf")
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                mc = cardlib.bake_mesh_cards(v, t, texel_density=side / extent)
                best = min(best, time.perf_counter() - t0)
            rays = min(bare_rays(mc, v, t) for _ in range(args.repeat))
            print(f"{name:16s} {len(t):7d} {side:5d} {len(mc.cards):5d} {mc.texels:8d} "
                  f"{100 * mc.coverage:8.2f}% {best:8.3f} {mc.texels / best / 1e6:9.2f} "
                  f"{rays:7.3f} {best / rays:9.1f}", flush=True)
    print("seconds: placement + capture + coverage of one mesh; rays s: the bare Embree cast of the "
          "same texel rays (baseline)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
