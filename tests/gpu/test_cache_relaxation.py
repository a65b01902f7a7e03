"""The F12 surface cache's over-relaxation (GISettings.cache_relax, surface_cache_indirect.comp.glsl):
with it, a closed room of albedo rho emitting Le gets nearer the geometric series
Le / (1 - rho) in the same iterations, and where light rings between two close facing white
plates (a mode whose update flips sign every iteration, which plain over-relaxation would grow),
the per-texel guard keeps the result where plain bounces put it."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import dataclasses
import mathutils
from lumen_gi.gpu_shaders import engine, gi_settings

RELAX = {"w": 1.0}
original = gi_settings.from_scene
gi_settings.from_scene = lambda s, viewport=False: dataclasses.replace(
    original(s, viewport), cache_relax=RELAX["w"])

def camera(location, target, lens=18.0):
    cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
    bpy.context.scene.camera = cam
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = lens

def slab(name, size, loc, mat):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=loc)
    ob = bpy.context.object
    ob.name = name
    ob.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    ob.data.materials.append(mat)

def render(w):
    RELAX["w"] = w
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    return R["combined"][..., :3].mean(axis=-1), R["position"][..., 3] > 0.5

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
w_ = bpy.data.worlds.new("World")
scene.world = w_
w_.use_nodes = True
w_.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 40
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 2
scene.lumen.engine.bounces = 6
scene.lumen.engine.converge_bounces = False   # the same iterations with and without relaxation
out = {}
if MODE == "room":
    mat = principled("Wall", (0.8, 0.8, 0.8), emission=(1.0, 1.0, 1.0), strength=0.2)
    half, t = (1.5, 1.2, 1.0), 0.2
    for axis in range(3):
        for sign in (-1.0, 1.0):
            size = [2 * h + 2 * t for h in half]
            size[axis] = t
            loc = [0.0, 0.0, 0.0]
            loc[axis] = sign * (half[axis] + t / 2)
            slab(f"Wall{axis}{sign}", size, loc, mat)
    camera((-1.2, -0.9, -0.3), (1.0, 0.6, 0.1))
else:
    # two white plates 0.3 m apart, only one of them glowing: the light rings between them
    glow = principled("Glow", (0.95, 0.95, 0.95), emission=(1.0, 1.0, 1.0), strength=1.0)
    white = principled("White", (0.95, 0.95, 0.95))
    slab("A", (2.0, 2.0, 0.1), (0.0, 0.0, -0.2), glow)
    slab("B", (2.0, 2.0, 0.1), (0.0, 0.0, 0.2), white)
    camera((2.6, 0.0, 0.0), (0.0, 0.0, 0.0), lens=35.0)
res, err = bake()
assert err is None, err
for name, w in (("plain", 1.0), ("relaxed", 1.5)):
    lum, hit = render(w)
    np.save(name + ".npy", lum)
    np.save("hit.npy", hit)
emit(ok=True)
"""


def _run(tmp_path, mode):
    run = run_python(f"MODE = {mode!r}\n" + SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    hit = np.load(tmp_path / "hit.npy")
    return np.load(tmp_path / "plain.npy")[hit], np.load(tmp_path / "relaxed.npy")[hit]


def test_relaxation_brings_a_closed_room_nearer_the_geometric_series(tmp_path):
    plain, relaxed = _run(tmp_path, "room")
    # Le = 0.2, rho = 0.8: L = 1.0 (combined = albedo * E / pi + Le = L)
    print(f"closed room: plain {plain.mean():.4f}, relaxed {relaxed.mean():.4f} (L = 1)")
    assert relaxed.mean() <= 1.03                    # no overshoot past the fixed point
    assert abs(1.0 - relaxed.mean()) < 0.75 * abs(1.0 - plain.mean())


def test_light_ringing_between_close_plates_does_not_grow(tmp_path):
    plain, relaxed = _run(tmp_path, "plates")
    print(f"plates: plain {plain.mean():.4f} (max {plain.max():.3f}), "
          f"relaxed {relaxed.mean():.4f} (max {relaxed.max():.3f})")
    assert np.isfinite(relaxed).all()
    assert relaxed.mean() <= 1.15 * plain.mean() + 1e-3
    assert relaxed.max() <= 1.5 * plain.max() + 1e-3
