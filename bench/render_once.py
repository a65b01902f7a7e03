"""Benchmark helper: one F12 render per bench/quality_scenes scene from THIS checkout, its Combined
saved as <out>/<scene>.npy and its wall, CPU and per-pass CPU seconds as <out>/<scene>.json.

Why: bench/f12_ab.py swaps only the GLSL folder inside one process; a change that also touches
the Python (a new pass, a new dispatch) is compared by running this from two git worktrees
(the old main and the change) and comparing the two folders: the images exactly (the engine is
deterministic) and the seconds over alternated rounds (the machine is shared).

    git worktree add /tmp/old main~1 && ln -s $PWD/.venv /tmp/old/.venv
    (cd /tmp/old && .venv/bin/python bench/render_once.py /tmp/ab/old cornell,window,thin 128)
    .venv/bin/python bench/render_once.py /tmp/ab/new cornell,window,thin 128
    .venv/bin/python bench/render_once.py --compare /tmp/ab/new /tmp/ab/old

Settings after the size (FIELD=VALUE, scene.lumen.engine's; bools 0/1) apply to every scene:
    .venv/bin/python bench/render_once.py /tmp/ab/new cornell 128 screen_trace=1

Each render follows a 32x32 warm-up of the same scene (shader compilation). `imported` and
`textured` need LUMEN_SHARED_MESHES (../shared/meshes).
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]


def apply_settings(scene, items) -> None:
    """FIELD=VALUE strings set on scene.lumen.engine (the value converted to the property's
    type: bool from 0/1)."""
    for item in items:
        field, _, value = item.partition("=")
        current = getattr(scene.lumen.engine, field)
        setattr(scene.lumen.engine, field, type(current)(int(value)) if isinstance(current, bool)
                else type(current)(value))


def render(out: str, scenes: list, size: int, settings=()) -> None:
    import demo
    import numpy as np

    import f12_ab

    addon = demo.load_addon()
    engine = addon.gpu_shaders.engine
    engine.KEEP_IMAGES = True
    Path(out).mkdir(parents=True, exist_ok=True)
    for name in scenes:
        with tempfile.TemporaryDirectory() as tmp:
            scene = f12_ab.baked_scene(name, tmp)
            apply_settings(scene, settings)
            wall, cpu, passes = f12_ab.warm_then_time(scene, size)
            R = engine.LAST_RENDER
            if "error" in R:
                raise SystemExit(f"{name}: {R.get('traceback', R['error'])}")
            np.save(f"{out}/{name}.npy", np.asarray(R["combined"], np.float32))
            with open(f"{out}/{name}.json", "w") as f:
                json.dump(dict(wall=wall, cpu=cpu, passes=dict(passes)), f, indent=1)
            top = sorted(passes.items(), key=lambda kv: -kv[1])[:5]
            print(f"{name}: wall {wall:.2f} s, CPU {cpu:.2f} s;",
                  ", ".join(f"{k} {v:.2f}" for k, v in top), flush=True)


def compare(a: str, b: str) -> None:
    """Per scene in both folders: relative squared difference and mean ratio of the images,
    wall and CPU seconds of each."""
    import numpy as np

    for f in sorted(Path(a).glob("*.npy")):
        g = Path(b) / f.name
        if not g.exists():
            continue
        x, y = np.load(f)[..., :3], np.load(g)[..., :3]
        rel = float(((x - y) ** 2).mean() / max(float((y ** 2).mean()), 1e-12))
        ja = json.loads(f.with_suffix(".json").read_text())
        jb = json.loads(g.with_suffix(".json").read_text())
        print(f"{f.stem}: image rel diff {rel:.2e}, mean ratio {x.mean() / max(y.mean(), 1e-12):.4f}; "
              f"wall {ja['wall']:.2f} / {jb['wall']:.2f} s, CPU {ja['cpu']:.2f} / {jb['cpu']:.2f} s")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--compare":
        compare(sys.argv[2], sys.argv[3])
    elif len(sys.argv) >= 4 and "=" not in "".join(sys.argv[1:4]):
        render(sys.argv[1], [s for s in sys.argv[2].split(",") if s], int(sys.argv[3]),
               sys.argv[4:])
    else:
        raise SystemExit(__doc__)
