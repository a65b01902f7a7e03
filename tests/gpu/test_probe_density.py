"""Screen-probe density on a small image (gi_settings.probe_tile_for) against a closed form.

A 0.5 x 0.5 m emissive square (radiance Le = 2, black base colour) hangs 0.8 m above a white
(albedo 0.8) 10 x 10 m floor under a black world, no lights: the floor's irradiance is the
square's alone, E(x) = Le * integral over the square of cos(theta) cos(theta') / d^2 (numpy,
40 x 40 sub-squares), a peak under the square that falls to a tenth within about 1 m. The
engine's Diffuse Indirect pass (E / pi) on the floor, at 128 x 128 px, is compared with it at
the floor pixels within 0.5 m of the peak (E falls by half there), once with the probe tile of
the image size rule (8 px: 16 probes across) and once with the preset's 16 px
(MIN_PROBES_ACROSS = 0: 8 probes across, the rule's absence). Measured: relative L1 error
0.143 with 8 px, 0.296 with 16 px (the peak 39% low: a probe 16 px away stands for it). The
test wants the denser probes within 20% and at most 0.6x the sparse ones' error; the tiles
reported must be 8 and 16. (Farther out, 0.5-1.6 m, both are about 30% below the closed form:
light from an emitter at grazing angles is lost somewhere else in the engine; left alone here.)
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

LE, SIDE, HEIGHT = 2.0, 0.5, 0.8

SNIPPET = f"""
from lumen_gi.gpu_shaders import engine, gi_settings

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0.0, 0.0, 0.0))
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
bpy.ops.mesh.primitive_plane_add(size={SIDE}, location=(0.0, 0.0, {HEIGHT}))
bpy.context.object.data.materials.append(principled("Panel", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0), strength={LE}))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
aimed_camera((0.0, -2.6, 2.2), (0.0, 0.3, 0.0)).data.lens = 24.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 128
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 4
scene.lumen.engine.bounces = 1
res, err = bake()
assert err is None, err
tiles = []
for rule in (16, 0):
    gi_settings.MIN_PROBES_ACROSS = rule
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(f"indirect_{{rule}}.npy", R["indirect"])
    np.save("position.npy", R["position"])
    tiles.append(R["gi_probe_tile"])
emit(tiles=tiles)
"""


def closed_form(points):
    """E at floor points (N, 3) from the square (Lambertian emitter, radiance LE), numerically."""
    n = 40
    c = (np.arange(n) + 0.5) / n * SIDE - SIDE / 2
    qx, qy = np.meshgrid(c, c)
    q = np.stack([qx.ravel(), qy.ravel(), np.full(n * n, HEIGHT)], 1)        # (M, 3)
    d = q[None] - points[:, None, :]                                         # (N, M, 3)
    d2 = (d ** 2).sum(-1)
    cos_r = d[..., 2] / np.sqrt(d2)          # floor normal +z
    cos_e = d[..., 2] / np.sqrt(d2)          # emitter normal -z, facing the floor
    return LE * (cos_r * cos_e / d2).sum(1) * (SIDE / n) ** 2


def test_denser_probes_follow_an_irradiance_peak(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    assert run.result["tiles"] == [8, 16]
    pos = np.load(tmp_path / "position.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(pos[..., 2]) < 0.02) & (np.hypot(pos[..., 0], pos[..., 1]) < 0.5)
    expected = closed_form(pos[floor][:, :3].astype(np.float64)) / np.pi     # Diffuse Indirect
    errs = {}
    for rule in (16, 0):
        got = np.load(tmp_path / f"indirect_{rule}.npy")[..., :3].mean(-1)[floor]
        errs[rule] = float(np.abs(got - expected).sum() / expected.sum())
        print(f"MIN_PROBES_ACROSS {rule}: {floor.sum()} floor px, relative L1 {errs[rule]:.4f}, "
              f"mean {got.mean():.4f} vs {expected.mean():.4f}")
    assert floor.sum() >= 300
    assert errs[16] < 0.2
    assert errs[16] < 0.6 * errs[0]
