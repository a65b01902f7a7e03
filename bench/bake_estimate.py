"""Benchmark: the bake's memory and time estimate (lumen_addon/estimate.py) against real bakes.

Each case bakes one shared mesh (../shared/meshes; 'x4' / 'x16': every triangle split into 4 /
16, for 0.4 and 1.6 million triangles) with the defaults (20 voxels and 20 texels per metre),
scaled so its longest axis asks for 64, 126 or 252 voxels (Max Resolution 252), in a fresh
Python process: seconds of bake_scene (SDF, cards, atlas; wall and CPU: on a shared machine the
CPU seconds are the steadier number) and the peak resident memory above the process before the
mesh was made (ru_maxrss), next to the estimate and their ratio.

    .venv/bin/python bench/bake_estimate.py [--meshes spot armadillo] [--sizes 64 126 252]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
MESHES = ROOT.parent / "shared" / "meshes"

CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {root!r})
import numpy as np
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_addon.obj import load_obj

def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize()

base = rss()
v, t = load_obj({path!r})
v = np.asarray(v, np.float64)
t = np.asarray(t, np.int64)
for _ in range({splits}):        # each triangle into 4 at its edge midpoints (shared, watertight)
    n = len(t)
    edges = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], 1).reshape(-1, 2), 1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    mid = len(v) + inv.reshape(n, 3)
    v = np.concatenate([v, (v[uniq[:, 0]] + v[uniq[:, 1]]) / 2])
    a, b, c = t.T
    ab, bc, ca = mid.T
    t = np.concatenate([np.stack(x, 1) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
ext = v.max(0) - v.min(0)
settings = BakeSettings(voxel_density=20.0, max_resolution=252, texel_density=20.0)
v = v * (({size} - 4) / 20.0 / ext.max())
obj = ObjectInput("mesh", v, t)
t0, c0 = time.perf_counter(), time.process_time()
bake = bake_scene([obj], settings)
seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(dict(triangles=int(len(t)), extent=list(map(float, v.max(0) - v.min(0))),
                      seconds=seconds, cpu=cpu, peak=peak - base,
                      texels=int(sum(mc.texels for mc in bake.cards.values())),
                      resolution=list(next(iter(bake.meshes.values())).mips[0].resolution))))
"""


def run_case(name, splits, size):
    code = CHILD.format(root=str(ROOT), path=str(MESHES / f"{name}.obj"), splits=splits, size=size)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    from lumen_addon.bake import BakeSettings
    from lumen_addon.estimate import MeshSize, estimate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+",
                    default=["spot", "stanford-bunny", "armadillo", "armadillo:x4", "armadillo:x16"])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 126, 252])
    ap.add_argument("--json", help="write the measurements here (calibration)")
    ap.add_argument("--replay", help="measurements written by --json: compare them with the "
                    "current estimate without baking again")
    args = ap.parse_args(argv)
    if not MESHES.is_dir():
        print(f"SKIP: {MESHES} not found")
        return 0
    rows = []
    print(f"{'mesh':18} {'tris':>8} {'vox':>4} {'texels':>8} {'MB':>7} {'est MB':>7} {'ratio':>6} "
          f"{'s':>7} {'cpu s':>7} {'est s':>7} {'ratio':>6}")
    cases = ([(r["mesh"], r["size"], r) for r in json.loads(Path(args.replay).read_text())]
             if args.replay else [(spec, size, None) for spec in args.meshes for size in args.sizes])
    for spec, size, m in cases:
        if m is None:
            name, _, mult = spec.partition(":")
            m = run_case(name, {"": 0, "x4": 1, "x16": 2}[mult], size)
        settings = BakeSettings(voxel_density=20.0, max_resolution=252, texel_density=20.0)
        est = estimate([MeshSize(m["triangles"], tuple(m["extent"]))], settings)
        m.update(mesh=spec, size=size, est_bytes=est.bytes, est_seconds=est.seconds)
        rows.append(m)
        print(f"{spec:18} {m['triangles']:8d} {size:4d} {m['texels']:8d} "
              f"{m['peak'] / 1e6:7.0f} {est.bytes / 1e6:7.0f} {est.bytes / m['peak']:6.2f} "
              f"{m['seconds']:7.2f} {m['cpu']:7.2f} {est.seconds:7.2f} "
              f"{est.seconds / m['cpu']:6.2f}",
              flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    b = np.array([r["est_bytes"] / r["peak"] for r in rows])
    s = np.array([r["est_seconds"] / r["cpu"] for r in rows])
    w = np.array([r["seconds"] / r["cpu"] for r in rows])
    print(f"\nestimate / measured: memory {b.min():.2f}-{b.max():.2f} (median {np.median(b):.2f}), "
          f"CPU seconds {s.min():.2f}-{s.max():.2f} (median {np.median(s):.2f}); wall / CPU "
          f"seconds {w.min():.2f}-{w.max():.2f} on this machine")
    return 0


if __name__ == "__main__":
    sys.exit(main())
