"""GI Method VXGI (gpu_shaders/vxgi.py, glsl/vxgi_cones.comp.glsl; llvmpipe through bpy).

- Sky furnace: a floor of albedo 0 under a uniform sky of radiance 1, nothing else: every cone
  sees only the sky, so E_indirect = pi (Diffuse Indirect = 1) within 2%, and the direct pass
  carries no sky light (VXGI's cones bring it: counted once). The VXGI_OCCLUSION view is black
  on the floor (no cone is stopped by the floor it starts from).
- Emitting wall: the same floor (albedo 0) beside a wall emitting Le (albedo 0), black world:
  E on the floor is Le times the wall's form factor, pi Le F(x), a numerical integral of
  cos cos / d^2 over the wall (numpy, here). Per band of distance from the wall, VXGI's mean is
  within 35% of it near the wall and 1.5-4x too high 1.5-2.5 m away (RATIO_BANDS: wide cones
  over-count a wall that only grazes them; the measured failure).
- The viewport (view_draw, 6 redraws) gets the F12 image's E on that floor within 5%.
- Cornell box (bench/quality_scenes.py, 64 px) against Cycles: VXGI's relMSE is lower than GI
  Off's (VXGI adds the missing indirect light).
- Thin walls (bench/quality_scenes.py's `thin`, walls 1.5 cm, under one SDF voxel): the leak
  (mean luminance inside the closed room / mean luminance of the lit outside) is measured and
  recorded, the lecture's known VXGI failure: LEAK_BAND says what it is today; Lumen's leak in
  the same run is lower.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 64
LE = 2.0
WALL = dict(x=-1.0, half_y=1.5, height=2.0)
# floor bands (metres from the wall) and the range VXGI's E / the integral keeps to in each:
# near the wall, where it fills the cones that see it, within 35%; farther away a 60-degree cone
# whose axis passes near the wall's edge counts it as covering most of its cross-section
# (opacity 1 - d / r), so the far floor gets 2-4x too much: the measured failure, recorded
BANDS = ((0.25, 0.5), (0.5, 1.0), (1.5, 2.5))
RATIO_BANDS = {(0.25, 0.5): (0.65, 1.35), (0.5, 1.0): (0.65, 1.35), (1.5, 2.5): (1.5, 4.0)}

FLOOR_SNIPPET = f"""
import math
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))
floor = bpy.context.object
floor.data.materials.append(principled("Floor", (0.0, 0.0, 0.0)))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
bg = w.node_tree.nodes["Background"]
bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
cam = aimed_camera((3.0, -2.5, 2.5), (0.0, 0.0, 0.0))
cam.data.lens = 30.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.gi_method = "VXGI"
scene.lumen.engine.render_frames = 2
scene.lumen.engine.bounces = 1
res, err = bake()
assert err is None, err
out = {{}}

def render(name, view="COMBINED"):
    scene.lumen.engine.debug_view = view
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    if view == "COMBINED":
        for k in ("indirect", "direct", "position", "normal"):
            np.save(f"{{name}}_{{k}}.npy", R[k])
        out[name] = dict(method=R["gi_method"], notes=R["notes"], memory=R["gpu_bytes"],
                         gi=R["gi_timings"], frame=R["frame_seconds"])
    else:
        np.save(f"{{name}}_{{view}}.npy", R["shown"])

render("furnace")
render("furnace", "VXGI_OCCLUSION")

# the emitting wall, black world
bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
bpy.ops.mesh.primitive_plane_add(size=1.0, location=({WALL['x']}, 0.0, {WALL['height'] / 2}))
wall = bpy.context.object
wall.rotation_euler = (0.0, math.pi / 2, 0.0)             # the plane's normal +z -> +x
wall.scale = ({WALL['height']}, {2 * WALL['half_y']}, 1.0)
wall.data.materials.append(principled("Wall", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0),
                                      strength={LE}))
res, err = bake()
assert err is None, err
render("wall")
# the viewport (view_draw): one VXGI gather per redraw into its history, Lumen's surface cache
# and voxel lighting updated on its own budget
import viewport_harness
scene.lumen.engine.viewport_quality = "LOW"
vp = viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 6,
                          lambda i: list(engine.LAST_RENDER["gi_progress"]))
out["viewport"] = dict(progress=vp["after"], method=engine.LAST_RENDER["gi_method"])
np.save("viewport_indirect.npy", engine.LAST_RENDER["indirect"])
emit(**out)
"""


def wall_form_factor(points, n=300) -> np.ndarray:
    """F(x) = integral over the wall of cos_x cos_w / (pi d^2) dA at floor points [N, 3]."""
    gy = (np.arange(n) + 0.5) / n * 2 * WALL["half_y"] - WALL["half_y"]
    gz = (np.arange(n) + 0.5) / n * WALL["height"]
    y, z = np.meshgrid(gy, gz)
    da = (2 * WALL["half_y"] / n) * (WALL["height"] / n)
    out = np.empty(len(points))
    for i, p in enumerate(points):          # per floor point, vectorised over the wall
        vx = p[0] - WALL["x"]
        d2 = vx * vx + (p[1] - y) ** 2 + z * z
        out[i] = (vx * z / (d2 * d2)).sum() * da / np.pi
    return out


def test_vxgi_sky_furnace_and_emitting_wall(tmp_path):
    run = run_python(FLOOR_SNIPPET, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    r = run.result
    for name in ("furnace", "wall"):
        assert r[name]["method"] == "VXGI", r[name]
        assert not [n for n in r[name]["notes"] if "GI Method" in n], r[name]["notes"]
    pos = np.load(tmp_path / "furnace_position.npy")
    nrm = np.load(tmp_path / "furnace_normal.npy")
    floor = (pos[..., 3] > 0.5) & (np.abs(nrm[..., 2]) > 0.99)
    assert floor.sum() > 0.5 * SIZE * SIZE
    ind = np.load(tmp_path / "furnace_indirect.npy")[..., :3]      # E / pi
    direct = np.load(tmp_path / "furnace_direct.npy")[..., :3]
    occl = np.load(tmp_path / "furnace_VXGI_OCCLUSION.npy")[..., 0]
    print(f"furnace: E / pi on {floor.sum()} floor px: mean {ind[floor].mean():.4f}, "
          f"min {ind[floor].min():.4f}, max {ind[floor].max():.4f}; direct max "
          f"{direct[floor].max():.2e}; occlusion max {occl[floor].max():.3f}; {r['furnace']['gi']}")
    assert np.abs(ind[floor] - 1.0).max() < 0.02
    assert direct[floor].max() < 1e-4          # the sky comes through the cones only
    assert occl[floor].max() < 0.02
    mem = r["furnace"]["memory"]
    assert mem["vxgi_cones"] == SIZE * SIZE * 16 and mem["vxgi_history"] == SIZE * SIZE * 16
    assert mem["voxel_lighting"] > 0 and not [k for k in mem if k.startswith("probes_")]

    pos = np.load(tmp_path / "wall_position.npy")
    nrm = np.load(tmp_path / "wall_normal.npy")
    ind = np.load(tmp_path / "wall_indirect.npy")[..., 0] * np.pi
    floor = (pos[..., 3] > 0.5) & (np.abs(nrm[..., 2]) > 0.99) & (np.abs(pos[..., 2]) < 1e-3)
    front = floor & (np.abs(pos[..., 1]) < WALL["half_y"] - 0.5)
    x = pos[..., 0] - WALL["x"]
    ratios = {}
    for lo, hi in BANDS:
        m = front & (x >= lo) & (x < hi)
        assert m.sum() >= 20, (lo, hi, m.sum())
        want = np.pi * LE * wall_form_factor(pos[m][:, :3].astype(np.float64))
        ratios[(lo, hi)] = ind[m].mean() / want.mean()
        print(f"wall: floor {lo}-{hi} m from it ({m.sum()} px): E {ind[m].mean():.3f}, "
              f"integral {want.mean():.3f}, ratio {ratios[(lo, hi)]:.3f}")
    print(f"{r['wall']['gi']}, frame {r['wall']['frame']:.2f} s")
    vp = np.load(tmp_path / "viewport_indirect.npy")[..., 0] * np.pi
    lit = front & (x > 0.25) & (x < 2.5)
    print(f"viewport after 6 redraws: E / F12 {vp[lit].mean() / ind[lit].mean():.4f}, "
          f"{r['viewport']}")
    assert r["viewport"]["method"] == "VXGI"
    assert abs(vp[lit].mean() / ind[lit].mean() - 1.0) < 0.05
    for band, (lo, hi) in RATIO_BANDS.items():
        assert lo < ratios[band] < hi, (band, ratios[band])


BENCH_SNIPPET = """
import sys
from pathlib import Path
sys.path.insert(0, {bench!r})
import quality, quality_scenes
from lumen_gi.gpu_shaders import engine

scene = quality_scenes.build({name!r})
quality.common_setup(scene, {size})
if {overhead!r}:               # look straight down into the room (its roof is hidden from it)
    cam = scene.camera
    cam.location = {overhead!r}
    quality_scenes._aim(cam, (0.0, 0.0, 0.0))
scene.lumen.bake.cache_dir = str(Path("cache").resolve())
log = quality.Log(Path("blender.log").resolve())
out = {{}}
if {cycles}:
    quality.apply_cycles(scene, quality.cycles_settings({samples}, False))
    _, passes = quality.render(scene, Path("cycles.exr").resolve(), log)
    np.save("cycles.npy", passes["Combined"][::-1, :, :3])   # EXR rows top-down, ours bottom-up
res, err = bake()
assert err is None, err
scene.render.engine = "LUMEN_GI"
for label, quality_, method in {runs!r}:
    scene.lumen.engine.render_quality = quality_
    scene.lumen.engine.gi_method = method
    scene.lumen.engine.render_frames = {frames}
    scene.lumen.engine.bounces = {bounces}
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(label + ".npy", R["combined"][..., :3])
    np.save("position.npy", R["position"])
    out[label] = dict(method=R.get("gi_method"), frame=R["frame_seconds"],
                      gi=R.get("gi_timings"))
emit(**out)
"""
BENCH = str(HERE.parents[1] / "bench")


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def test_vxgi_adds_light_in_the_cornell_box(tmp_path):
    """Against Cycles (64 spp, 64 px): VXGI's relMSE is below GI Off's."""
    runs = (("off", "OFF", "LUMEN"), ("vxgi", "LOW", "VXGI"))
    snippet = BENCH_SNIPPET.format(bench=BENCH, name="cornell", size=SIZE, cycles=True,
                                   samples=64, runs=runs, overhead=None, frames=4, bounces=3)
    run = run_python(snippet, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    r = run.result
    assert r["vxgi"]["method"] == "VXGI"
    ref = np.load(tmp_path / "cycles.npy")
    err = {k: rel_mse(np.load(tmp_path / f"{k}.npy"), ref) for k in ("off", "vxgi")}
    lum = {k: float(np.load(tmp_path / f"{k}.npy").mean() / ref.mean()) for k in ("off", "vxgi")}
    print(f"cornell {SIZE} px: relMSE GI off {err['off']:.4f}, VXGI {err['vxgi']:.4f}; mean / "
          f"Cycles: off {lum['off']:.3f}, VXGI {lum['vxgi']:.3f}; VXGI {r['vxgi']['gi']}")
    assert err["vxgi"] < err["off"]
    assert lum["vxgi"] > lum["off"]


# the leak into bench/quality_scenes.py's thin room (1.5 cm walls and roof under a sunlit sky):
# mean luminance on the room's inside / on the lit outside. VXGI, LOW (0.2 m voxels), 64 px,
# measured 6.5% (Lumen in the same run: 0.00%): the lecture's thin-wall leak, recorded. Why: the
# opacity 1 - d / r of a wall of no thickness, integrated across it (d = |s|), lets through
# exp(2 * integral of ln u over (0, 1)) = exp(-2) = 13.5% of what lies behind, whatever the step
LEAK_BAND = (0.03, 0.12)


def test_vxgi_thin_wall_leak_is_measured(tmp_path):
    runs = (("lumen", "LOW", "LUMEN"), ("vxgi", "LOW", "VXGI"))
    snippet = BENCH_SNIPPET.format(bench=BENCH, name="thin", size=SIZE, cycles=False,
                                   samples=0, runs=runs, overhead=(0.0, 0.3, 6.0), frames=1,
                                   bounces=1)
    run = run_python(snippet, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    pos = np.load(tmp_path / "position.npy")
    ix, iy, iz = 1.5, 1.5, 2.2                 # THIN["inner"] / 2 (x, y), height
    surface = pos[..., 3] > 0.5
    inside = surface & (np.abs(pos[..., 0]) < ix - 0.05) & (np.abs(pos[..., 1]) < iy - 0.05) \
        & (pos[..., 2] < iz - 0.05)
    outside = surface & ~((np.abs(pos[..., 0]) < ix + 0.05) & (np.abs(pos[..., 1]) < iy + 0.05))
    assert inside.sum() > 200 and outside.sum() > 200, (inside.sum(), outside.sum())
    leak = {}
    for k in ("lumen", "vxgi"):
        img = np.load(tmp_path / f"{k}.npy") @ np.array([0.2126, 0.7152, 0.0722])
        leak[k] = float(img[inside].mean() / img[outside].mean())
    print(f"thin room leak ({inside.sum()} px inside, {outside.sum()} outside): "
          f"Lumen {leak['lumen']:.2%}, VXGI {leak['vxgi']:.2%}; {run.result['vxgi']}")
    assert LEAK_BAND[0] <= leak["vxgi"] <= LEAK_BAND[1]
    assert leak["lumen"] < leak["vxgi"]
