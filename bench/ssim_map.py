"""Where an engine's SSIM is lost: per-pixel SSIM maps against the Cycles reference, split by
the kind of pixel, for engines whose EXRs `bench/quality.py --keep-exr` left in its output.

    .venv/bin/python bench/ssim_map.py --out OUT [--scenes cornell,textured] [--engines lumen,eevee]
        [--png]

The map is quality.py's SSIM before its mean (the same tone map, exposure and 11x11 Gaussian
window), so its mean is the table's SSIM. It is the product of a luminance term l (local means)
and a contrast-structure term cs (local variances and covariance); which of them drops tells a
wrong brightness from missing or extra detail and noise. Pixels are classed from the reference
(Depth) and the lumen EXR's G-buffer passes (Normal, Diffuse Color), which every engine is
compared on, so all engines share one classification:

    dark      surfaces the reference shows (almost) black: tone-mapped luminance under 0.05,
              where SSIM's luminance term turns any light into a loss (c1 = 1e-4: 0.03 against
              0 scores l = 0.1)
    edge      a depth jump (> 3% between 4-neighbours) or the silhouette of the background within
              2 px: anti-aliasing and geometric edges
    crease    a normal change over 25 degrees within 2 px (no depth jump): concave corners and
              contact, where the bounce and the SDF occlusion are hardest
    texture   the albedo varies (max - min of the 5x5 Diffuse Color luminance over 10% of its
              mean) on a smooth surface: texture detail
    bright    the reference's tone-mapped luminance over 0.9: emitters and light-source shapes
    flat      the rest: smooth surfaces, where noise and speckle show
    background  no surface in the reference (Depth >= 1e9) and not within 1 px of one

Per class: its share of the pixels, the mean SSIM of each engine, and the class's part of the
gap to a comparison engine (sum over its pixels of the SSIM difference / all pixels: the parts
add up to the difference of the table's SSIMs). `noise` (the two half-sample references against
each other) is the ceiling the reference's own noise allows. Local std ratio: the mean over a
class of the engine's local standard deviation (Gaussian window) over the reference's: < 1 is
smoother than the reference (lost detail, or the reference's noise not reproduced), > 1 is extra
detail or speckle. --png writes <out>/ssim_<scene>.png: the SSIM maps side by side (white 1,
black <= 0.5) and the class map.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402  (the bench's own tone map, blur and EXR reader)

CLASSES = ("dark", "edge", "crease", "texture", "bright", "flat", "background")


def ssim_terms(x, ref):
    """Per-pixel (ssim, l, cs) maps exactly as quality.ssim computes its mean."""
    exposure = 0.5 / max(float(quality.lum(ref).mean()), 1e-6)
    a, b = quality.lum(quality.tone_map(x, exposure)), quality.lum(quality.tone_map(ref, exposure))
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    blur = quality._gauss_blur
    ma, mb = blur(a), blur(b)
    va = blur(a * a) - ma * ma
    vb = blur(b * b) - mb * mb
    cov = blur(a * b) - ma * mb
    l_term = (2 * ma * mb + c1) / (ma * ma + mb * mb + c1)
    cs = (2 * cov + c2) / (va + vb + c2)
    return l_term * cs, l_term, cs, np.sqrt(np.maximum(va, 0)), np.sqrt(np.maximum(vb, 0))


def _grow(mask, r):
    """Dilate a boolean mask by r pixels (square)."""
    out = mask.copy()
    h, w = mask.shape
    p = np.pad(mask, r)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= p[r + dy:r + dy + h, r + dx:r + dx + w]
    return out


def _range(img, r):
    """(min, max) over a (2r+1)^2 window, edges clamped."""
    h, w = img.shape
    p = np.pad(img, r, mode="edge")
    stack = [p[r + dy:r + dy + h, r + dx:r + dx + w] for dy in range(-r, r + 1)
             for dx in range(-r, r + 1)]
    return np.min(stack, 0), np.max(stack, 0)


def classify(ref, depth, normal, albedo) -> np.ndarray:
    """int [h, w]: an index into CLASSES per pixel (the first class that applies, in order)."""
    h, w = ref.shape[:2]
    d = depth[..., 0] if depth is not None else np.ones((h, w))
    bg = d >= 1e9
    dd = np.minimum(d, 1e3)
    jump = np.zeros((h, w), bool)
    for axis in (0, 1):
        a, b = np.take(dd, range(0, dd.shape[axis] - 1), axis), np.take(dd, range(1, dd.shape[axis]), axis)
        j = np.abs(a - b) > 0.03 * np.minimum(a, b)
        pad = [(0, 0), (0, 0)]
        pad[axis] = (0, 1)
        jump |= np.pad(j, pad)
        pad[axis] = (1, 0)
        jump |= np.pad(j, pad)
    edge = _grow(jump, 1)
    n = normal[..., :3].astype(np.float64)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
    crease = np.zeros((h, w), bool)
    r = 2
    p = np.pad(n, ((r, r), (r, r), (0, 0)), mode="edge")
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            q = p[r + dy:r + dy + h, r + dx:r + dx + w]
            crease |= (n * q).sum(-1) < np.cos(np.radians(25.0))
    valid = np.linalg.norm(normal[..., :3], axis=-1) > 0.5
    lo_valid, _ = _range(valid.astype(np.float64), r)
    crease &= ~edge & valid & (lo_valid > 0.5)
    al = quality.lum(albedo)
    lo, hi = _range(al, 2)
    texture = (hi - lo > 0.1 * np.maximum(al, 1e-3)) & ~edge & ~crease & ~bg
    exposure = 0.5 / max(float(quality.lum(ref).mean()), 1e-6)
    tone = quality.lum(quality.tone_map(ref, exposure))
    bright = tone > 0.9
    dark = (tone < 0.05) & ~bg
    background = bg & ~edge
    cls = np.full((h, w), CLASSES.index("flat"), np.int8)
    for name, m in (("bright", bright), ("texture", texture), ("crease", crease), ("edge", edge),
                    ("dark", dark), ("background", background)):
        cls[m] = CLASSES.index(name)
    return cls


def load_ref(out: Path, scene: str):
    """(reference image, depth, the two halves) from quality.py's cache in `out`."""
    metas = sorted(out.glob(f"ref_{scene}_*.json"), key=lambda p: p.stat().st_mtime)
    if not metas:
        raise FileNotFoundError(f"no ref_{scene}_*.json in {out}")
    info = json.loads(metas[-1].read_text())
    passes = [quality.read_exr(out / f) for f in info["files"]]
    weights = [s["samples"] for s in info["settings"]]
    imgs = [p["Combined"][..., :3].astype(np.float64) for p in passes]
    ref = sum(wt * im for wt, im in zip(weights, imgs)) / sum(weights)
    return ref, passes[0].get("Depth"), imgs


def analyse(out: Path, scene: str, engines, png=False) -> dict:
    ref, depth, halves = load_ref(out, scene)
    images, aux = {}, None
    for eng in engines:
        p = out / f"{scene}_{eng}.exr"
        if p.exists():
            passes = quality.read_exr(p)
            images[eng] = np.nan_to_num(passes["Combined"][..., :3].astype(np.float64))
            if "Normal" in passes and "Diffuse Color" in passes:
                aux = passes
    if aux is None:
        raise FileNotFoundError(f"{scene}: no kept lumen EXR (Normal, Diffuse Color) in {out}")
    cls = classify(ref, depth, aux["Normal"], aux["Diffuse Color"])
    maps = {eng: ssim_terms(img, ref) for eng, img in images.items()}
    if len(halves) == 2:
        maps["noise"] = ssim_terms(halves[0], halves[1])
    res = dict(scene=scene, share={c: float((cls == i).mean()) for i, c in enumerate(CLASSES)},
               engines={})
    for eng, (s, l_term, cs, sd_x, sd_ref) in maps.items():
        per = {}
        for i, c in enumerate(CLASSES):
            m = cls == i
            if not m.any():
                continue
            per[c] = dict(ssim=float(s[m].mean()), l=float(l_term[m].mean()),
                          cs=float(cs[m].mean()), part=float(s[m].sum() / s.size),
                          std_ratio=float(sd_x[m].mean() / sd_ref[m].mean()) if sd_ref[m].mean() > 1e-3 else float("nan"))
        res["engines"][eng] = dict(ssim=float(s.mean()), classes=per)
    if png:
        write_png(out / f"ssim_{scene}.png", [maps[e][0] for e in maps], cls)
    return res


def write_png(path: Path, maps, cls):
    import OpenImageIO as oiio

    tiles = [np.repeat(np.clip((m - 0.5) / 0.5, 0, 1)[..., None], 3, -1) for m in maps]
    colours = np.array([(0.6, 0.1, 0.8), (1, 0.2, 0.2), (1, 0.8, 0.1), (0.2, 0.5, 1), (1, 1, 1),
                        (0.3, 0.3, 0.3), (0, 0, 0)])
    tiles.append(colours[cls])
    canvas = np.concatenate(tiles, 1).astype(np.float32)
    buf = oiio.ImageBuf(np.ascontiguousarray(canvas))
    out = oiio.ImageBuf()
    oiio.ImageBufAlgo.copy(out, buf, oiio.UINT8)
    out.write(str(path))


def report(res: dict, base: str, against: str):
    say = quality.say
    e = res["engines"]
    say(f"\n[{res['scene']}] SSIM " + ", ".join(f"{k} {v['ssim']:.4f}" for k, v in e.items()))
    if base not in e or against not in e:
        return
    say(f"{'class':8s} {'share':>6s} | {'SSIM ' + base:>12s} {'l':>6s} {'cs':>6s} {'std':>5s} | "
        f"{'SSIM ' + against:>12s} {'l':>6s} {'cs':>6s} {'std':>5s} | {'gap part':>8s} | "
        f"{'noise':>6s}")
    for c in CLASSES:
        if c not in e[base]["classes"]:
            continue
        a, b = e[base]["classes"][c], e[against]["classes"][c]
        nz = e.get("noise", {}).get("classes", {}).get(c, {}).get("ssim")
        say(f"{c:8s} {res['share'][c]:6.1%} | {a['ssim']:12.4f} {a['l']:6.3f} {a['cs']:6.3f} "
            f"{a['std_ratio']:5.2f} | {b['ssim']:12.4f} {b['l']:6.3f} {b['cs']:6.3f} "
            f"{b['std_ratio']:5.2f} | {b['part'] - a['part']:+8.4f} | "
            f"{'-' if nz is None else format(nz, '6.3f')}")
    say(f"{'total':8s} {'':6s} | {e[base]['ssim']:12.4f} {'':20s} | {e[against]['ssim']:12.4f} "
        f"{'':20s} | {e[against]['ssim'] - e[base]['ssim']:+8.4f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", required=True, help="quality.py's --out, run with --keep-exr")
    ap.add_argument("--scenes", default="cornell,textured,imported,window")
    ap.add_argument("--engines", default="lumen,eevee,eevee_rt,eevee_volume")
    ap.add_argument("--base", default="lumen", help="the engine whose loss is explained")
    ap.add_argument("--against", default="best",
                    help="the engine to compare with (best: the other engine of highest SSIM)")
    ap.add_argument("--png", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    engines = [e for e in args.engines.split(",") if e]
    results = []
    for scene in [s for s in args.scenes.split(",") if s]:
        try:
            res = analyse(out, scene, engines, args.png)
        except FileNotFoundError as exc:
            quality.say(f"[{scene}] skipped: {exc}")
            continue
        against = args.against
        if against == "best":
            others = {k: v["ssim"] for k, v in res["engines"].items()
                      if k not in (args.base, "noise")}
            against = max(others, key=others.get) if others else args.base
        report(res, args.base, against)
        results.append(res)
    (out / "ssim_map.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
