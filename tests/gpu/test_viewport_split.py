"""The viewport's split (GISettings.split = 4 or 16): each redraw integrates one pixel of every 2x2
(4x4) block
and screen_probe_temporal_split blends it into the history by that pixel's own sample count,
keeps the others, and fills pixels not yet integrated from this redraw's neighbours on their
plane; its first round's sample (probes partly filled) is replaced by the second's; a turn the
fallback skipped (w -2: over its budget) keeps the history as it is. Exact: per redraw the integrated pixels carry one known value and every other pixel
garbage, so any wrong turn (GLSL's Bayer order against screen_probes.split_phase), wrong count or
garbage read shows. llvmpipe, bpy in a subprocess."""
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

W, H, FRAMES, HISTORY = 13, 9, 36, 2.0
GARBAGE = 1.0e6

SNIPPET = f"""
import gpu
import numpy as np
from lumen_gi.gpu_shaders import compute
from lumen_gi.gpu_shaders.resources import float_buffer
from lumen_gi.gpu_shaders.screen_probes import ScreenProbes, split_phase

W, H = {W}, {H}
OUT = {{}}

def tex(a):
    return gpu.types.GPUTexture((W, H), format='RGBA32F', data=float_buffer(a))

def job():
  for split, step in ((4, 2), (16, 4)):
      ys, xs = np.mgrid[0:H, 0:W]
      pos = np.zeros((H, W, 4), np.float32)
      pos[..., 0], pos[..., 1], pos[..., 3] = xs * 0.01, ys * 0.01, 1.0
      pos[0, 5, 3] = 0.0                                  # a background pixel
      nor = np.zeros((H, W, 4), np.float32)
      nor[..., 2] = 1.0
      gbuf = {{"textures": {{"position": tex(pos), "normal": tex(nor)}}}}
      probes = ScreenProbes(W, H, 8, 8)
      phase = split_phase(xs, ys, step)
      shown = []
      for f in range({FRAMES}):
          new = np.full((H, W, 4), {GARBAGE}, np.float32)
          mine = phase == f % split
          new[mine] = (f + 1.0, 2.0 * f, 1.0, 1.0)
          if f >= split and (f // split) % 2 == 1:       # turns the fallback skipped: w -2
              new[mine & ((xs + ys) % 3 == 0)] = ({GARBAGE}, {GARBAGE}, {GARBAGE}, -2.0)
          out = probes.temporal_split(tex(new), gbuf, (0.0, 0.0, 5.0), split, {HISTORY})
          shown.append(compute.read(out).tolist())
      OUT[f"shown{{split}}"] = shown
      OUT[f"frames{{split}}"] = probes.frames

run_in_gpu_context(job)
emit(**OUT)
"""


def expected(split):
    """The same history in numpy: per pixel its own turns (Bayer order), a running mean
    then exponential over HISTORY, the first round's sample replaced by the second's; before its
    first turn this redraw's value (one per redraw); a skipped turn (w -2) changes nothing but
    still counts as a turn."""
    ys, xs = np.mgrid[0:H, 0:W]
    b = 2 * ((xs & 1) ^ (ys & 1)) + (ys & 1)
    if split == 16:
        b = 4 * b + 2 * (((xs >> 1) & 1) ^ ((ys >> 1) & 1)) + ((ys >> 1) & 1)
    hist = np.zeros((H, W, 2))
    count = np.zeros((H, W), int)
    out = []
    for f in range(FRAMES):
        v = np.array([f + 1.0, 2.0 * f])
        mine = b == f % split
        kept = count - 1 if f >= split else count
        blend = np.maximum(1.0 / (kept + 1), 1.0 / HISTORY)[..., None]
        sample = mine & ~((f >= split) & ((f // split) % 2 == 1) & ((xs + ys) % 3 == 0))
        hist = np.where(sample[..., None], hist * (1 - blend) + v * blend, hist)
        count = count + mine
        out.append(np.where((count > 0)[..., None], hist, v))
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = run_python(SNIPPET, tmp_path_factory.mktemp("split"), timeout=300)
    assert out.returncode == 0, out.explain()
    return out.result


@pytest.mark.parametrize("split", [4, 16])
def test_split_history_turns_counts_and_fill(run, split):
    shown = np.asarray(run[f"shown{split}"])            # [frame, y, x, rgba]
    assert run[f"frames{split}"] == FRAMES
    want = expected(split)
    bg = np.zeros((H, W), bool)
    bg[0, 5] = True
    for f in range(FRAMES):
        got = shown[f]
        assert (got[bg][:, 3] == -1.0).all() and (got[bg][:, :3] == 0.0).all()
        assert np.abs(got[~bg][..., :3]).max() < 100.0, f"frame {f}: garbage read"
        err = np.abs(got[..., :2] - want[f])[~bg].max()
        assert err < 1e-4, f"frame {f}: max error {err}"
