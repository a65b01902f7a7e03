"""Global illumination of the LUMEN_GI engine (llvmpipe, F12 through bpy) against closed forms.

- Energy conservation of the bounce: inside a closed room whose walls all have albedo rho and
  emit radiance Le, every surface converges to L = Le / (1 - rho) (the geometric series of
  bounces), whatever the room's shape. rho = 0.5, Le = 0.5 -> L = 1. An F12 render with B
  surface-cache bounces plus the screen-probe gather holds B + 2 terms of the series:
  1 - rho^(B + 2) of L (B = 8: 0.999).
- White furnace: a convex object (a sphere) of albedo rho under a uniform sky L_sky sees only
  the sky, so its radiance is rho * L_sky everywhere (rho = 0.8, L_sky = 1).
Images are saved in the test's folder (combined.npy) for inspection.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

COMMON = """
import mathutils
from lumen_gi.gpu_shaders import engine

def finish(size, quality="LOW", frames=4, bounces=8):
    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.lumen.engine.render_quality = quality
    scene.lumen.engine.render_frames = frames
    scene.lumen.engine.bounces = bounces
    res, err = bake()
    assert err is None, err
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save("combined.npy", R["combined"])
    np.save("indirect.npy", R["indirect"])
    np.save("position.npy", R["position"])
    return R

def camera(location, target, lens=18.0):
    cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
    bpy.context.scene.camera = cam
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = lens
    return cam

def world(colour):
    w = bpy.data.worlds.new("World")
    bpy.context.scene.world = w
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
"""

ROOM_SCENE = """
scene = empty_scene(voxel_density=10.0, cache_dir="cache")
mat = principled("Wall", (0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0), strength=0.5)
closed_room(mat)
world((0.0, 0.0, 0.0))
camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
R = finish(48)
"""

ROOM = COMMON + ROOM_SCENE + """
emit(gi=R["gi_timings"], iterations=R["gi_iterations"])
"""

FURNACE = COMMON + """
scene = empty_scene(voxel_density=24.0, cache_dir="cache")
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.6)
ball = bpy.context.object
ball.data.materials.append(principled("Ball", (0.8, 0.8, 0.8)))
world((1.0, 1.0, 1.0))
camera((0.0, -3.0, 0.8), (0.0, 0.0, 0.0), lens=50.0)
R = finish(48, frames=4, bounces=2)
emit(gi=R["gi_timings"])
"""


def test_closed_room_converges_to_the_geometric_series(tmp_path):
    run = run_python(ROOM, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    img = np.load(tmp_path / "combined.npy")[..., :3]
    lum = img.mean(axis=-1)
    expected = 0.5 / (1.0 - 0.5) * (1.0 - 0.5 ** 10)
    print(run.result, lum.mean(), np.percentile(lum, [1, 5, 50, 95, 99]))
    assert abs(lum.mean() - expected) <= 0.03 * expected
    assert (np.abs(lum - expected) <= 0.1 * expected).mean() >= 0.95


def test_white_furnace_sphere(tmp_path):
    run = run_python(FURNACE, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    img = np.load(tmp_path / "combined.npy")[..., :3]
    hit = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    lum = img.mean(axis=-1)
    assert hit.mean() > 0.2
    print(run.result, lum[hit].mean(), np.percentile(lum[hit], [1, 5, 50, 95, 99]))
    np.testing.assert_allclose(lum[~hit], 1.0, atol=1e-6)          # the sky itself
    assert abs(lum[hit].mean() - 0.8) <= 0.02 * 0.8
    assert (np.abs(lum[hit] - 0.8) <= 0.05 * 0.8).mean() >= 0.95


ROOM_LOD = COMMON + """
import dataclasses
from lumen_gi.gpu_shaders import compute, gi_settings, surface_cache
_settings = gi_settings.from_scene
# the coarsest ray LOD everywhere: every radiosity probe traces one row (4) of its 16 rays
gi_settings.from_scene = lambda s, viewport=False: dataclasses.replace(_settings(s, viewport),
                                                                       sc_lod_rays=1e-6)
TRACED = []
_light = surface_cache.SurfaceCache.light_indirect

def light_indirect(self, *args, **kw):
    k = _light(self, *args, **kw)
    rays = compute.read(self.probe_textures["rays"])[..., 3]
    probes = compute.read(self.probe_textures["probes"])[..., 3] > 0.5
    h, w = probes.shape
    slots = rays[:h * 4, :w * 4].reshape(h, 4, w, 4).transpose(0, 2, 1, 3)[probes]
    TRACED.append(float((slots > 0.0).mean()))
    return k

surface_cache.SurfaceCache.light_indirect = light_indirect
""" + ROOM_SCENE + """
emit(traced=TRACED)
"""


def test_ray_lod_keeps_the_closed_room_series(tmp_path):
    """The surface cache's ray LOD (gi.sc_ray_lod) forced to its coarsest: each radiosity probe
    traces one row of 4 of its 16 rays, and the SH pass divides by the rays it used, so the
    closed room still converges to Le / (1 - rho) (a divisor of 16 would leave it 4x short)."""
    run = run_python(ROOM_LOD, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    traced = run.result["traced"]
    assert traced and all(t == 0.25 for t in traced), traced
    lum = np.load(tmp_path / "combined.npy")[..., :3].mean(axis=-1)
    expected = 0.5 / (1.0 - 0.5) * (1.0 - 0.5 ** 10)
    print(lum.mean(), np.percentile(lum, [1, 5, 50, 95, 99]))
    assert abs(lum.mean() - expected) <= 0.03 * expected
    assert (np.abs(lum - expected) <= 0.1 * expected).mean() >= 0.9


SEEDS = COMMON + """
from lumen_gi.gpu_shaders.screen_probes import ScreenProbes
JITTER = [[]]        # per render: every gather's (tile offset, ray jitter)
_jitter = ScreenProbes.jitter

def jitter(self, frame):
    tile, ray = _jitter(self, frame)
    JITTER[-1].append(np.concatenate([np.asarray(tile, float), np.asarray(ray, float)]))
    return tile, ray

ScreenProbes.jitter = jitter
""" + ROOM_SCENE + """
np.save("seed0.npy", R["indirect"])
for seed in (1, 0):
    bpy.context.scene.lumen.engine.seed = seed
    JITTER.append([])
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if seed == 1:
        np.save("seed1.npy", R["indirect"])
np.save("jitter.npy", np.array(JITTER))
emit(ok=True)
"""


def test_seed_changes_only_the_noise(tmp_path):
    """Seed (Cycles' Seed): another seed's F12 takes other jitter sequences, so its image differs
    pixel by pixel, by noise only: the closed room's indirect light has the same mean."""
    run = run_python(SEEDS, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    a = np.load(tmp_path / "seed0.npy")[..., :3].mean(-1)
    b = np.load(tmp_path / "seed1.npy")[..., :3].mean(-1)
    diff = np.abs(a - b)
    print("seed 0 / 1 mean:", a.mean(), b.mean(), "max |diff|:", diff.max(), "mean:", diff.mean())
    assert diff.max() > 1e-4 * a.mean()              # other sequences, another noise
    assert abs(a.mean() - b.mean()) <= 0.01 * a.mean()
    # the screen probes' rays too: their jitter sets repeat every 16 frames and seeds are
    # SEED_FRAMES apart, so seed 1 traced seed 0's ray sets (one frame later) until each seed
    # got its own shift
    seed0, seed1, seed0_again = np.load(tmp_path / "jitter.npy")     # [gathers, tile xy + ray xy]
    print("probe jitter (tile xy, ray xy), seed 0:", seed0, "seed 1:", seed1)
    assert np.array_equal(seed0, seed0_again)
    shared = np.abs(seed1[:, None, 2:] - seed0[None, :, 2:]).max(-1).min(-1) < 1e-6
    assert not shared.any(), f"{shared.sum()} of seed 1's {len(seed1)} ray sets are seed 0's"
