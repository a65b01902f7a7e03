"""Benchmark: two of bench/quality.py's engines A/B against Cycles under several F12 seeds.

Runs quality.py once per seed (`--lumen-seed N --keep-exr`, its Cycles references rendered by
the first run and reused by the others) and prints per scene the paired relMSE change B / A - 1
of every seed, its mean and standard error, and the relMSE of the seed-averaged images (their
noise averaged away: what is left is the two versions' bias).
Why: one seed's paired change is mostly noise. An F12's screen probes put the light into
probe-sized blotches that move with the seed, and changing a few rays (the screen trace first)
moves them, so bench/quality.py's relMSE changes by up to +-4% per seed either way (glow, 128 px)
while the seed-averaged change is under 1%. Seeds 0, 1, 2 once looked consistent because they
shared their screen-probe rays (gpu_shaders/screen_probes.py: ScreenProbes.jitter).

    .venv/bin/python bench/seed_ab.py [--a lumen] [--b lumen_screen] [--seeds 0-5]
                                      [--scenes cornell,window] [--size 128]
                                      [--cycles-samples 512] [--out /tmp/seed_ab]
"""
from __future__ import annotations

import argparse
import glob
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

from quality import EPS, read_exr  # noqa: E402
from quality_scenes import SCENES  # noqa: E402


def seeds_arg(text: str) -> list:
    """'0-5' or '0,2,7' -> [0, 1, ...]."""
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def rel_mse(x, ref):
    """quality.py's relMSE (metrics' rel_mse, without the other metrics)."""
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + EPS)))


def table(out: Path, seeds, scenes, a: str, b: str):
    """Rows (scene, [B/A - 1 per seed], relMSE of the mean images A, B) from the runs' EXRs."""
    rows = []
    for scene in scenes:
        refs = sorted(glob.glob(str(out / "refs" / f"ref_{scene}_*_s*.exr")))
        runs = [out / f"s{s}" for s in seeds]
        runs = [r for r in runs if (r / f"{scene}_{a}.exr").exists()
                and (r / f"{scene}_{b}.exr").exists()]
        if not refs or not runs:
            continue
        ref = np.mean([read_exr(Path(p))["Combined"][..., :3] for p in refs], axis=0)
        A = [read_exr(r / f"{scene}_{a}.exr")["Combined"][..., :3] for r in runs]
        B = [read_exr(r / f"{scene}_{b}.exr")["Combined"][..., :3] for r in runs]
        change = [rel_mse(y, ref) / rel_mse(x, ref) - 1.0 for x, y in zip(A, B)]
        rows.append((scene, change, rel_mse(np.mean(A, 0), ref), rel_mse(np.mean(B, 0), ref)))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", default="lumen")
    ap.add_argument("--b", default="lumen_screen")
    ap.add_argument("--seeds", type=seeds_arg, default=seeds_arg("0-5"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--cycles-samples", type=int, default=512)
    ap.add_argument("--out", type=Path, default=Path("/tmp/seed_ab"))
    ap.add_argument("--report-only", action="store_true", help="the table of runs already in --out")
    args = ap.parse_args()
    refs = args.out / "refs"
    refs.mkdir(parents=True, exist_ok=True)
    for seed in [] if args.report_only else args.seeds:
        run = args.out / f"s{seed}"
        run.mkdir(exist_ok=True)
        for ref in refs.glob("ref_*"):               # the Cycles references, rendered once
            if not (run / ref.name).exists():
                (run / ref.name).symlink_to(ref)
        print(f"seed {seed}: {run}", flush=True)
        subprocess.run([sys.executable, str(ROOT / "bench" / "quality.py"), "--size",
                        str(args.size), "--cycles-samples", str(args.cycles_samples), "--engines",
                        f"cycles_ref,{args.a},{args.b}", "--scenes", args.scenes, "--lumen-seed",
                        str(seed), "--keep-exr", "--out", str(run)],
                       check=True, stdout=subprocess.DEVNULL)
        for ref in run.glob("ref_*"):
            if not ref.is_symlink() and not (refs / ref.name).exists():
                ref.rename(refs / ref.name)
                (run / ref.name).symlink_to(refs / ref.name)
    rows = table(args.out, args.seeds, args.scenes.split(","), args.a, args.b)
    print(f"relMSE against Cycles, {args.b} / {args.a} - 1 (%), paired per seed "
          f"({', '.join(map(str, args.seeds))}); and of the seed-averaged images")
    print(f"{'scene':9s} {'per seed':44s} {'mean':>6s} {'se':>5s}   {'averaged images':s}")
    for scene, change, ra, rb in rows:
        c = np.array(change) * 100
        se = c.std(ddof=1) / np.sqrt(len(c)) if len(c) > 1 else float("nan")
        print(f"{scene:9s} {' '.join(f'{v:+.2f}' for v in c):44s} {c.mean():+6.2f} {se:5.2f}   "
              f"{ra:.6f} -> {rb:.6f} ({(rb / ra - 1) * 100:+.2f}%)")


if __name__ == "__main__":
    main()
