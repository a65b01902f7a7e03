"""F12 anti-aliasing (gpu_shaders/antialias.py, glsl/aa_resolve.comp.glsl).

- numpy: the jitters are distributed as Cycles' Blackman-Harris filter (mean 0, the filter's
  variance, inside its span: twice the Filter Size, as Cycles' film.cpp builds it); a jittered view_proj moves every point's pixel position by the
  jitter exactly; the samples' shares of the direct light's strata cover all 8 of them.
- An emissive half-plane seen by an orthographic camera with its edge through the centres of
  one pixel column (GI Off, black world): without anti-aliasing the image is a hard step (0 or
  1); with it that column is 0.5 (a symmetric filter over a symmetric jitter set) and each row's
  sum is the covered width, 16.5 pixels, exactly as the filtered step integrates.
- With GI on, in a closed emissive room, anti-aliasing keeps the mean (within 1%): the bounce is
  read back at the samples without gain or loss.
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402


def _antialias():
    """gpu_shaders/antialias.py without the package's GPU imports (its numpy part)."""
    import importlib.util
    import types

    pkg = types.ModuleType("aa_pkg")
    pkg.__path__ = [str(ROOT / "gpu_shaders")]
    sys.modules.setdefault("aa_pkg", pkg)
    for name in ("probe_math", "antialias"):
        spec = importlib.util.spec_from_file_location(f"aa_pkg.{name}",
                                                      ROOT / "gpu_shaders" / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[f"aa_pkg.{name}"] = mod
        spec.loader.exec_module(mod)
    return sys.modules["aa_pkg.antialias"]


def test_jitters_follow_the_filter():
    aa = _antialias()
    size = 1.5
    width = aa.filter_span(size)
    assert width == 3.0            # Cycles: filter_table(FILTER_BLACKMAN_HARRIS, w) doubles w
    j = aa.jitters(64, size)
    assert j.shape == (64, 2)
    assert np.abs(j).max() <= width / 2
    xs = np.linspace(-width / 2, width / 2, 20001)
    f = aa.blackman_harris(xs, width)
    var = (xs ** 2 * f).sum() / f.sum()
    np.testing.assert_allclose(j.mean(axis=0), 0.0, atol=1e-3)
    np.testing.assert_allclose(j.var(axis=0), var, rtol=0.05)
    np.testing.assert_allclose(np.sort(j[:, 0]), -np.sort(j[:, 0])[::-1], atol=1e-9)  # symmetric


def test_jitters_filter_every_edge_orientation_alike():
    """The jitters' spread is the same across edges of any orientation: Hammersley's 8 points
    (4 of them on one diagonal) spread 0.50 px across one diagonal and 0.22 px across the other;
    each axis still takes every stratum of the filter once."""
    aa = _antialias()
    for n in (4, 8, 16, 32):
        j = aa.jitters(n, 1.5)
        assert aa.anisotropy(j) < 1.15, (n, aa.anisotropy(j))
        u = aa.stratified_set(n)
        for axis in (0, 1):
            np.testing.assert_allclose(np.sort(u[:, axis]), (np.arange(n) + 0.5) / n)
    assert aa.anisotropy(aa.jitters(8, 1.5)) < 1.01
    from aa_pkg.probe_math import hammersley
    h = (hammersley(8) + 0.5 / 8) % 1.0 - 0.5
    assert aa.anisotropy(h) > 1.5                   # what the old pairing did (1.9)


def test_light_parts_cover_every_stratum():
    aa = _antialias()
    for samples, take in ((1, 8), (2, 4), (4, 2), (8, 1), (3, 2), (16, 1)):
        parts = [aa.light_part(k, samples, 8) for k in range(samples)]
        assert all(t == take for _, t in parts)
        covered = sorted({(f + i) % 8 for f, t in parts for i in range(t)})
        if samples * take >= 8:
            assert covered == list(range(8)), (samples, parts)


def test_jittered_projection_moves_pixels_by_the_jitter():
    aa = _antialias()
    rng = np.random.default_rng(3)
    f, n, w, h = 2.0, 0.1, 64, 48
    proj = np.array([[f * h / w, 0, 0.1, 0], [0, f, -0.05, 0], [0, 0, -1.0002, -0.2 * n],
                     [0, 0, -1, 0]], np.float64)
    view = np.eye(4)
    view[:3, 3] = (0.3, -0.2, -4.0)
    vp = proj @ view
    pts = np.c_[rng.uniform(-1, 1, (10, 3)), np.ones(10)]

    def pixels(m):
        c = pts @ m.T
        ndc = c[:, :2] / c[:, 3:]
        return (ndc * 0.5 + 0.5) * (w, h)

    moved = pixels(aa.jittered(vp, 0.3, -0.7, w, h))
    np.testing.assert_allclose(moved - pixels(vp), np.tile((-0.3, 0.7), (10, 1)), atol=1e-9)
    a, b = aa.footprint(vp, h)
    assert b == 0.0 and abs(a - 2.0 / (f * h)) < 1e-3 * a     # (the lens shift adds a hair)


EDGE = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0, location=(-2.0, 0.0, 0.0))   # covers x < 0
bpy.context.object.data.materials.append(principled("Glow", (0.0, 0.0, 0.0),
                                                    emission=(1.0, 1.0, 1.0), strength=1.0))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
cam = aimed_camera((-0.05, 0.0, 2.0), (-0.05, 0.0, 0.0))
cam.data.type = "ORTHO"
cam.data.ortho_scale = 3.2                   # 32 px of 0.1 m: column 16's centre is x = 0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 32
scene.render.resolution_percentage = 100
scene.render.filter_size = 1.5
scene.lumen.engine.render_quality = "OFF"
res, err = bake()
assert err is None, err
out = {}
for samples in (1, 8):
    scene.lumen.engine.aa_samples = samples
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(f"edge_{samples}.npy", R["combined"])
    out[samples] = R.get("aa_samples", 0)
emit(samples=out)
"""


def test_an_edge_through_pixel_centres_is_half_covered(tmp_path):
    run = run_python(EDGE, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    hard = np.load(tmp_path / "edge_1.npy")[..., :3].mean(-1)
    soft = np.load(tmp_path / "edge_8.npy")[..., :3].mean(-1)
    rows = slice(4, 28)                      # away from the plane's far edges (|y| < 1.2 m)
    print(run.result, np.round(soft[16, 12:21], 3))
    assert run.result["samples"]["8"] == 8
    assert set(np.unique(np.round(hard[rows], 3))) <= {0.0, 1.0}          # the staircase
    np.testing.assert_allclose(soft[rows, 16], 0.5, atol=0.02)
    np.testing.assert_allclose(soft[rows].sum(axis=1), 16.5, atol=0.05)
    assert soft[rows, 15].mean() > 0.75 and soft[rows, 17].mean() < 0.25


ROOM = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
mat = principled("Wall", (0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0), strength=0.5)
closed_room(mat)
w = bpy.data.worlds.new("World")
scene.world = w
aimed_camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1)).data.lens = 18.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 40
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 2
scene.lumen.engine.bounces = 4
res, err = bake()
assert err is None, err
for samples in (1, 4):
    scene.lumen.engine.aa_samples = samples
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(f"room_{samples}.npy", R["combined"])
    np.save(f"room_{samples}_indirect.npy", R["indirect"])
emit(aa=R.get("aa_seconds"))
"""


def test_antialiasing_keeps_the_bounce(tmp_path):
    run = run_python(ROOM, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    for kind in ("", "_indirect"):
        one = np.load(tmp_path / f"room_1{kind}.npy")[..., :3]
        four = np.load(tmp_path / f"room_4{kind}.npy")[..., :3]
        assert np.isfinite(four).all()
        print(kind, one.mean(), four.mean())
        assert abs(four.mean() - one.mean()) <= 0.01 * one.mean()
