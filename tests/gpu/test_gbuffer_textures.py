"""Image textures in the LUMEN_GI G-buffer: a 2 x 2 m plane (UVs 0..1) with a 16 x 16 checkerboard
PNG (4 x 4 texel squares, two sRGB colours) on its Principled Base Color, seen straight down by an
orthographic camera whose view is exactly the plane (64 x 64 px: pixel (x, y) has UV
((x + 0.5) / 64, (y + 0.5) / 64), row 0 at the bottom). The "Diffuse Color" pass (the G-buffer
albedo) is compared with the checker's two linearised 8-bit colours at pixels well inside the
squares, and at every pixel with lumen_addon.materials.sample_texture of the extracted texture.
"""
import sys
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402

SIZE = 64
TEX = 16
SQUARE = 4
COLOURS = ((0.9, 0.25, 0.1), (0.1, 0.35, 0.8))      # sRGB, as painted into the PNG

SNIPPET = f"""
import time
from pathlib import Path
from lumen_gi.gpu_shaders import engine
from lumen_gi.operators.extract import extract_scene
from lumen_gi.lumen_addon.materials import sample_texture

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 0.0))
plane = bpy.context.object
img = bpy.data.images.new("Checker", {TEX}, {TEX}, alpha=False)
px = np.zeros(({TEX}, {TEX}, 4), np.float32)
yy, xx = np.mgrid[0:{TEX}, 0:{TEX}]
odd = ((yy // {SQUARE}) + (xx // {SQUARE})) % 2 == 1
px[..., 3] = 1.0
px[~odd, :3] = {COLOURS[0]!r}
px[odd, :3] = {COLOURS[1]!r}
img.pixels.foreach_set(px.ravel())
path = str(Path("checker.png").resolve())
img.filepath_raw = path
img.file_format = "PNG"
img.save()
bpy.data.images.remove(img)
img = bpy.data.images.load(path)
mat = principled("CheckerMat", (0.5, 0.5, 0.5))
image_texture(mat, img)
plane.data.materials.append(mat)
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
cam.location = (0.0, 0.0, 5.0)
cam.data.type = "ORTHO"
cam.data.ortho_scale = 2.0
scene.camera = cam
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
t = time.perf_counter()
result, error = bake()
assert error is None, error
bake_seconds = time.perf_counter() - t
vl = scene.view_layers[0]
vl.use_pass_diffuse_color = True
if hasattr(scene.render.image_settings, "media_type"):
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "32"
scene.render.engine = "LUMEN_GI"
scene.render.filepath = str(Path("lumen.exr").resolve())
t = time.perf_counter()
bpy.ops.render.render(write_still=True)
render_seconds = time.perf_counter() - t
R = engine.LAST_RENDER
assert "error" not in R, R.get("traceback", R.get("error"))
objects, _ = extract_scene(bpy.context.evaluated_depsgraph_get())
tex = objects[0].materials[0].base_color_texture
c = (np.arange({SIZE}) + 0.5) / {SIZE}
u, v = np.meshgrid(c, c)
ref = sample_texture(tex, np.stack([u.ravel(), v.ravel()], 1)).reshape({SIZE}, {SIZE}, 3)
np.save("reference.npy", ref)
# minified: UVs x 32, so a pixel covers 8 x 8 texels (2 x 2 checker squares)
for d in plane.data.uv_layers.active.data:
    d.uv = (d.uv[0] * 32.0, d.uv[1] * 32.0)
scene.render.filepath = str(Path("lumen_far.exr").resolve())
bpy.ops.render.render(write_still=True)
assert "error" not in engine.LAST_RENDER, engine.LAST_RENDER.get("error")
emit(bake_seconds=bake_seconds, render_seconds=render_seconds, draws=R["gbuffer_draws"],
     texture_uploads=R["texture_uploads"], gbuffer_seconds=R["gbuffer_seconds"],
     texture_shape=list(tex.shape))
"""


def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.fixture(scope="module")
def render(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("gbuffer_textures")
    start = time.perf_counter()
    run = run_python(SNIPPET, tmp, timeout=120)
    assert run.returncode == 0, run.explain()
    albedo = read_pass(tmp / "lumen.exr", "Diffuse Color")
    albedo = albedo[::-1]          # OIIO rows are top first; G-buffer row 0 is the bottom
    print(f"run {time.perf_counter() - start:.1f} s; {run.result}")
    far = read_pass(tmp / "lumen_far.exr", "Diffuse Color")
    return albedo, np.load(tmp / "reference.npy"), run.result, far


def inner_mask():
    """Pixels whose UV is at least one texel from every checker square edge."""
    c = (np.arange(SIZE) + 0.5) / SIZE * TEX          # texel coordinate of the pixel centre
    inside = np.abs((c % SQUARE) - SQUARE / 2) <= SQUARE / 2 - 1.0
    return inside[:, None] & inside[None, :]


def test_albedo_is_the_checker(render):
    albedo, _, result, _ = render
    expected = [srgb_to_linear(np.round(np.asarray(c) * 255) / 255) for c in COLOURS]
    mask = inner_mask()
    c = (np.arange(SIZE) + 0.5) / SIZE * TEX // SQUARE
    odd = ((c[:, None] + c[None, :]) % 2 == 1)
    seen = []
    for k, sel in enumerate((mask & ~odd, mask & odd)):
        err = np.abs(albedo[sel] - expected[k]).max()
        seen.append(int(sel.sum()))
        print(f"colour {k}: {sel.sum()} px, expected {np.round(expected[k], 4)}, max |err| {err:.5f}")
        assert sel.sum() >= 100
        assert err <= 2 / 255
    assert result["texture_uploads"] == 1 and result["draws"] == 1


def test_albedo_matches_sample_texture(render):
    albedo, ref, _, _ = render
    err = np.abs(albedo - ref)
    print(f"max |ours - sample_texture| {err.max():.6f} over {SIZE}x{SIZE} px, "
          f"mean {err.mean():.7f}")
    assert err[inner_mask()].max() <= 2 / 255
    assert np.mean(err.max(axis=-1) <= 2 / 255) >= 0.99


def test_a_minified_texture_is_its_mean_not_moire(render):
    """UVs x 32: each pixel covers 8 x 8 texels, two squares of each colour: mip level 3 of the
    chain (gbuffer.mip_chain) gives the mean of the two colours at every pixel. One sample of
    level 0 per pixel (before) gave one of the two colours at random: moire."""
    far = render[3]
    mean = np.mean([srgb_to_linear(np.round(np.asarray(c) * 255) / 255) for c in COLOURS], axis=0)
    err = np.abs(far - mean) / mean
    print(f"minified: mean {far.reshape(-1, 3).mean(axis=0)}, expected {mean}, max rel {err.max():.4f}")
    assert err.max() < 0.03
