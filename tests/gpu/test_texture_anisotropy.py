"""Anisotropic texture filtering in the LUMEN_GI G-buffer (gbuffer.glsl sample_mipmapped).

A 2 x 2 m plane seen straight down by an orthographic camera whose view is exactly the plane
(64 x 64 px), with a 16 x 16 PNG of horizontal stripes (4 texels each, two sRGB colours,
constant along u) whose UVs are stretched 32x along u only: a pixel covers 8 texels along u and
a quarter of a texel along v, the footprint of a floor seen at a grazing angle. The right
filter averages along u (where the stripes are constant: nothing to lose) and keeps v sharp:
every pixel well inside a stripe is that stripe's colour. A mip level chosen from the longer
axis alone (level 3: 8 x 8 texels, two stripes) gave the mean of the two colours everywhere,
which is what blurred the `textured` benchmark's far floor. Rendered with anti-aliasing off
(aa_samples 1: footprint_scale 1) and with the default 8 samples (footprint_scale 1 / sqrt(8)).
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
STRIPE = 4
STRETCH = 32.0
COLOURS = ((0.9, 0.25, 0.1), (0.1, 0.35, 0.8))      # sRGB, as painted into the PNG

SNIPPET = f"""
import time
from pathlib import Path
from lumen_gi.gpu_shaders import engine

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 0.0))
plane = bpy.context.object
img = bpy.data.images.new("Stripes", {TEX}, {TEX}, alpha=False)
px = np.zeros(({TEX}, {TEX}, 4), np.float32)
yy, xx = np.mgrid[0:{TEX}, 0:{TEX}]
odd = (yy // {STRIPE}) % 2 == 1
px[..., 3] = 1.0
px[~odd, :3] = {COLOURS[0]!r}
px[odd, :3] = {COLOURS[1]!r}
img.pixels.foreach_set(px.ravel())
path = str(Path("stripes.png").resolve())
img.filepath_raw = path
img.file_format = "PNG"
img.save()
bpy.data.images.remove(img)
img = bpy.data.images.load(path)
mat = principled("StripeMat", (0.5, 0.5, 0.5))
image_texture(mat, img)
plane.data.materials.append(mat)
for d in plane.data.uv_layers.active.data:
    d.uv = (d.uv[0] * {STRETCH}, d.uv[1])
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
cam.location = (0.0, 0.0, 5.0)
cam.data.type = "ORTHO"
cam.data.ortho_scale = 2.0
scene.camera = cam
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
result, error = bake()
assert error is None, error
vl = scene.view_layers[0]
vl.use_pass_diffuse_color = True
if hasattr(scene.render.image_settings, "media_type"):
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "32"
scene.render.engine = "LUMEN_GI"
scene.lumen.engine.render_quality = "OFF"        # the G-buffer is what is tested
for aa in (1, 8):
    scene.lumen.engine.aa_samples = aa
    scene.render.filepath = str(Path(f"lumen_aa{{aa}}.exr").resolve())
    bpy.ops.render.render(write_still=True)
    assert "error" not in engine.LAST_RENDER, engine.LAST_RENDER.get("error")
emit(done=True)
"""


def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.fixture(scope="module")
def albedos(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("texture_anisotropy")
    start = time.perf_counter()
    run = run_python(SNIPPET, tmp, timeout=300)
    assert run.returncode == 0, run.explain()
    print(f"run {time.perf_counter() - start:.1f} s")
    # OIIO rows are top first; G-buffer row 0 is the bottom (v = (row + 0.5) / SIZE)
    return {aa: read_pass(tmp / f"lumen_aa{aa}.exr", "Diffuse Color")[::-1] for aa in (1, 8)}


@pytest.mark.parametrize("aa", (1, 8))
def test_stripes_stay_sharp_across_the_short_axis(albedos, aa):
    albedo = albedos[aa]
    expected = [srgb_to_linear(np.round(np.asarray(c) * 255) / 255) for c in COLOURS]
    v = (np.arange(SIZE) + 0.5) / SIZE * TEX                # texel row of each pixel row
    inside = np.abs((v % STRIPE) - STRIPE / 2) <= STRIPE / 2 - 1.0
    odd = (v // STRIPE) % 2 == 1
    cols = slice(2, SIZE - 2)                               # away from the plane's edges
    for k, rows in enumerate((inside & ~odd, inside & odd)):
        px = albedo[rows, cols].reshape(-1, 3)
        err = np.abs(px - expected[k]).max()
        print(f"aa {aa}, stripe colour {k}: {len(px)} px, expected {np.round(expected[k], 4)}, "
              f"mean {np.round(px.mean(axis=0), 4)}, max |err| {err:.5f}")
        assert len(px) >= 500
        assert err <= 2 / 255          # the mean of the two (level 3) is 0.2-0.4 off
