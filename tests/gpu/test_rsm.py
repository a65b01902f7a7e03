"""GI Method RSM (gpu_shaders/rsm.py; llvmpipe through bpy) against numerical integrals.

A floor (albedo 0.5) and a wall (a plane at x = -1, |y| <= 1.5, 0 <= z <= 2, facing +x, albedo
(0.8, 0.4, 0.2)), lit by one light at a time; black world, so the only indirect light on the floor
is the wall's one bounce (floor texels are coplanar with the floor pixels: they add nothing).
- Sun: the wall's radiance is rho E_sun cos_w / pi everywhere, and E at a floor point x is the
  integral over the wall of L cos_x cos_w / d^2 (midpoint rule in numpy, here). The RSM_FLUX view
  shows each texel's reflected radiance: exactly that of the wall or of the floor.
- Spot, point (a cube of six maps), area (one-sided, I0 cos): the wall's irradiance varies as
  I cos / r^2 from the light; the same integral with it (tests the perspective maps' texel solid
  angles), with more frames and a wider per-pixel band for the wide maps (FRAMES, BAND).
E_indirect = pi x Diffuse Indirect; the RSM ignores occlusion, and nothing occludes here. The
viewport (view_draw, one gather per redraw into its history) converges to the F12 image.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64
RES = 256
WALL = dict(x=-1.0, half_y=1.5, height=2.0, albedo=(0.8, 0.4, 0.2))
SUN = dict(direction=(-1.0, 0.3, -0.8), strength=3.0)
SPOT = dict(location=(1.5, 0.2, 1.0), power=800.0, size_deg=120.0)
# frames of 256 samples per light type, and the per-pixel band 90% of the pixels keep to: an
# area light's map is 160 degrees wide, so the wall lies far from a floor pixel's own texel,
# where the paper's sampling pattern is sparse
FRAMES = dict(SUN=8, SPOT=8, POINT=4, AREA=32)
BAND = dict(SUN=0.15, SPOT=0.15, POINT=0.15, AREA=0.25)

SNIPPET = f"""
import math
import mathutils
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 0.0, 0.0))
floor = bpy.context.object
floor.data.materials.append(principled("Floor", (0.5, 0.5, 0.5)))
bpy.ops.mesh.primitive_plane_add(size=1.0, location=({WALL['x']}, 0.0, {WALL['height'] / 2}))
wall = bpy.context.object
wall.rotation_euler = (0.0, math.pi / 2, 0.0)             # the plane's normal +z -> +x
wall.scale = ({WALL['height']}, {2 * WALL['half_y']}, 1.0)
wall.data.materials.append(principled("Wall", {WALL['albedo']!r}))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
cam = aimed_camera((3.5, -2.5, 2.5), (0.2, 0.0, 0.0))
cam.data.lens = 30.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.gi_method = "RSM"
scene.lumen.engine.rsm_resolution = {RES}
scene.lumen.engine.rsm_samples = 256
scene.lumen.engine.render_frames = 8
res, err = bake()
assert err is None, err

def light(kind):
    data = bpy.data.lights.new(kind, kind)
    obj = link(bpy.data.objects.new(kind, data))
    if kind == "SUN":
        data.energy = {SUN['strength']}
        data.angle = 0.0
        d = mathutils.Vector({SUN['direction']!r})
    else:
        data.energy = {SPOT['power']}
        obj.location = {SPOT['location']!r}
        if kind == "AREA":
            data.size = 0.05
        else:
            data.shadow_soft_size = 0.0
        if kind == "SPOT":
            data.spot_size = math.radians({SPOT['size_deg']})
            data.spot_blend = 0.0
        d = mathutils.Vector(({WALL['x']}, 0.0, 1.0)) - obj.location
    obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()
    return obj

out = {{}}
for kind in ("SUN", "SPOT", "POINT", "AREA"):
    obj = light(kind)
    # the spot's wide map puts the wall far from the floor's own texels: a noisier estimate
    scene.lumen.engine.render_frames = {FRAMES!r}[kind]
    bpy.context.view_layer.update()
    out[kind + "_axis"] = list(-obj.matrix_world.col[2].xyz.normalized())
    for view in ("COMBINED", "RSM_FLUX"):
        scene.lumen.engine.debug_view = view
        bpy.ops.render.render()
        R = engine.LAST_RENDER
        assert "error" not in R, R.get("traceback", R.get("error"))
        if view == "COMBINED":
            np.save(kind + "_indirect.npy", R["indirect"])
            np.save("position.npy", R["position"])
            np.save("normal.npy", R["normal"])
            out[kind] = dict(method=R["gi_method"], notes=R["notes"], memory=R["gpu_bytes"],
                             gi=R["gi_timings"], frame=R["frame_seconds"])
        else:
            np.save(kind + "_flux.npy", R["shown"])
    if kind == "SUN":          # the viewport: one gather per redraw into its history
        import viewport_harness
        scene.lumen.engine.debug_view = "COMBINED"
        scene.lumen.engine.viewport_quality = "LOW"
        vp = viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 10,
                                  lambda i: list(engine.LAST_RENDER["gi_progress"]))
        out["viewport"] = vp["after"]
        np.save("viewport_indirect.npy", engine.LAST_RENDER["indirect"])
    bpy.data.objects.remove(obj)
emit(**out)
"""


def wall_grid(n=300):
    """Midpoints (y, z) and the area of each cell of the wall."""
    gy = (np.arange(n) + 0.5) / n * 2 * WALL["half_y"] - WALL["half_y"]
    gz = (np.arange(n) + 0.5) / n * WALL["height"]
    y, z = np.meshgrid(gy, gz)
    return y, z, (2 * WALL["half_y"] / n) * (WALL["height"] / n)


def floor_irradiance(points, radiance_of) -> np.ndarray:
    """E at floor points [N, 3] (normal +z) from the wall whose radiance at (y, z) is
    radiance_of(y, z) (per rgb channel: [..., 3]): sum of L cos_x cos_w / d^2 dA."""
    y, z, da = wall_grid()
    L = radiance_of(y, z)
    out = np.empty((len(points), 3))
    for i, p in enumerate(points):          # per floor point, vectorised over the wall
        vx = p[0] - WALL["x"]
        d2 = vx * vx + (p[1] - y) ** 2 + z * z
        g = vx * z / (d2 * d2)               # cos_w cos_x / d^2 = (vx / d)(z / d) / d^2
        out[i] = (L * g[..., None]).sum(axis=(0, 1)) * da
    return out


def check(kind, tmp, result, radiance_of, maps=1):
    ind = np.load(tmp / f"{kind}_indirect.npy")[..., :3] * np.pi
    pos = np.load(tmp / "position.npy")
    nrm = np.load(tmp / "normal.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(nrm[..., 2]) > 0.99) & (np.abs(pos[..., 2]) < 1e-3)
    near = floor & (pos[..., 0] > WALL["x"] + 0.3) & (pos[..., 0] < 1.5) & \
        (np.abs(pos[..., 1]) < WALL["half_y"] - 0.5)
    assert near.sum() >= 150, near.sum()
    want = floor_irradiance(pos[near][:, :3].astype(np.float64), radiance_of)
    got = ind[near]
    ratio = got / want
    mean = got.mean(0) / want.mean(0)
    print(f"{kind}: {near.sum()} floor px, E / integral mean {mean}, per pixel (r) p5 "
          f"{np.percentile(ratio[:, 0], 5):.3f} p50 {np.median(ratio[:, 0]):.3f} p95 "
          f"{np.percentile(ratio[:, 0], 95):.3f}; E_r {want[:, 0].min():.4f}.."
          f"{want[:, 0].max():.4f}; {result[kind]['gi']}, frame {result[kind]['frame']:.2f} s")
    assert result[kind]["method"] == "RSM"
    assert not [n for n in result[kind]["notes"] if "GI Method" in n], result[kind]["notes"]
    assert np.all(np.abs(mean - 1.0) < 0.03)
    assert (np.abs(ratio - 1.0) < BAND[kind]).mean() > 0.9
    assert np.all(ind[floor & (pos[..., 0] < WALL["x"] - 0.1)] < 1e-6)   # behind the wall
    mem = result[kind]["memory"]
    assert mem["rsm_flux"] == mem["rsm_position"] == mem["rsm_normal"] == maps * RES * RES * 16
    assert mem["rsm_depth"] == maps * RES * RES * 4
    return ind, pos


def test_rsm_one_bounce_of_each_light_type_matches_the_integral(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    r = run.result
    rho = np.array(WALL["albedo"])
    d = np.array(SUN["direction"]) / np.linalg.norm(SUN["direction"])
    np.testing.assert_allclose(r["SUN_axis"], d, atol=1e-6)
    cos_w, cos_f = -d[0], -d[2]
    sun_l = rho * SUN["strength"] * cos_w / np.pi
    check("SUN", tmp_path, r, lambda y, z: np.broadcast_to(sun_l, y.shape + (3,)))

    # the viewport's history converges to the F12 image (both averages of 8 gathers)
    sun, pos = np.load(tmp_path / "SUN_indirect.npy"), np.load(tmp_path / "position.npy")
    vp = np.load(tmp_path / "viewport_indirect.npy")
    lit = (pos[..., 3] > 0.5) & (sun[..., 0] > 0.01)
    print(f"viewport: E / F12 {vp[lit].mean() / sun[lit].mean():.4f}, progress {r['viewport']}")
    assert r["viewport"][0] == [1, 8] and r["viewport"][-1] == [8, 8]
    assert abs(vp[lit][:, :3].mean() / sun[lit][:, :3].mean() - 1.0) < 0.02

    # RSM_FLUX: each texel's radiance, exactly that of the wall or of the floor
    flux = np.load(tmp_path / "SUN_flux.npy")[..., :3].reshape(-1, 3)
    lit = flux[flux.sum(-1) > 0]
    floor_l = 0.5 * SUN["strength"] * cos_f / np.pi
    is_wall = np.abs(lit / sun_l - 1.0).max(-1) < 1e-4
    is_floor = np.abs(lit / floor_l - 1.0).max(-1) < 1e-4
    print(f"RSM_FLUX: {len(lit)} px, wall {is_wall.sum()}, floor {is_floor.sum()}")
    assert is_wall.sum() > 100 and is_floor.sum() > 100 and np.all(is_wall | is_floor)

    s = np.array(SPOT["location"])

    def radiance(kind):
        axis = np.array(r[kind + "_axis"])
        intensity = SPOT["power"] / (np.pi if kind == "AREA" else 4 * np.pi)  # lights.py units

        def of(y, z):
            v = np.stack([np.full_like(y, WALL["x"]), y, z], -1) - s     # light -> wall point
            r2 = (v * v).sum(-1)
            cos_l = (v @ axis) / np.sqrt(r2)
            if kind == "SPOT":
                assert cos_l.min() > np.cos(np.radians(SPOT["size_deg"] / 2))  # all in the cone
            i = intensity * (np.maximum(cos_l, 0.0) if kind == "AREA" else 1.0)
            e = i * (-v[..., 0]) / np.sqrt(r2) / r2                         # I cos_w / r^2
            return rho * e[..., None] / np.pi
        return of

    check("SPOT", tmp_path, r, radiance("SPOT"))
    check("POINT", tmp_path, r, radiance("POINT"), maps=6)             # a cube of six maps
    check("AREA", tmp_path, r, radiance("AREA"))
