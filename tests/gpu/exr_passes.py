"""Reading one render pass out of the multilayer EXRs Blender 5.0 writes (one part per pass)."""
import numpy as np


def read_pass(path, layer_pass):
    """RGB float32 (H, W, 3) of the pass named `layer_pass` (e.g. "Diffuse Direct") in `path`."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    seen, sub = [], 0
    try:
        while inp.seek_subimage(sub, 0):
            spec = inp.spec()
            names = list(spec.channelnames)
            seen += names
            idx = [i for i, n in enumerate(names) if n.rsplit(".", 1)[0].endswith("." + layer_pass)]
            if len(idx) >= 3:
                px = inp.read_image(sub, 0, 0, spec.nchannels, "float")
                return np.asarray(px, np.float32)[..., idx[:3]]
            sub += 1
    finally:
        inp.close()
    raise AssertionError(f"no pass {layer_pass!r} in {path}: {seen}")
