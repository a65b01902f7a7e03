"""The surface cache on the GPU (gpu_shaders/surface_cache.py, llvmpipe in a bpy subprocess) against
exact answers: card texel world positions against the numpy twin, and direct sun light per texel
against the closed form E = E_sun * max(0, n.L) with an exact ray-box shadow test.

Scene: a 4 x 4 x 0.1 m floor (top at z = 0) and a 0.6 m box on it, 16 voxels/m, 20 texels/m, one
sun. Texels whose shadow ray passes within MARGIN of the box's surface (the penumbra of a cone
trace through an SDF of 6 cm voxels) or that lie within MARGIN of the box (contact) are left out;
the rest must match: lit within 2% of the closed form, shadowed below 2% of E_sun.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender"), str(HERE.parent / "core")]

from blender_runner import run_python  # noqa: E402

E_SUN = 3.0
SUN_DIR = np.array([-1.0, -0.5, -0.6]) / np.linalg.norm([-1.0, -0.5, -0.6])   # where light goes
BOX_MIN, BOX_MAX = np.array([-0.3, -0.3, 0.0]), np.array([0.3, 0.3, 0.6])
MARGIN = 0.15

SNIPPET = f"""
import traceback
sys.path.insert(0, {str(HERE.parent / 'core')!r})
from shapes import box, matrix
from lumen_gi.lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_gi.gpu_shaders.resources import SceneResources, float_buffer
from lumen_gi.gpu_shaders.surface_cache import SurfaceCache
from lumen_gi.gpu_shaders.card_packing import card_texel_world
import gpu

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
bake = bake_scene([ObjectInput("Floor", *box((2.0, 2.0, 0.05)), matrix((0.0, 0.0, -0.05))),
                   ObjectInput("Box", *box((0.3, 0.3, 0.3)), matrix((0.0, 0.0, 0.3)))],
                  BakeSettings(voxel_density=16.0, texel_density=20.0))
ERRORS, OUT = [], {{}}

class SCTestEngine(bpy.types.RenderEngine):
    bl_idname = "LUMEN_SC_TEST"
    bl_label = "Surface cache test"
    bl_use_gpu_context = True
    def render(self, depsgraph):
        try:
            res = SceneResources.from_bake(bake)
            sc = SurfaceCache(bake.atlas, [i.cards for i in bake.instances])
            row = np.zeros(16, np.float32)
            row[4:7] = {list(SUN_DIR)}
            row[7] = 0.0093
            row[8:11] = {E_SUN}
            lights = gpu.types.GPUTexture((4, 1), format='RGBA32F', data=float_buffer(row))
            sc.light_direct(res, lights, 1)
            twin = card_texel_world(sc.packed, bake.atlas.layers,
                                    [i.matrix_world for i in bake.instances])
            np.savez("sc.npz", direct=sc.read("direct"), position=sc.read_layer(res, "position"),
                     normal=sc.read_layer(res, "normal"), albedo=sc.read_layer(res, "albedo"),
                     twin_position=twin["position"], twin_normal=twin["normal"],
                     twin_albedo=twin["albedo"], twin_valid=twin["valid"])
            # combine over tiles: the sun doubled everywhere, combined on half the tiles only
            sc.combine(res)
            final_a = sc.read("final")
            half = np.arange(0, len(sc.pages), 2)
            tiles = (half, np.ones(len(half)))
            row[8:11] = {2 * E_SUN}
            lights2 = gpu.types.GPUTexture((4, 1), format='RGBA32F', data=float_buffer(row))
            sc.light_direct(res, lights2, 1)
            sc.combine(res, tiles)
            np.savez("combine.npz", a=final_a, b=sc.read("final"), direct=sc.read("direct"),
                     tiles=sc.pages.tiles[half])
            OUT["stats"] = sc.stats()
            OUT["lighting_size"] = list(sc.packed.lighting_size)
            OUT["rows"] = sc.packed.rows
        except Exception:
            ERRORS.append(traceback.format_exc())
        r = self.begin_result(0, 0, 4, 4)
        self.end_result(r)

bpy.utils.register_class(SCTestEngine)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
scene.camera = cam
scene.render.engine = "LUMEN_SC_TEST"
scene.render.resolution_x = scene.render.resolution_y = 4
bpy.ops.render.render()
assert not ERRORS, ERRORS[0]
emit(**OUT)
"""


def ray_box(o, d, lo, hi):
    """Slab test: does the ray o + t d (t > 0) meet the box [lo, hi]? (vectorised over rows)"""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0, t1 = (lo - o) * inv, (hi - o) * inv
    tmin = np.nanmax(np.minimum(t0, t1), axis=1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=1)
    return tmax >= np.maximum(tmin, 0.0)


def box_distance(p, lo, hi):
    return np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)


def test_card_texels_and_direct_sun(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=120)
    assert run.returncode == 0, run.explain()
    d = np.load(tmp_path / "sc.npz")
    valid = d["twin_valid"]
    assert valid.sum() > 2000
    gpu_valid = d["position"][..., 3] > 0.5
    np.testing.assert_array_equal(gpu_valid, valid)
    np.testing.assert_allclose(d["position"][valid][:, :3], d["twin_position"][valid], atol=1e-4)
    np.testing.assert_allclose(d["normal"][valid][:, :3] * 2 - 1, d["twin_normal"][valid], atol=1e-4)
    np.testing.assert_allclose(d["albedo"][valid][:, :3], d["twin_albedo"][valid], atol=2e-3)

    p, n = d["twin_position"][valid], d["twin_normal"][valid]
    E = d["direct"][valid][:, :3].mean(axis=1)
    to_sun = -SUN_DIR
    cos = np.maximum(n @ to_sun, 0.0)
    o = p + n * 1e-4
    lo, hi = BOX_MIN + MARGIN, BOX_MAX - MARGIN
    sure_shadow = ray_box(o, np.broadcast_to(to_sun, o.shape), lo, hi) & (cos > 0)
    sure_lit = ~ray_box(o, np.broadcast_to(to_sun, o.shape), BOX_MIN - MARGIN, BOX_MAX + MARGIN)
    # the box's own faces (the floor under the box faces into the box: it is neither)
    on_box = (box_distance(p, BOX_MIN, BOX_MAX) < 1e-3) & (box_distance(p + 2e-3 * n, BOX_MIN, BOX_MAX) > 1e-3)
    under = (box_distance(p, BOX_MIN, BOX_MAX) < 1e-3) & ~on_box
    near_box = box_distance(p, BOX_MIN, BOX_MAX) < MARGIN
    sure_lit |= on_box & (cos > 0)          # the box's own sunny faces
    keep = ~(near_box & ~on_box) & ~under
    lit, shadow = sure_lit & keep & (cos > 0.05), sure_shadow & keep
    assert lit.sum() > 1000 and shadow.sum() > 50, (lit.sum(), shadow.sum())
    expect = E_SUN * cos
    good_lit = np.abs(E[lit] - expect[lit]) <= 0.02 * expect[lit] + 1e-3
    assert good_lit.mean() >= 0.99, (good_lit.mean(), np.percentile(np.abs(E[lit] - expect[lit]), 99))
    good_dark = E[shadow] <= 0.02 * E_SUN
    assert good_dark.mean() >= 0.99, good_dark.mean()
    back = keep & (n @ to_sun < -0.05)
    assert np.all(E[back] == 0.0)
    deep = under & np.all(np.abs(p[:, :2]) < 0.3 - MARGIN, axis=1)   # a voxel's blur from the sides
    assert deep.sum() > 10 and np.all(E[deep] <= 0.02 * E_SUN)     # the floor under the box is dark

    # combine(tiles): final light recomputed on those tiles' texels only, in place
    c = np.load(tmp_path / "combine.npz")
    mask = np.zeros(valid.shape, bool)
    for tx, ty in c["tiles"]:
        mask[ty * 32:(ty + 1) * 32, tx * 32:(tx + 1) * 32] = True
    assert (mask & valid).sum() > 500 and (~mask & valid).sum() > 500
    np.testing.assert_array_equal(c["b"][~mask], c["a"][~mask])       # the others untouched
    albedo = d["albedo"][..., :3]
    expect = c["direct"][..., :3] * albedo / np.pi                    # no emission, no indirect
    lit = mask & valid & (c["direct"][..., :3].max(axis=-1) > 0.1)
    assert lit.sum() > 300
    np.testing.assert_allclose(c["b"][lit][:, :3], expect[lit], rtol=2e-3, atol=1e-5)
    assert np.all(c["b"][lit][:, :3].mean(axis=1) > 1.9 * c["a"][lit][:, :3].mean(axis=1))
    print(run.result)
