"""The README's main command: tools/demo.py bakes the demo scene, exports the cache and renders
the preview. Run as a user would (its own process), at a small image size."""
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def test_demo_bakes_exports_and_renders(tmp_path):
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "demo.py"), "--out", str(tmp_path),
                          "--size", "64", "48"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert "Sphere.dup1" in run.stdout and "(shared)" in run.stdout      # instances share a bake

    from lumen_addon.cache import read_cache
    bake = read_cache(tmp_path / "cache")
    assert len(bake.instances) == 7 and len(bake.meshes) == 5 and bake.atlas is not None

    import OpenImageIO as oiio
    img = oiio.ImageInput.open(str(tmp_path / "preview.png"))
    pixels = img.read_image(format=oiio.FLOAT)
    img.close()
    assert pixels.shape[:2] == (48, 64)
    # A lit scene, not a blank or constant image: the red box shows, shadows are darker than floor.
    # (GI lights the box with bounced floor colours and sky: red by ratio, not absolute levels)
    red = (pixels[..., 0] > 0.3) & (pixels[..., 0] > 2.0 * np.maximum(pixels[..., 1], pixels[..., 2]))
    assert red.sum() > 10
    assert np.ptp(pixels[..., :3].mean(axis=2)) > 0.3
