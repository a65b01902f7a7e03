"""Small helpers every compute pass uses: build a shader once from a declaration, dispatch over
an image, allocate and read RGBA32F textures. Needs a GPU context.

A pass is declared by what it reads: `scene` (sdf_lib.glsl's three samplers; sdf_ray_lib.glsl
comes with it), `surface_cache`
(surface_cache_lib.glsl's), `global_sdf` (global_sdf_lib.glsl's), `sky` (sky_lib.glsl's), extra 2D float samplers, images
(binding order = listed order, RGBA32F unless given; integer formats such as R32I
are iimage2D, for atomics) and push constants; its source is the
libraries it needs followed by glsl/<name>.comp.glsl.
"""
from __future__ import annotations

import gpu
import numpy as np

from . import glsl_include
from .resources import SceneResources, read_texture

GROUP = 8
_SHADERS = {}
GUARD = "bind_guard"


def new_info(group=(GROUP, GROUP, 1)):
    """A GPUShaderCreateInfo for a compute pass, with the bind guard as its first push constant.

    Why: Blender 5.3's OpenGL backend writes the texture unit of every `uniform_sampler` call into
    the shader's first uniform as well (measured: four samplers holding 1, 2, 3, 4 read back 4, 2,
    3, 4 when the shader has no push constant; tests/versions). An int constant that comes first,
    is read (so the compiler keeps it) and is set last absorbs those writes, whatever the order in
    which a pass binds its samplers and constants. Costs one uniform compare per invocation."""
    info = gpu.types.GPUShaderCreateInfo()
    info.local_group_size(*group)
    info.push_constant('INT', GUARD)
    return info


def create(info, source: str):
    """The compute shader of `source` (exactly one `void main()`), run behind the bind guard."""
    if source.count("void main()") != 1:
        raise ValueError("a compute source needs exactly one 'void main()'")
    source = source.replace("void main()", "void pass_main()") + (
        f"\nvoid main()\n{{\n  if ({GUARD} == -1) {{\n    return;\n  }}\n  pass_main();\n}}\n")
    info.compute_source(source)
    return gpu.shader.create_from_info(info)


def run(sh, groups_x: int, groups_y: int = 1, groups_z: int = 1):
    """gpu.compute.dispatch of sh after setting the bind guard (last, see new_info)."""
    sh.uniform_int(GUARD, 0)
    gpu.compute.dispatch(sh, int(groups_x), int(groups_y), int(groups_z))


def owners(files) -> list:
    """The declare functions of the libraries among `files` (glsl_include.files), in slot order:
    a pass that includes sdf_lib.glsl gets SceneResources' samplers, and so on."""
    from .global_sdf import GlobalSDF
    from .sky_light import SkyLight
    from .surface_cache import SurfaceCache
    table = (("sdf_lib.glsl", SceneResources.declare),
             ("surface_cache_lib.glsl", SurfaceCache.declare),
             ("global_sdf_lib.glsl", GlobalSDF.declare), ("sky_lib.glsl", SkyLight.declare))
    return [declare for lib, declare in table if lib in files]


def declare_libs(info, name: str, slot: int = 0):
    """Declare the samplers of the libraries glsl/<name> includes on info; returns (source of
    name with its includes resolved, next free sampler slot)."""
    for declare in owners(glsl_include.files(name)):
        slot = declare(info, slot)
    return glsl_include.source(name), slot


def shader(name: str, *, samplers=(), images=("out_image",), push=()):
    """The compute shader of glsl/<name>.comp.glsl and the libraries it #includes (cached by
    name); the samplers of sdf_lib, surface_cache_lib, global_sdf_lib and sky_lib come with
    them. images: names or (name, format) or (name, format, qualifiers such as {'READ',
    'WRITE'}: write-only unless given); push: (type, name)."""
    if name in _SHADERS:
        return _SHADERS[name]
    info = new_info()
    src, slot = declare_libs(info, name + ".comp.glsl")
    for s in samplers:
        info.sampler(slot, 'FLOAT_2D', s)
        slot += 1
    for k, im in enumerate(images):
        im = (im,) if isinstance(im, str) else tuple(im)
        im_name = im[0]
        fmt = im[1] if len(im) > 1 else 'RGBA32F'
        access = im[2] if len(im) > 2 else {'WRITE'}
        info.image(k, fmt, 'INT_2D' if fmt.endswith('I') else 'FLOAT_2D', im_name,
                   qualifiers=set(access))
    for kind, pname in push:
        info.push_constant(kind, pname)
    _SHADERS[name] = create(info, src)
    return _SHADERS[name]


def texture(size, fmt='RGBA32F'):
    """A new 2D texture cleared to zero. A new GPUTexture's contents are undefined (OpenGL and
    Vulkan leave them so), and the surface cache's passes keep textures whose texels are written
    a tile at a time: what no pass wrote yet must read as 'nothing', not as garbage."""
    tex = gpu.types.GPUTexture((int(size[0]), int(size[1])), format=fmt)
    channels = next(n for prefix, n in (("RGBA", 4), ("RGB", 3), ("RG", 2), ("R", 1))
                    if fmt.startswith(prefix))
    tex.clear(format='INT' if fmt.endswith('I') else 'FLOAT', value=(0,) * channels)
    return tex


def dispatch(sh, width: int, height: int):
    run(sh, -(-int(width) // GROUP), -(-int(height) // GROUP), 1)


def read(tex) -> np.ndarray:
    """float32 [h, w, C] of a 2D texture (waits for the GPU)."""
    return read_texture(tex)


def vec(v, n=3):
    return [float(c) for c in np.asarray(v, np.float64).reshape(-1)[:n]]
