"""Benchmark: the skyline packer (lumen_addon/atlas.py) against xatlas on real card sets.

The design names xatlas for the surface-cache atlas. Its Python binding packs pre-sized
rectangles exactly when each rectangle is its own UV chart (own four vertices, own face material
so charts never merge), with texels_per_unit = 1, rotate_charts and rotate_charts_to_axis off and
bilinear off: a chart of (w - 1) x (h - 1) units spans the centres of w x h texels, so it lands
on exactly w x h texels at a whole-texel position (checked for every rectangle below).

Two atlases of each scene, the cards from a real bake of the scene (extract_scene + bake_scene):
    cards     the bake's card atlas: every mesh's cards, PADDING texels of repeated edge around
              each (xatlas: padding = PADDING, which keeps charts 2 x PADDING apart, plus a border
              of PADDING around the atlas for the outer cards' edge texels)
    lighting  the surface cache's lighting atlas (gpu_shaders/card_packing.py): one rectangle per
              (instance, card), sizes rounded up to 4x4 blocks, no padding (xatlas: padding 0,
              blockAlign on, so every 4x4 probe block stays on one card)
Occupancy = card texels / atlas texels; seconds = best of --repeat packings. Every packing is
checked (sizes, whole-texel positions, no overlap of the reserved areas, inside the atlas); a
packing that fails the check is reported as inexact.

    .venv/bin/python bench/atlas_packing.py [--scenes demo cornell ...] [--repeat 5]

xatlas is benchmark-only (bench/requirements.txt); scenes are the demo (tools/demo.py) and the
quality benchmark's (bench/quality_scenes.py).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

PROBE_BLOCK = 4


def card_sets(name: str):
    """(card atlas sizes [(w, h)], lighting atlas sizes [(w, h)]) of a real bake of scene `name`."""
    import bpy

    import demo
    addon = demo.load_addon()
    if name == "demo":
        scene = demo.build_demo_scene()
    else:
        import quality_scenes
        scene = quality_scenes.build(name)
    from lumen_gi.lumen_addon.bake import bake_scene
    from lumen_gi.operators.bake_op import settings_from
    from lumen_gi.operators.extract import extract_scene

    del addon
    objects, _ = extract_scene(bpy.context.evaluated_depsgraph_get())
    bake = bake_scene(objects, settings_from(scene))
    cards = [tuple(int(v) for v in c.resolution) for mc in bake.cards.values() for c in mc.cards]
    per_mesh = {k: [tuple(int(v) for v in c.resolution) for c in mc.cards]
                for k, mc in bake.cards.items()}
    lighting = [(-(-w // PROBE_BLOCK) * PROBE_BLOCK, -(-h // PROBE_BLOCK) * PROBE_BLOCK)
                for inst in bake.instances for w, h in per_mesh.get(inst.cards, [])]
    return cards, lighting


def skyline(sizes, padding):
    from lumen_gi.lumen_addon.atlas import pack

    pos, (w, h) = pack(sizes, padding)
    return np.asarray(pos, np.int64), (int(w), int(h))


def skyline_one_width(sizes, padding):
    """The packer before the width search: one width, sqrt(1.1 x area) rounded up to 64."""
    from lumen_gi.lumen_addon.atlas import _skyline

    outer = np.asarray(sizes, np.int64).reshape(-1, 2) + 2 * padding
    area = float((outer[:, 0] * outer[:, 1]).sum())
    width = int(max(outer[:, 0].max(), -(-int(np.ceil(np.sqrt(area * 1.1))) // 64) * 64))
    pos, height = _skyline(outer, width)
    return pos + padding, (width, -(-height // 4) * 4)


def xatlas_pack(sizes, padding, block_align=False):
    """Positions (N, 2) of each rectangle's first texel and the atlas (width, height), by xatlas:
    each rectangle its own chart, texels_per_unit 1, no rotation, no bilinear border."""
    import xatlas

    s = np.asarray(sizes, np.int64).reshape(-1, 2)
    n = len(s)
    uv = np.zeros((n, 4, 2), np.float32)
    span = (s - 1).astype(np.float32)               # texel centres of the first and last texel
    uv[:, 1, 0] = span[:, 0]
    uv[:, 2] = span
    uv[:, 3, 1] = span[:, 1]
    faces = (np.arange(n, dtype=np.uint32)[:, None] * 4
             + np.array([0, 1, 2, 0, 2, 3], np.uint32)).reshape(-1, 3)
    material = np.repeat(np.arange(n, dtype=np.uint32), 2).reshape(-1, 1)
    atlas = xatlas.Atlas()
    atlas.add_uv_mesh(uv.reshape(-1, 2), faces, material)
    opts = xatlas.PackOptions()
    opts.texels_per_unit = 1.0
    opts.rotate_charts = False
    opts.rotate_charts_to_axis = False
    opts.bilinear = False
    opts.padding = int(padding)
    opts.blockAlign = bool(block_align)
    atlas.generate(xatlas.ChartOptions(), opts)
    vmap, _, out_uv = atlas.get_mesh(0)
    width, height = int(atlas.width), int(atlas.height)
    texel = out_uv.astype(np.float64) * [width, height] - 0.5      # texel centre -> index
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    np.minimum.at(lo, vmap // 4, texel)
    np.maximum.at(hi, vmap // 4, texel)
    pos = np.rint(lo).astype(np.int64)
    exact = (np.allclose(lo, pos, atol=1e-3) and np.allclose(hi - lo, s - 1, atol=1e-3)
             and atlas.atlas_count == 1)
    # the outer cards' repeated edge texels need `padding` texels inside the atlas
    return pos + padding, (width + 2 * padding, height + 2 * padding), exact


def check(pos, sizes, atlas_size, padding) -> bool:
    """Every rectangle, grown by `padding` on each side, inside the atlas and overlapping no other."""
    s = np.asarray(sizes, np.int64).reshape(-1, 2)
    w, h = atlas_size
    lo, hi = pos - padding, pos + s + padding
    if (lo < 0).any() or (hi[:, 0] > w).any() or (hi[:, 1] > h).any():
        return False
    occupied = np.zeros((h, w), np.uint8)
    for (x0, y0), (x1, y1) in zip(lo, hi):           # a loop over rectangles, not texels
        if occupied[y0:y1, x0:x1].any():
            return False
        occupied[y0:y1, x0:x1] = 1
    return True


def best_time(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def measure(sizes, padding, block_align, repeat):
    s = np.asarray(sizes, np.int64).reshape(-1, 2)
    texels = int((s[:, 0] * s[:, 1]).sum())
    t_one, (pos, size) = best_time(lambda: skyline_one_width(s, padding), repeat)
    one = dict(seconds=t_one, size=size, occupancy=texels / (size[0] * size[1]),
               exact=check(pos, s, size, padding))
    t_sky, (pos, size) = best_time(lambda: skyline(s, padding), repeat)
    sky = dict(seconds=t_sky, size=size, occupancy=texels / (size[0] * size[1]),
               exact=check(pos, s, size, padding))
    t_xa, (pos, size, exact) = best_time(lambda: xatlas_pack(s, padding, block_align), repeat)
    ok = exact and check(pos, s, size, padding)
    if block_align:
        ok = ok and not (pos % PROBE_BLOCK).any()
    xa = dict(seconds=t_xa, size=size, occupancy=texels / (size[0] * size[1]), exact=ok)
    return len(s), texels, one, sky, xa


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=None)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    try:
        import xatlas  # noqa: F401
    except ImportError:
        print("SKIP: xatlas is not installed (pip install -r bench/requirements.txt)")
        return 0
    import quality_scenes

    scenes = args.scenes or ["demo", *quality_scenes.SCENES]
    print(f"{'':33}{'skyline, one width':^24}  {'skyline (ours)':^24}  {'xatlas':^24}")
    print(f"{'scene':9} {'atlas':8} {'rects':>5} {'texels':>8}  "
          + "  ".join([f"{'size':>11} {'occ':>6} {'ms':>5}"] * 3) + f"  {'occ x/s':>7} {'ms x/s':>6}")
    ratios = []
    for name in scenes:
        try:
            cards, lighting = card_sets(name)
        except Exception as exc:   # e.g. 'imported' without ../shared/meshes
            print(f"{name:9} skipped: {type(exc).__name__}: {exc}")
            continue
        from lumen_gi.lumen_addon.atlas import PADDING
        for label, sizes, padding, align in (("cards", cards, PADDING, False),
                                             ("lighting", lighting, 0, True)):
            if not sizes:
                continue
            n, texels, one, sky, xa = measure(sizes, padding, align, args.repeat)

            def cell(r):
                size = f"{r['size'][0]}x{r['size'][1]}" + ("" if r["exact"] else "!")
                return f"{size:>11} {r['occupancy']:6.1%} {r['seconds'] * 1e3:5.1f}"
            occ_ratio = xa["occupancy"] / sky["occupancy"]
            time_ratio = xa["seconds"] / sky["seconds"]
            ratios.append((occ_ratio, time_ratio, xa["exact"], sky["occupancy"] / one["occupancy"]))
            print(f"{name:9} {label:8} {n:5d} {texels:8d}  {cell(one)}  {cell(sky)}  {cell(xa)}  "
                  f"{occ_ratio:7.3f} {time_ratio:6.2f}")
    if ratios:
        occ = np.array([r[0] for r in ratios])
        tim = np.array([r[1] for r in ratios])
        gain = np.array([r[3] for r in ratios])
        print(f"\n(! marks an inexact packing.) xatlas / ours: occupancy geometric mean "
              f"{np.exp(np.log(occ).mean()):.3f} (range {occ.min():.3f}-{occ.max():.3f}), packing "
              f"time geometric mean {np.exp(np.log(tim).mean()):.2f} (range {tim.min():.2f}-"
              f"{tim.max():.2f}); xatlas exact in {sum(r[2] for r in ratios)} of {len(ratios)} "
              f"atlases. Ours / one width: occupancy geometric mean "
              f"{np.exp(np.log(gain).mean()):.3f} (range {gain.min():.3f}-{gain.max():.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
