"""The back of an open surface is surface: it emits and is lit (LUMEN_GI, llvmpipe, F12).

Cycles and EEVEE emit and shade on both sides of every face; only a closed mesh hides its backs
(its inside). A single-sided emissive quad (the panel of bench/quality.py's `glow` room, an
imported light fixture) lights what lies behind it as much as what it faces: in the glow room
the panel's back, 5 cm under the ceiling, gave 17% of the image's light in Cycles that the
surface cache (cards of front faces only) did not have.

Closed form: a black (albedo 0) square quad of radiance Le at height h, facing UP, over a floor
of albedo rho facing up, in a black world. The floor sees only the quad's back, so its radiance
is one bounce, L(x) = rho Le F(x), with F the form factor from a floor point to the parallel
rectangle above it (sum of four corner rectangles, each
f(A, B) = (A atan(B / sqrt(1 + A^2)) / sqrt(1 + A^2) + B atan(A / sqrt(1 + B^2)) / sqrt(1 + B^2))
/ (2 pi), A and B the corner's offsets over h, odd in both). Before cards captured the backs of
open faces, the floor under the quad was black.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

LE, RHO, H, HALF = 4.0, 0.5, 1.0, 0.6

SCENE = f"""
scene = empty_scene(voxel_density=20.0, cache_dir="cache")
quad = bpy.data.meshes.new("Quad")
s = {HALF}
quad.from_pydata([(-s, -s, {H}), (s, -s, {H}), (s, s, {H}), (-s, s, {H})], [], [(0, 1, 2, 3)])
quad.update()
assert quad.polygons[0].normal.z > 0.99          # facing up: the floor sees its back
quad.materials.append(principled("Glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0),
                                 strength={LE}))
link(bpy.data.objects.new("Quad", quad))
floor = cube("Floor", 1.0, (0.0, 0.0, -0.1))
floor.scale = (6.0, 6.0, 0.2)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
floor.data.materials.append(principled("Floor", ({RHO}, {RHO}, {RHO})))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
aimed_camera((1.9, -0.5, 0.9), (-0.2, 0.0, 0.0)).data.lens = 24.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 48
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 4
scene.lumen.engine.bounces = 1
scene.lumen.engine.gi_gather = "PIXEL"     # rays per pixel: the cache, no probe filter
res, err = bake()
assert err is None, err
bpy.ops.render.render()
from lumen_gi.gpu_shaders import engine
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
np.save("combined.npy", R["combined"])
np.save("position.npy", R["position"])
"""


def form_factor(x, y, h=H, half=HALF):
    """Point on the floor at (x, y) to the parallel square [-half, half]^2 at height h."""
    def f(a, b):
        A, B = a / h, b / h
        sa, sb = np.sqrt(1 + A * A), np.sqrt(1 + B * B)
        return (A / sa * np.arctan(B / sa) + B / sb * np.arctan(A / sb)) / (2 * np.pi)

    x0, x1, y0, y1 = -half - x, half - x, -half - y, half - y
    return f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0)


def test_form_factor_closed_form():
    # straight under the centre of a square of side 2a at height h: 4 corner rectangles
    a = HALF / H
    corner = 2 * a / np.sqrt(1 + a * a) * np.arctan(a / np.sqrt(1 + a * a)) / (2 * np.pi)
    assert abs(form_factor(0.0, 0.0) - 4 * corner) < 1e-12
    assert form_factor(0.0, 0.0) < 1.0 and form_factor(50.0, 0.0) < 1e-4


def test_floor_lit_by_the_back_of_an_emissive_quad(tmp_path):
    run = run_python(SCENE, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    img = np.load(tmp_path / "combined.npy")[..., :3].mean(axis=-1)
    pos = np.load(tmp_path / "position.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 0.02)
    x, y = pos[..., 0], pos[..., 1]
    under = floor & (np.abs(x) < 0.5) & (np.abs(y) < 0.5)       # under the quad, off its rim
    near = floor & ~under & (np.hypot(x, y) < 1.5)
    expected = RHO * LE * form_factor(x, y)
    print({k: (float(img[m].mean()), float(expected[m].mean()), int(m.sum()))
           for k, m in (("under", under), ("near", near))})
    assert under.sum() > 50 and near.sum() > 500
    for m in (under, near):
        assert abs(img[m].mean() / expected[m].mean() - 1.0) <= 0.08


# Near field: the same quad facing DOWN at 3 cm over the floor (0.6 of a 5 cm voxel, as a light
# panel under a ceiling). No GI ray reaches the floor beneath it or the strip around it (rays leave
# a surface a voxel off it, and the thin-wall rule closes the gap), so before
# surface_cache_lib.glsl's sc_near_emission that halo was black; Cycles lights it by the closed
# form: L = rho Le F(x, y) at h = 3 cm.
H_NEAR, HALF_NEAR = 0.03, 0.3
SCENE_NEAR = (SCENE.replace(f"(-s, -s, {H}), (s, -s, {H}), (s, s, {H}), (-s, s, {H})",
                            f"(-s, -s, {H_NEAR}), (-s, s, {H_NEAR}), (s, s, {H_NEAR}), (s, -s, {H_NEAR})")
              .replace("s = " + str(HALF), "s = " + str(HALF_NEAR))
              .replace("assert quad.polygons[0].normal.z > 0.99          # facing up: the floor sees its back",
                       "assert quad.polygons[0].normal.z < -0.99         # facing down, 3 cm over the floor")
              .replace("aimed_camera((1.9, -0.5, 0.9), (-0.2, 0.0, 0.0))",
                       "aimed_camera((0.9, -0.7, 0.8), (0.1, 0.0, 0.0))")
              .replace("resolution_y = 48", "resolution_y = 96"))


def test_floor_lit_by_an_emissive_quad_closer_than_a_voxel(tmp_path):
    assert SCENE_NEAR.count(str(H_NEAR)) == 4 and "normal.z < -0.99" in SCENE_NEAR
    assert "resolution_y = 96" in SCENE_NEAR
    run = run_python(SCENE_NEAR, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    img = np.load(tmp_path / "combined.npy")[..., :3].mean(axis=-1)
    pos = np.load(tmp_path / "position.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 0.01)
    x, y = pos[..., 0], pos[..., 1]
    out = np.maximum(np.abs(x), np.abs(y)) - HALF_NEAR          # distance outside the quad's edge
    expected = RHO * LE * form_factor(x, y, H_NEAR, HALF_NEAR)
    bins = {"0-3 cm": floor & (out > 0.0) & (out < 0.03),
            "3-8 cm": floor & (out >= 0.03) & (out < 0.08)}
    print({k: (float(img[m].mean()), float(expected[m].mean()), int(m.sum())) for k, m in bins.items()})
    for m in bins.values():
        assert m.sum() >= 10
        assert abs(img[m].mean() / expected[m].mean() - 1.0) <= 0.06
