"""Small helpers every compute pass uses: build a shader once from a declaration, dispatch over
an image, allocate and read RGBA32F textures. Needs a GPU context.

A pass is declared by what it reads: `scene` (sdf_lib.glsl's three samplers; sdf_ray_lib.glsl
comes with it), `surface_cache`
(surface_cache_lib.glsl's), `global_sdf` (global_sdf_lib.glsl's), extra 2D float samplers, images
(binding order = listed order, RGBA32F unless given) and push constants; its source is the
libraries it needs followed by glsl/<name>.comp.glsl.
"""
from __future__ import annotations

import gpu
import numpy as np

from .resources import SceneResources, glsl

GROUP = 8
_SHADERS = {}


def shader(name: str, *, samplers=(), images=("out_image",), push=(), libs=(), scene=False,
           surface_cache=False, global_sdf=False):
    """The compute shader of glsl/<name>.comp.glsl (cached by name). images: names or
    (name, format); push: (type, name)."""
    if name in _SHADERS:
        return _SHADERS[name]
    info = gpu.types.GPUShaderCreateInfo()
    info.local_group_size(GROUP, GROUP, 1)
    slot = 0
    src = []
    if scene:
        slot = SceneResources.declare(info, slot)
        src += [glsl("sdf_lib.glsl"), glsl("sdf_ray_lib.glsl")]
    if surface_cache:
        from .surface_cache import SurfaceCache
        slot = SurfaceCache.declare(info, slot)
    if global_sdf:
        from .global_sdf import GlobalSDF
        slot = GlobalSDF.declare(info, slot)
        src.append(glsl("global_sdf_lib.glsl"))
    if surface_cache:
        src.append(glsl("surface_cache_lib.glsl"))
    for s in samplers:
        info.sampler(slot, 'FLOAT_2D', s)
        slot += 1
    for k, im in enumerate(images):
        im_name, fmt = (im, 'RGBA32F') if isinstance(im, str) else im
        info.image(k, fmt, 'FLOAT_2D', im_name, qualifiers={'WRITE'})
    for kind, pname in push:
        info.push_constant(kind, pname)
    src += [glsl(lib) for lib in libs] + [glsl(name + ".comp.glsl")]
    info.compute_source("\n".join(src))
    _SHADERS[name] = gpu.shader.create_from_info(info)
    return _SHADERS[name]


def texture(size, fmt='RGBA32F'):
    """A new 2D texture cleared to zero. A new GPUTexture's contents are undefined (Blender 5.3's
    OpenGL backend hands back memory of freed textures), so a pass that leaves texels unwritten
    would let the next pass read garbage."""
    tex = gpu.types.GPUTexture((int(size[0]), int(size[1])), format=fmt)
    channels = next(n for prefix, n in (("RGBA", 4), ("RGB", 3), ("RG", 2), ("R", 1))
                    if fmt.startswith(prefix))
    tex.clear(format='INT' if fmt.endswith('I') else 'FLOAT', value=(0,) * channels)
    return tex


def dispatch(sh, width: int, height: int):
    gpu.compute.dispatch(sh, -(-int(width) // GROUP), -(-int(height) // GROUP), 1)


def read(tex) -> np.ndarray:
    """float32 [h, w, C] of a 2D texture (waits for the GPU)."""
    return np.asarray(tex.read().to_list(), np.float32).reshape(tex.height, tex.width, -1)


def vec(v, n=3):
    return [float(c) for c in np.asarray(v, np.float64).reshape(-1)[:n]]
