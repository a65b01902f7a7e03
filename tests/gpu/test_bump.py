"""A Bump node (Image Texture -> Bump Height -> the Principled BSDF's Normal), against Cycles: a
floor whose height falls linearly along +x on its left half (Distance 1: a 30-degree slope of
the shading normal towards +x) and is flat on its right half, under a sun from +x and above;
pure Lambert, GI off in ours and no bounces in Cycles.

- our G-buffer's shading normal on the left half is the 30-degree normal to 2e-3 (the height's
  screen derivatives, gbuffer.glsl bumped), on the right half +z; Invert tilts it the other way;
- each half's Diffuse Direct matches Cycles' within 3%.
Before, a Bump node was left out with a warning: both halves shaded as flat.
"""
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402
from test_normal_maps import SUN_OVER_FLOOR, oct_decode, textured_floor  # noqa: E402

SIZE = 48
TILT = math.radians(30.0)
SLOPE = 4.0 * math.tan(TILT)         # height per unit of u: the plane is 4 m across

SNIPPET = textured_floor("Height", 64, 4) + f"""
u = (np.arange(64) + 0.5) / 64
h = np.where(u < 0.5, {SLOPE} * (0.5 - u), 0.0).astype(np.float32)
px[..., :3] = h[None, :, None]
img.pixels.foreach_set(px.ravel())
bump = nodes.new("ShaderNodeBump")
bump.inputs["Distance"].default_value = 1.0           # (5.0's default is 1 mm)
links.new(tex.outputs["Color"], bump.inputs["Height"])
links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
""" + SUN_OVER_FLOOR + """
R = render_lumen(save=("normal", "albedo", "emission", "position"), quality="OFF", exr="lumen.exr")
render_cycles(16, exr="cycles.exr", bounces=0)
bump.invert = True
import os
os.makedirs("inverted", exist_ok=True)
os.chdir("inverted")
render_lumen(save=("albedo", "emission"), quality="OFF")
emit(notes=R.get("notes", []))
"""


def test_bump_node_shades_the_floor_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    normal = oct_decode(np.load(tmp_path / "albedo.npy")[..., 3],
                        np.load(tmp_path / "emission.npy")[..., 3])     # the shading normal
    inverted = oct_decode(np.load(tmp_path / "inverted" / "albedo.npy")[..., 3],
                          np.load(tmp_path / "inverted" / "emission.npy")[..., 3])
    pos = np.load(tmp_path / "position.npy")
    ours = read_pass(tmp_path / "lumen.exr", "Diffuse Direct")[::-1]   # rows bottom first
    ref = read_pass(tmp_path / "cycles.exr", "Diffuse Direct")[::-1]
    tilted = np.array([math.sin(TILT), 0.0, math.cos(TILT)])
    x, y = pos[..., 0], pos[..., 1]
    floor = (pos[..., 3] > 0.5) & (np.abs(y) < 1.8)
    # away from the texture's wrap at the plane's edge and the kink at its middle
    for name, sel, want in (("left", floor & (x < -0.3) & (x > -1.7), tilted),
                            ("right", floor & (x > 0.3) & (x < 1.7), np.array([0.0, 0.0, 1.0]))):
        assert sel.sum() > 100
        print(name, "shading normal", normal[sel].mean(0), "want", want)
        np.testing.assert_allclose(normal[sel], np.tile(want, (sel.sum(), 1)), atol=2e-3)
        flipped = want * np.array([-1.0, 1.0, 1.0])
        np.testing.assert_allclose(inverted[sel], np.tile(flipped, (sel.sum(), 1)), atol=2e-3)
        a, b = ours[sel].mean(), ref[sel].mean()
        print(name, "ours", a, "cycles", b)
        assert abs(a / b - 1.0) < 0.03, (name, a, b)
