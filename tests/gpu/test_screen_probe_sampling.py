"""Importance-sampled screen-probe rays (gpu_shaders/glsl/screen_probe_rays.comp.glsl,
screen_probe_compose.comp.glsl) through F12 renders of the LUMEN_GI engine (llvmpipe, bpy in a
subprocess). ScreenProbes.gather is wrapped to read back every frame's gather (tests only).

- Furnace: a sphere of albedo 0 emitting L = 1 under a sky of L = 1: every probe ray sees L, so
  every interpolated pixel's E is pi L, frame by frame (screen_probe_sh projects the probe's mean
  exactly). With importance sampling (from the second frame: culled and supersampled texels)
  it stays pi L and equal to uniform rays' E within 1e-4.
- One bright patch above a floor, black sky: the mean over the probes' 16-frame jitter cycle of
  the gathered E agrees with the brute-force per-pixel gather (GI gather PIXEL, 256 cosine rays
  per pixel per frame) and with uniform rays', and the frame-to-frame variance of E is lower
  than with uniform rays (the same probes, jitter and frames).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

COMMON = """
import dataclasses
import mathutils
from lumen_gi.gpu_shaders import engine, gi_settings, compute, screen_probes

CFG = {}
FRAMES = []
_settings = gi_settings.from_scene
gi_settings.from_scene = lambda s, viewport=False: dataclasses.replace(_settings(s, viewport), **CFG)
_gather = screen_probes.ScreenProbes.gather
def _wrapped(self, *args, **kw):
    out = _gather(self, *args, **kw)
    plan = compute.read(self.textures["plan"])[..., 0] if self.sampled else None
    FRAMES.append(dict(E=compute.read(out), sampled=self.sampled,
                       kinds=None if plan is None else np.bincount(
                           np.rint(plan).astype(int).ravel(), minlength=3).tolist()))
    return out
screen_probes.ScreenProbes.gather = _wrapped
_pixel = screen_probes.pixel_gather
def _pixel_wrapped(*args, **kw):
    out = _pixel(*args, **kw)
    FRAMES.append(dict(E=compute.read(out), sampled=False, kinds=None))
    return out
screen_probes.pixel_gather = _pixel_wrapped

def render(size, frames, **cfg):
    CFG.clear()
    CFG.update(cfg)
    FRAMES.clear()
    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.lumen.engine.render_quality = "LOW"
    scene.lumen.engine.render_frames = frames
    scene.lumen.engine.bounces = 1
    scene.lumen.engine.converge_bounces = False   # the iterations this test counts
    scene.lumen.engine.noise_threshold = 0.0
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    return np.stack([f["E"] for f in FRAMES]), [f["sampled"] for f in FRAMES], \
        [f["kinds"] for f in FRAMES]

def camera(location, target, lens=18.0):
    cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
    bpy.context.scene.camera = cam
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = lens

def world(colour):
    w = bpy.data.worlds.new("World")
    bpy.context.scene.world = w
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
"""

# an emitting sphere of albedo 0 under a sky of L = 1: every probe ray sees L = 1
FURNACE_SCENE = """
scene = empty_scene(voxel_density=24.0, cache_dir="cache")
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.6)
bpy.context.object.data.materials.append(principled("Ball", (0.0, 0.0, 0.0), emission=(1, 1, 1),
                                                    strength=1.0))
world((1.0, 1.0, 1.0))
camera((0.0, -3.0, 0.8), (0.0, 0.0, 0.0), lens=50.0)
res, err = bake()
assert err is None, err
"""

FURNACE = COMMON + FURNACE_SCENE + """
out = {}
for name, imp in (("uniform", False), ("importance", True)):
    E, sampled, kinds = render(48, 3, probe_importance=imp)
    np.save(name + ".npy", E)
    out[name] = dict(sampled=sampled, kinds=kinds)
emit(**out)
"""

PATCH = COMMON + """
scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
bpy.context.object.data.materials.append(principled("Floor", (0.5, 0.5, 0.5)))
bpy.ops.mesh.primitive_plane_add(size=0.4, location=(0.3, 0.4, 1.0), rotation=(3.14159265, 0, 0))
bpy.context.object.data.materials.append(principled("Patch", (0.0, 0.0, 0.0), emission=(1, 1, 1),
                                                    strength=25.0))
world((0.0, 0.0, 0.0))
camera((0.0, -2.2, 1.6), (0.0, 0.2, 0.0), lens=28.0)
res, err = bake()
assert err is None, err
out = {}
for name, cfg in (("uniform", dict(probe_importance=False, probe_tile=8)),
                  ("importance", dict(probe_importance=True, probe_tile=8)),
                  ("pixel", dict(gather="PIXEL", pixel_rays=256))):
    E, sampled, kinds = render(48, 17 if name != "pixel" else 2, **cfg)
    np.save(name + ".npy", E)
    out[name] = dict(sampled=sampled, kinds=kinds)
emit(**out)
"""


def test_furnace_stays_exact(tmp_path):
    run = run_python(FURNACE, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    r = run.result
    assert r["uniform"]["sampled"] == [False] * 3
    assert r["importance"]["sampled"] == [False, True, True]
    kinds = r["importance"]["kinds"][1]
    assert kinds[1] > 0 and kinds[2] >= 4 * kinds[1] // 4 > 0, kinds   # supersampled and culled
    uni = np.load(tmp_path / "uniform.npy")
    imp = np.load(tmp_path / "importance.npy")
    inter = uni[..., 3] > 0.5                   # interpolated pixels (not fallback, not sky)
    assert inter.mean() > 0.1
    assert (imp[..., 3] == uni[..., 3]).all()
    print(kinds, np.abs(imp[..., :3][inter] / np.pi - 1).max(),
          np.abs(uni[..., :3][inter] / np.pi - 1).max())
    for frame in range(3):
        e = imp[frame][..., :3][inter[frame]] / np.pi
        # the probes' SH is exact for a constant L; a pixel whose interpolation weights sum to
        # between 0.99 and 1 (probe_interp_lib.glsl) is that much below
        assert (np.abs(e - 1.0) <= 1e-4).mean() >= 0.99, np.percentile(e, [0, 1, 50, 99, 100])
        assert np.abs(e - 1.0).max() <= 0.011
    np.testing.assert_allclose(imp[..., :3][inter], uni[..., :3][inter], atol=1e-4)


def test_bright_patch_less_variance_same_mean(tmp_path):
    run = run_python(PATCH, tmp_path, timeout=1200)
    assert run.returncode == 0, run.explain()
    r = run.result
    assert r["importance"]["sampled"] == [False] + [True] * 16
    # frame 0 is uniform in both; frames 1-16: the probes' whole 16-frame jitter cycle
    uni = np.load(tmp_path / "uniform.npy")[1:]
    imp = np.load(tmp_path / "importance.npy")[1:]
    ref = np.load(tmp_path / "pixel.npy").mean(axis=0)
    floor = (uni[0, ..., 3] > 0.5) & (imp[0, ..., 3] > 0.5)
    assert floor.mean() > 0.3
    lum = lambda e: e[..., :3].mean(axis=-1)
    var_u = lum(uni).var(axis=0)[floor].mean()
    var_i = lum(imp).var(axis=0)[floor].mean()
    m_ref = lum(ref)[floor].mean()
    m_u, m_i = lum(uni).mean(axis=0)[floor].mean(), lum(imp).mean(axis=0)[floor].mean()
    print(r["importance"]["kinds"], "var ratio", var_i / var_u, "means", m_ref, m_u, m_i)
    assert var_i < 0.7 * var_u
    assert abs(m_i - m_ref) <= 0.1 * m_ref
    # no farther from the per-pixel reference than uniform rays are (their mean carries the
    # probes' own interpolation bias: -19% here at this commit, -13% when this test was written)
    assert abs(m_i - m_ref) <= abs(m_u - m_ref) + 0.02 * m_ref


BOXES = COMMON + """
gi_settings.MIN_PROBES_ACROSS = 4      # keep 16 px tiles at 64 px (the density rule would halve them)
scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
bpy.context.object.data.materials.append(principled("Floor", (0.6, 0.6, 0.6)))
for i, (x, y, s) in enumerate(((-0.5, 0.2, 0.5), (0.4, -0.2, 0.3), (0.6, 0.7, 0.6))):
    bpy.ops.mesh.primitive_cube_add(size=s, location=(x, y, s / 2))
    bpy.context.object.data.materials.append(principled("Box%d" % i, (0.7, 0.3, 0.2)))
world((0.8, 0.9, 1.0))
camera((0.3, -2.6, 1.4), (0.1, 0.2, 0.2), lens=30.0)
res, err = bake()
assert err is None, err
out = {}
for name, cfg in (("fallback", dict(adaptive_probes=False)), ("adaptive", dict(adaptive_probes=True)),
                  ("pixel", dict(gather="PIXEL", pixel_rays=256))):
    E, sampled, kinds = render(64, 4, **cfg)       # the same cache bounces in all three
    np.save(name + ".npy", E)
emit(done=True)
"""


def test_adaptive_probes_replace_fallback_rays(tmp_path):
    """Boxes on a floor at 64 px (16 px tiles: silhouettes and box sides the uniform probes do
    not interpolate): adaptive probes serve most of the pixels that traced fallback rays, and
    their E agrees with the brute-force per-pixel gather as well as the fallback rays' did."""
    run = run_python(BOXES, tmp_path, timeout=1200)
    assert run.returncode == 0, run.explain()
    fb = np.load(tmp_path / "fallback.npy")
    ad = np.load(tmp_path / "adaptive.npy")
    ref = np.load(tmp_path / "pixel.npy").mean(axis=0)[..., :3].mean(axis=-1)
    surface = fb[0, ..., 3] >= 0
    share_before = (fb[..., 3] == 0)[:, surface].mean()
    share_after = (ad[..., 3] == 0)[:, surface].mean()
    adaptive = (ad[..., 3] == 0.5)[:, surface].mean()
    print("fallback share", share_before, "->", share_after, "adaptive", adaptive)
    assert share_before > 0.05
    assert share_after <= 0.6 * share_before
    assert adaptive > 0.3 * share_before
    # the pixels that traced fallback rays before and take adaptive probes now (every frame)
    moved = (fb[..., 3] == 0).all(axis=0) & (ad[..., 3] == 0.5).all(axis=0)
    assert moved.sum() >= 20
    e_fb = fb[..., :3].mean(axis=(0, -1))[moved].mean()
    e_ad = ad[..., :3].mean(axis=(0, -1))[moved].mean()
    e_ref = ref[moved].mean()
    print("moved pixels", moved.sum(), "E ref", e_ref, "fallback rays", e_fb, "adaptive", e_ad)
    assert abs(e_ad - e_ref) <= max(0.15 * e_ref, 1.2 * abs(e_fb - e_ref))


CONVEX = COMMON + """
scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_cube_add(size=1.0)
bpy.context.object.data.materials.append(principled("Box", (0.8, 0.8, 0.8)))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.5, 0.3, 0.0)
world((0.0, 0.0, 0.0))
camera((1.6, -2.4, 1.5), (0.0, 0.0, 0.0), lens=50.0)
res, err = bake()
assert err is None, err
E, sampled, kinds = render(48, 4)
np.save("convex.npy", E)
emit(direct=float(np.asarray(engine.LAST_RENDER["direct"])[..., :3].max()))
"""


def test_a_convex_object_under_a_black_sky_gets_no_indirect_light(tmp_path):
    """A lone sunlit cube under a black world sees nothing but the black sky from any of its
    faces: E_indirect is 0 everywhere (Cycles: exactly 0). The probes' rays below their own
    surface hit that lit surface; projected into the SH with the rest of the sphere they came
    back through the SH's ringing (an unlit face beside a lit one, ~1% of its light, speckled:
    the rims of the benchmark's Cornell box, SSIM 0.95). screen_probe_sh projects the hemisphere
    above the probe only (below it: the mean above)."""
    run = run_python(CONVEX, tmp_path, timeout=900)
    assert run.returncode == 0, run.explain()
    E = np.load(tmp_path / "convex.npy")
    surface = E[0, ..., 3] >= 0
    assert surface.mean() > 0.15
    e = E[..., :3].max(axis=-1)[:, surface]
    direct_e = np.pi * run.result["direct"]         # Diffuse Direct is E / pi
    print("max E", e.max(), "mean E", e.mean(), "direct E", direct_e)
    assert direct_e > 1.0
    assert e.max() <= 1e-4 * direct_e


LIVE = COMMON + """
ATLAS = []
_gather_live = screen_probes.ScreenProbes.gather
def _atlas(self, *args, **kw):
    out = _gather_live(self, *args, **kw)
    t = self.textures
    ATLAS.append(dict(info=compute.read(t["info"]), radiance=compute.read(t["radiance"]),
                      listed=compute.read_counter(t["probe_counter"]), res=self.res,
                      uniform=self.grid))
    return out
screen_probes.ScreenProbes.gather = _atlas
""" + FURNACE_SCENE + """
render(48, 2, probe_importance=False)
for k, a in enumerate(ATLAS):
    np.save(f"info{k}.npy", a["info"])
    np.save(f"radiance{k}.npy", a["radiance"])
emit(listed=[a["listed"] for a in ATLAS], res=ATLAS[0]["res"], uniform=list(ATLAS[0]["uniform"]))
"""


def test_only_the_live_probes_are_traced_and_all_of_them(tmp_path):
    """screen_probe_list: the probe trace runs one invocation per ray of a live probe slot (the
    atlas, sized for every adaptive probe there could be, is mostly empty; on llvmpipe an
    invocation that returns at once cost nearly what a traced one does). Furnace (every ray sees
    L = 1): every texel of every live slot holds L = 1 and a hit distance > 0 (a texel the
    compact dispatch missed would hold the cleared 0), every texel of an empty slot w = -1 (no
    probe), and the list counted exactly the live slots, adaptive ones among them."""
    run = run_python(LIVE, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    r = run.result
    res, (gw, gh) = r["res"], r["uniform"]
    assert len(r["listed"]) == 2
    for k, listed in enumerate(r["listed"]):
        info = np.load(tmp_path / f"info{k}.npy")
        rad = np.load(tmp_path / f"radiance{k}.npy")
        ah, aw = info.shape[:2]
        live = info[..., 3] > 0
        assert listed == int(live.sum())
        assert 0 < live.mean() < 0.5, live.mean()          # mostly empty: what the list skips
        assert live[gh:].any()                               # adaptive probes are traced too
        texels = rad.reshape(ah, res, aw, res, 4).transpose(0, 2, 1, 3, 4)   # [slot y, x, ty, tx]
        assert (texels[live][..., 3] > 0).all()
        assert np.abs(texels[live][..., :3] - 1.0).max() < 1e-4
        assert (texels[~live][..., 3] == -1.0).all()
