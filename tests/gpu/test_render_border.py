"""A render border (Render Region) must not lose the render: Blender's result then holds only
the border's pixels, and writing the whole frame into it raised ("RenderPass.rect: array
length cannot be changed"), so F12 drew nothing. The border's pixels must equal those pixels of
the full render, with and without Crop to Render Region, on a border whose edges fall between
pixels."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender"), str(HERE)]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402

SNIPPET = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
cube("Box", 1.0, (0.3, 0.0, 0.5))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.rotation_euler = (0.6, 0.3, 0.0)
aimed_camera((0.0, -5.0, 4.0), (0.0, 0.0, 0.3))
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"
scene.lumen.engine.aa_samples = 1
scene.render.resolution_x, scene.render.resolution_y = 71, 53
if hasattr(scene.render.image_settings, "media_type"):
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "32"
out = {"bake": bake()}
for name, border, crop in (("full", False, False), ("border", True, False),
                           ("cropped", True, True)):
    scene.render.use_border, scene.render.use_crop_to_border = border, crop
    scene.render.border_min_x, scene.render.border_max_x = 0.2, 0.7
    scene.render.border_min_y, scene.render.border_max_y = 0.15, 0.9
    scene.render.filepath = str(__import__("pathlib").Path(name + ".exr").resolve())
    bpy.ops.render.render(write_still=True)
    R = engine.LAST_RENDER
    out[name] = dict(error=R.get("error"), written=R.get("passes_written", []))
emit(**out)
"""


def test_render_border_writes_the_border_pixels_of_the_full_render(tmp_path):
    res = run_python(SNIPPET, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    r = res.result
    for name in ("full", "border", "cropped"):
        assert r[name]["error"] is None and "Combined" in r[name]["written"], r
    full = read_pass(tmp_path / "full.exr", "Combined")        # rows top-down (EXR)
    cropped = read_pass(tmp_path / "cropped.exr", "Combined")
    h, w = cropped.shape[:2]
    assert 0 < w < 71 and 0 < h < 53, cropped.shape
    # where in the full frame: the offset at which the crop matches (one exists, near the
    # border's own corner: x 0.2 * 71 = 14.2, y from the top (1 - 0.9) * 53 = 5.3)
    errs = {(y, x): float(np.abs(full[y:y + h, x:x + w] - cropped).max())
            for y in range(4, 8) for x in range(13, 16)}
    (y0, x0), err = min(errs.items(), key=lambda kv: kv[1])
    assert err < 1e-5, errs
    assert float(np.abs(cropped).max()) > 0.01          # the border holds the lit scene
    border = read_pass(tmp_path / "border.exr", "Combined")
    assert border.shape == full.shape
    assert np.abs(border[y0:y0 + h, x0:x0 + w] - cropped).max() < 1e-5


FILM = """
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=10.0, cache_dir="cache")
cube("Box", 1.0, (0.0, 0.0, 0.5))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.rotation_euler = (0.6, 0.3, 0.0)
aimed_camera((0.0, -5.0, 4.0), (0.0, 0.0, 0.3))
scene.world = bpy.data.worlds.new("World")
scene.world.use_nodes = True
scene.world.node_tree.nodes["Background"].inputs[0].default_value = (0.2, 0.3, 0.5, 1.0)
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 1
scene.lumen.engine.aa_samples = 8
scene.render.resolution_x = scene.render.resolution_y = 40
out = {"bake": bake()}
for transparent in (False, True):
    scene.render.film_transparent = transparent
    bpy.ops.render.render()
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    np.save(f"combined_{int(transparent)}.npy", R["combined"])
    np.save("position.npy", R["position"])
emit(**out)
"""


def test_transparent_film_gives_coverage_alpha_and_no_background(tmp_path):
    # Film > Transparent (compositing over a plate): Combined alpha was 1 everywhere and the
    # world filled the background
    res = run_python(FILM, tmp_path, timeout=300)
    assert res.returncode == 0, res.explain()
    opaque, clear = (np.load(tmp_path / f"combined_{k}.npy") for k in (0, 1))
    covered = np.load(tmp_path / "position.npy")[..., 3] > 0.5
    assert (opaque[..., 3] == 1.0).all()
    a = clear[..., 3]
    assert a.min() == 0.0 and a.max() == 1.0
    # the samples' coverage: the unjittered G-buffer's, but partial across the 3 px filter
    assert a[covered].mean() > 0.9 and a[~covered].mean() < 0.1, (a[covered].mean(),
                                                                  a[~covered].mean())
    assert (a[covered] > 0.0).all() and (a[~covered] < 1.0).all()
    assert ((a > 0.0) & (a < 1.0)).sum() > 10                # the box's edges are partial
    inside = a == 1.0
    # premultiplied: nothing of the world where nothing is covered; the surfaces as before
    assert np.abs(clear[a == 0.0][:, :3]).max() == 0.0
    assert np.abs(clear[inside][:, :3] - opaque[inside][:, :3]).max() < 1e-5
    assert (opaque[~covered][:, :3] > 0.01).all()            # the world shows when opaque
