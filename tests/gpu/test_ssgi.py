"""GI Method SSGI (gpu_shaders/ssgi.py, hzb.py; llvmpipe through bpy) against exact answers.

- The HZB (hzb.depth_pyramid) of a synthetic G-buffer, 37 x 23 pixels (odd sizes: the last texel
  of a level has one child per odd side), read back: level 0 is the MIN of the window depths of
  each pixel's 3x3 neighbourhood (1 on the background) and every texel of every other level is
  exactly the MIN of its children;
  the colour pyramid's levels are the mean of theirs (premultiplied by coverage).
- A floor under a parallel emissive panel (L = 2 x (1, 0.5, 0.25), no albedo) seen from the side,
  the whole panel on screen and no light but the panel's: every ray that hits returns the panel's
  colour, so E_indirect on the floor has the panel's chromaticity exactly; its own rays hit with
  the probability of the panel's form factor F(x) (SSGI_HITS' green), and E = pi L F(x) is the
  numerical integral of L cos cos / d^2 over the panel (numpy, here).
- The viewport (view_draw, one iteration per redraw) converges to the F12 image of that view.
- LPV and VXGI are built (tests/gpu/test_lpv.py, tests/gpu/test_vxgi.py).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

HZB = """
import traceback
import gpu
from lumen_gi.gpu_shaders import compute, hzb
from lumen_gi.gpu_shaders.resources import float_buffer

W, H = 37, 23
rng = np.random.default_rng(7)
pos = np.zeros((H, W, 4), np.float32)
pos[..., :3] = rng.uniform([-3, -3, 1.0], [3, 3, 40.0], (H, W, 3))
pos[..., 3] = (rng.random((H, W)) > 0.15).astype(np.float32)
src = rng.random((H, W, 4)).astype(np.float32)
f, n, fa = 1.0 / np.tan(0.6), 0.1, 100.0
proj = np.array([[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)],
                 [0, 0, -1, 0]])
view = np.diag([1.0, 1.0, -1.0, 1.0])      # looking down +z
vp = proj @ view
ERRORS, OUT = [], {}

class HZBTestEngine(bpy.types.RenderEngine):
    bl_idname = "LUMEN_HZB_TEST"
    bl_label = "HZB test"
    bl_use_gpu_context = True
    def render(self, depsgraph):
        try:
            ptex = gpu.types.GPUTexture((W, H), format='RGBA32F', data=float_buffer(pos))
            stex = gpu.types.GPUTexture((W, H), format='RGBA32F', data=float_buffer(src))
            gbuf = {"textures": {"position": ptex}}
            OUT["hzb"] = compute.read(hzb.depth_pyramid(gbuf, vp, W, H))
            OUT["colour"] = compute.read(hzb.colour_pyramid(stex, gbuf, W, H))
        except Exception:
            ERRORS.append(traceback.format_exc())
        r = self.begin_result(0, 0, 4, 4)
        self.end_result(r)

bpy.utils.register_class(HZBTestEngine)
scene = bpy.context.scene
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
scene.camera = cam
scene.render.engine = "LUMEN_HZB_TEST"
scene.render.resolution_x = scene.render.resolution_y = 4
bpy.ops.render.render()
assert not ERRORS, ERRORS[0]
np.savez("hzb.npz", pos=pos, src=src, vp=vp, **OUT)
emit(layout=hzb.mip_layout(W, H))
"""

PANEL_L = (2.0, 1.0, 0.5)
PANEL = dict(half=1.0, height=1.5)
SIZE = 128

SCENE = f"""
import mathutils
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 0.0, 0.0))
floor = bpy.context.object
floor.data.materials.append(principled("Floor", (0.5, 0.5, 0.5)))
bpy.ops.mesh.primitive_plane_add(size={2 * PANEL['half']}, location=(0.0, 0.0, {PANEL['height']}))
panel = bpy.context.object
panel.rotation_euler = (3.14159265358979, 0.0, 0.0)       # facing down, at the floor
panel.data.materials.append(principled("Panel", (0.0, 0.0, 0.0), emission=(1.0, 0.5, 0.25),
                                       strength=2.0))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
cam = aimed_camera((0.0, -3.5, 0.75), (0.0, 0.0, 0.75))
cam.data.lens = 35.0
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.gi_method = "SSGI"
scene.lumen.engine.ssgi_rays = 8
scene.lumen.engine.ssgi_thickness = 0.02         # the panel is a plane: no thickness behind it
scene.lumen.engine.bounces = 2
scene.lumen.engine.render_frames = 8
res, err = bake()
assert err is None, err
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
np.save("indirect.npy", R["indirect"])
np.save("position.npy", R["position"])
np.save("normal.npy", R["normal"])
out = dict(method=R["gi_method"], notes=R["notes"], memory=R["gpu_bytes"],
           gi=R["gi_timings"], iterations=R["gi_iterations"], frame=R["frame_seconds"])
# the viewport: one iteration per redraw into its history, for the same still view
import viewport_harness
scene.lumen.engine.viewport_quality = "LOW"
def redraw(i):
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("error")
    return dict(progress=list(R["gi_progress"]), converged=R["gi_converged"])
vp = viewport_harness.run(scene, engine.LumenGIRenderEngine, {SIZE}, {SIZE}, 12, redraw)
out["viewport"] = vp["after"]
np.save("viewport_indirect.npy", engine.LAST_RENDER["indirect"])
scene.lumen.engine.debug_view = "SSGI_HITS"
bpy.ops.render.render()
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
np.save("hits.npy", R["shown"])
scene.lumen.engine.debug_view = "COMBINED"
scene.render.resolution_x = scene.render.resolution_y = 24
scene.lumen.engine.render_frames = 1
scene.lumen.engine.bounces = 1
for method in ("VXGI",):
    scene.lumen.engine.gi_method = method
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    out[method] = dict(error=R.get("error"), method=R.get("gi_method"), notes=R.get("notes"),
                       sc_tiles=R.get("gi_sc_tiles"))
emit(**out)
"""


def test_hzb_levels_are_the_min_of_their_children(tmp_path):
    run = run_python(HZB, tmp_path, timeout=120)
    assert run.returncode == 0, run.explain()
    d = np.load(tmp_path / "hzb.npz")
    rects = run.result["layout"][0]
    pos, vp = d["pos"].astype(np.float64), d["vp"]
    h = pos[..., :3] @ vp[:3, :3].T + vp[:3, 3]
    wc = pos[..., :3] @ vp[3, :3] + vp[3, 3]
    depth = np.where(pos[..., 3] > 0.5, np.clip(h[..., 2] / wc * 0.5 + 0.5, 0, 1), 1.0)
    pad = np.pad(depth, 1, constant_values=1.0)          # level 0: the 3x3 MIN of the depths
    want0 = np.min([pad[1 + j:1 + j + depth.shape[0], 1 + i:1 + i + depth.shape[1]]
                    for j in (-1, 0, 1) for i in (-1, 0, 1)], axis=0)
    levels = [d["hzb"][y:y + hh, x:x + ww, 0] for x, y, ww, hh in rects]
    colours = [d["colour"][y:y + hh, x:x + ww] for x, y, ww, hh in rects]
    assert len(levels) == 7 and levels[-1].shape == (1, 1)             # 37x23 -> ... -> 1x1
    err0 = np.abs(levels[0] - want0).max()
    cover = pos[..., 3:] > 0.5
    want_c0 = np.concatenate([d["src"][..., :3] * cover, cover], axis=-1)
    print(f"level 0 |gpu - numpy| max {err0:.2e}; levels {[lv.shape for lv in levels]}")
    assert err0 < 2e-6
    assert np.abs(colours[0] - want_c0).max() < 1e-6
    for k in range(1, len(levels)):
        lo, hi = levels[k - 1], levels[k]
        c_lo = colours[k - 1]
        ph, pw = 2 * hi.shape[0] - lo.shape[0], 2 * hi.shape[1] - lo.shape[1]
        pad = np.pad(lo, ((0, ph), (0, pw)), constant_values=np.inf)
        mins = pad.reshape(hi.shape[0], 2, hi.shape[1], 2).min(axis=(1, 3))
        assert np.array_equal(hi, mins), k                          # exactly the min
        cnt = np.pad(np.ones(lo.shape), ((0, ph), (0, pw)))
        sums = np.pad(c_lo, ((0, ph), (0, pw), (0, 0))).reshape(
            hi.shape[0], 2, hi.shape[1], 2, 4).sum(axis=(1, 3))
        means = sums / cnt.reshape(hi.shape[0], 2, hi.shape[1], 2).sum(axis=(1, 3))[..., None]
        np.testing.assert_allclose(colours[k], means, rtol=1e-5, atol=1e-7)
    assert abs(levels[-1][0, 0] - depth.min()) < 2e-6                # the top: the nearest


def panel_irradiance(points: np.ndarray, n: int = 400) -> np.ndarray:
    """E(x) / L at floor points [N, 3] (normal +z) from the panel (z = height, |x|, |y| <= half,
    facing down): the midpoint rule for the integral of cos_x cos_p / d^2 over the panel."""
    half, height = PANEL["half"], PANEL["height"]
    g = (np.arange(n) + 0.5) / n * 2 * half - half
    px, py = np.meshgrid(g, g)
    da = (2 * half / n) ** 2
    out = np.empty(len(points))
    for i, p in enumerate(points):          # a few hundred floor points, vectorised per point
        dz = height - p[2]
        d2 = (px - p[0]) ** 2 + (py - p[1]) ** 2 + dz * dz
        out[i] = (dz * dz / (d2 * d2)).sum() * da
    return out


def test_ssgi_on_a_floor_under_a_lit_panel(tmp_path):
    run = run_python(SCENE, tmp_path, timeout=400)
    assert run.returncode == 0, run.explain()
    r = run.result
    ind = np.load(tmp_path / "indirect.npy")[..., :3] * np.pi       # Diffuse Indirect x pi = E
    pos = np.load(tmp_path / "position.npy")
    nrm = np.load(tmp_path / "normal.npy")
    hits = np.load(tmp_path / "hits.npy")
    assert r["method"] == "SSGI" and not [n for n in r["notes"] if "GI Method" in n], r["notes"]
    floor = (pos[..., 3] > 0.5) & (np.abs(nrm[..., 2]) > 0.99) & (np.abs(pos[..., 2]) < 1e-3)
    under = floor & (np.abs(pos[..., 0]) < 0.8) & (np.abs(pos[..., 1]) < 0.8)
    assert under.sum() >= 60, under.sum()
    L = np.array(PANEL_L)
    e = ind[under]
    chroma = e / e[:, :1]
    print(f"{under.sum()} floor px under the panel; E/E_r min {chroma.min(0)} max {chroma.max(0)}")
    np.testing.assert_allclose(chroma, np.broadcast_to(L / L[0], chroma.shape), rtol=1e-4)
    want = panel_irradiance(pos[under][:, :3].astype(np.float64))
    got = e[:, 0] / L[0]
    ratio = got / want
    share = hits[..., 1][under]
    print(f"E / (pi L F): mean {got.mean() / want.mean():.4f}, per pixel p5 "
          f"{np.percentile(ratio, 5):.3f} p50 {np.median(ratio):.3f} p95 {np.percentile(ratio, 95):.3f}; hit share mean "
          f"{share.mean():.4f} vs F {(want / np.pi).mean():.4f}; {r['gi']} {r['iterations']} it, "
          f"frame {r['frame']:.2f} s")
    assert abs(got.mean() / want.mean() - 1.0) < 0.04
    assert (np.abs(ratio - 1.0) < 0.15).mean() > 0.9
    assert abs(share.mean() / (want / np.pi).mean() - 1.0) < 0.04    # hits: P = form factor
    mem = r["memory"]
    aw, ah = SIZE + SIZE // 2, SIZE                   # the atlas: level 0, the rest beside it
    assert mem["ssgi_hzb"] == aw * ah * 4 and mem["ssgi_colour"] == aw * ah * 16
    assert mem["ssgi_hits"] == SIZE * 8 * SIZE * 16
    # the viewport's history (12 redraws, LOW: about 8 frames) converges to the F12 image
    vp = np.load(tmp_path / "viewport_indirect.npy")[..., :3] * np.pi
    steps = r["viewport"]
    print(f"viewport: E / F12 {vp[under].mean() / ind[under].mean():.4f}; "
          f"{steps[:3]}...{steps[-1]}")
    assert steps[0]["progress"] == [1, 8] and not steps[0]["converged"]
    assert steps[-1]["progress"] == [8, 8] and steps[-1]["converged"]
    assert abs(vp[under].mean() / ind[under].mean() - 1.0) < 0.03
    m = r["VXGI"]             # every method is built: none falls back to Lumen any more
    assert m["error"] is None and m["method"] == "VXGI", m
    assert not any("not built yet" in n for n in m["notes"]), m["notes"]


PANEL_DRAW = """
from lumen_gi.operators.panel import RENDER_PANELS

scene = bpy.context.scene
scene.render.engine = "LUMEN_GI"
prop = scene.lumen.engine.bl_rna.properties["gi_method"]
out = dict(default=scene.lumen.engine.gi_method,
           items={i.identifier: i.description for i in prop.enum_items})
for method in ("LUMEN", "SSGI", "RSM", "LPV", "VXGI"):
    scene.lumen.engine.gi_method = method
    drawn = draw_panels(RENDER_PANELS)
    out[method] = [n if k == "prop" else f"{k}: {n}" for log in drawn.values() for k, n in log]
    out[method + "_panels"] = list(drawn)
emit(**out)
"""


def test_gi_method_setting_and_what_the_render_panel_shows(tmp_path):
    run = run_python(PANEL_DRAW, tmp_path, timeout=60)
    assert run.returncode == 0, run.explain()
    r = run.result
    assert r["default"] == "LUMEN"
    assert list(r["items"]) == ["LUMEN", "SSGI", "RSM", "LPV", "VXGI"]
    assert all(len(d) > 20 for d in r["items"].values())           # plain-language descriptions
    for method in r["items"]:
        assert all(p in r[method] for p in ("render_quality", "viewport_quality", "gi_method",
                                            "debug_view"))
    ssgi = ("ssgi_rays", "ssgi_steps", "ssgi_thickness", "ssgi_reuse")
    rsm = ("rsm_resolution", "rsm_samples")
    assert all(p in r["SSGI"] for p in ssgi) and not any(p in r["SSGI"] for p in rsm)
    assert all(p in r["RSM"] for p in rsm) and not any(p in r["RSM"] for p in ssgi)
    assert "gi_gather" in r["LUMEN"] and "gi_gather" not in r["SSGI"]
    assert not any("Not built yet" in line for m in r["items"] for line in r[m])
    assert all(p in r["LPV"] for p in ("lpv_cells", "lpv_iterations", "lpv_occlusion"))
    assert all(p in r["VXGI"] for p in ("vxgi_cones", "vxgi_cone_angle", "vxgi_distance",
                                        "vxgi_step", "vxgi_offset"))
    assert "gi_gather" not in r["VXGI"]
    # one sub-panel per built method, drawn only while it is the chosen one
    subs = {"LUMEN": "RENDER_PT_lumen_gi_lumen", "SSGI": "RENDER_PT_lumen_gi_ssgi",
            "RSM": "RENDER_PT_lumen_gi_rsm", "LPV": "RENDER_PT_lumen_gi_lpv",
            "VXGI": "RENDER_PT_lumen_gi_vxgi"}
    for method in r["items"]:
        shown = [p for p in subs.values() if p in r[method + "_panels"]]
        assert shown == ([subs[method]] if method in subs else []), (method, shown)
