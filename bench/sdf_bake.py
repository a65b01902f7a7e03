"""Benchmark: bake the shared meshes' SDFs and compare with open3d in the same run.

For each mesh in ../shared/meshes, scaled so its longest axis gets 64 and then 126 voxels, print
triangles, resolution, bricks kept/total, bytes and seconds of our bake (3 mips, sign included),
then the time open3d's RaycastingScene.compute_signed_distance takes for the sample points of the
bricks we keep (mip 0) and the ratio. Signs of both are checked against the generalised winding
number (libigl's fast winding number) on the band samples.

    ./lumen bench sdf_bake [--sizes 64 126] [--meshes spot dragon] [--repeat 3]

Times are the best of --repeat runs on each side (the machines we share are noisy).

open3d and libigl are benchmark-only (bench/requirements.txt), not dependencies of the extension.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lumen_addon import sdf  # noqa: E402
from lumen_addon.geometry import clean_mesh  # noqa: E402
from lumen_addon.obj import load_obj  # noqa: E402

MESHES = ROOT.parent / "shared" / "meshes"


def kept_samples(m: sdf.MeshSDF):
    """Unique sample positions of mip 0's kept bricks and their stored distances."""
    mip = m.mips[0]
    kept = np.argwhere(mip.indirection >= 0)
    slots = mip.indirection[tuple(kept.T)]
    off = np.stack(np.meshgrid(*(np.arange(sdf.BRICK),) * 3, indexing="ij"), -1).reshape(-1, 3)
    idx = (kept[:, None, :] * sdf.BRICK_CELLS + off[None]).reshape(-1, 3)
    codes = mip.bricks[slots].reshape(-1)
    idx, first = np.unique(idx, axis=0, return_index=True)
    dist = (codes[first].astype(np.float64) - 127.5) / 127.5 * mip.band
    return m.origin + idx * mip.voxel_size, dist


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 126])
    ap.add_argument("--meshes", nargs="+", default=None)
    ap.add_argument("--repeat", type=int, default=3, help="best of N timings, for both sides")
    args = ap.parse_args(argv)
    if not MESHES.is_dir():
        print(f"SKIP: {MESHES} not found (the shared test meshes live beside the checkout)")
        return 0
    try:
        import open3d as o3d
    except Exception as exc:  # noqa: BLE001 - report any import failure, keep benchmarking ours
        o3d = None
        print(f"open3d unavailable ({exc}); install bench/requirements.txt for the comparison")
    try:
        import igl
    except Exception:  # noqa: BLE001
        igl = None
        print("libigl unavailable: no winding-number sign check")

    names = args.meshes or sorted(p.stem for p in MESHES.glob("*.obj"))
    head = (f"{'mesh':16s} {'tris':>7s} {'vox':>4s} {'resolution':>12s} {'bricks':>11s} {'KiB':>7s} "
            f"{'ours s':>7s} {'o3d s':>7s} {'o3d/ours':>8s} {'ours=GWN':>9s} {'o3d=GWN':>8s}")
    print(head)
    print("-" * len(head))
    for name in names:
        v, t = load_obj(MESHES / f"{name}.obj")
        mesh = clean_mesh(v, t)
        extent = float((mesh.vertices.max(0) - mesh.vertices.min(0)).max())
        scene = None
        if o3d is not None:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                                o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
        for size in args.sizes:
            cap = int(math.ceil(size / sdf.BRICK_CELLS)) * sdf.BRICK_CELLS
            density = (size - 2 * sdf.MARGIN_VOXELS) / extent
            ours = float("inf")
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                m = sdf.bake_mesh_sdf(v, t, voxel_density=density, max_resolution=cap)
                ours = min(ours, time.perf_counter() - t0)
            st = m.stats()[0]
            pts, dist = kept_samples(m)
            band = np.abs(dist) < m.mips[0].band * 0.99
            o3d_s = ratio = agree_o3d = float("nan")
            if scene is not None:
                q = o3d.core.Tensor(pts.astype(np.float32))
                o3d_s = float("inf")
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    o3d_d = scene.compute_signed_distance(q).numpy()
                    o3d_s = min(o3d_s, time.perf_counter() - t0)
                ratio = o3d_s / ours
            agree = float("nan")
            if igl is not None:
                w = igl.fast_winding_number(mesh.vertices, mesh.triangles, pts[band])
                agree = float(np.mean((dist[band] < 0) == (w > 0.5)))
                if scene is not None:
                    agree_o3d = float(np.mean((o3d_d[band] < 0) == (w > 0.5)))
            res = "x".join(str(r) for r in st["resolution"])
            print(f"{name:16s} {len(mesh.triangles):7d} {size:4d} {res:>12s} "
                  f"{st['bricks_kept']:5d}/{st['bricks_total']:<5d} {st['bytes'] / 1024:7.1f} "
                  f"{ours:7.2f} {o3d_s:7.2f} {ratio:8.2f} {100 * agree:8.3f}% {100 * agree_o3d:7.3f}%",
                  flush=True)
    print("o3d/ours > 1 means our bake (3 mips, sign included) is faster than open3d's signed "
          "distance over mip 0's kept samples alone.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
