"""Compute passes: one declaration per pass (`Pass`), bound from that declaration and dispatched;
zero-cleared textures and read-back. Needs a GPU context.

A pass is glsl/<name>.comp.glsl, whose `#include "x.glsl"` lines name the libraries it uses
(glsl_include.py resolves them: recursively, each once, dependencies first), and a `Pass`:

    PLACE = compute.Pass("screen_probe_place", samplers=("gbuf_position", "gbuf_normal"),
                         images=("out_image", "probe_normal_out"),
                         push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile')))
    PLACE.run((w, h), gbuf_position=..., gbuf_normal=..., out_image=..., probe_normal_out=...,
              cam_pos=..., probe_tile=16)

Every declared sampler (2D float), image (RGBA32F write-only unless given; integer formats such
as R32I are iimage2D, for atomics) and push constant is bound from the keyword of its name. A
library's samplers come with its include and are bound by their owner, given by keyword:
sdf_lib.glsl `scene=` (SceneResources), surface_cache_lib.glsl `cache=` (SurfaceCache),
global_sdf_lib.glsl `gsdf=` (GlobalSDF), sky_lib.glsl `sky=` (SkyLight),
voxel_lighting_lib.glsl and voxel_lighting_trace_lib.glsl `voxels=` (VoxelLighting or None).
The screen trace and the radiance cache hand their inputs over as dicts to splat into `run`
(ScreenTrace.inputs, radiance_cache.lookup_inputs, ...). A missing or unknown input raises.
Push constants over Vulkan's 128 bytes go into a uniform block (the GLSL is unchanged).
"""
from __future__ import annotations

import re

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


SHARED_DECL = re.compile(r"^[ \t]*shared[ \t]+[^;{}()]+;[ \t]*$", re.MULTILINE)
SHARED_LINE = re.compile(r"^[ \t]*shared\b.*$", re.MULTILINE)
SHARED_MACRO = "LUMEN_SHARED_DECLS"


def hoist_shared(info, source: str) -> str:
    """`source` with its work-group `shared` declarations moved into a define of `info`, expanded
    where the first of them stood. Why: Blender 5.3 drops `shared` declarations from a Python
    compute source (every use then fails to compile: 's_pos' undeclared; 5.0 compiles them),
    while a define's text reaches the compiler as it is (both versions, measured).
    A `shared` line this cannot move (a comment after the `;`) raises here, on every Blender:
    left in place, 5.3 alone dropped it (screen_bounds' s_clip, tests/versions)."""
    found = list(SHARED_DECL.finditer(source))
    moved = {m.start() for m in found}
    for m in SHARED_LINE.finditer(source):
        if m.start() not in moved:
            raise ValueError(f"a shared declaration must be alone on its line, nothing after "
                             f"the ';' (compute.hoist_shared): {m.group(0).strip()!r}")
    decls = [m.group(0).strip() for m in found]
    if not decls:
        return source
    info.define(SHARED_MACRO, " ".join(decls))
    first = found[0]
    rest = SHARED_DECL.sub("", source[first.end():])
    return source[:first.start()] + SHARED_MACRO + rest


def create(info, source: str):
    """The compute shader of `source` (exactly one `void main()`), run behind the bind guard."""
    if source.count("void main()") != 1:
        raise ValueError("a compute source needs exactly one 'void main()'")
    source = hoist_shared(info, source)
    source = source.replace("void main()", "void pass_main()") + (
        f"\nvoid main()\n{{\n  if ({GUARD} == -1) {{\n    return;\n  }}\n  pass_main();\n}}\n")
    info.compute_source(source)
    return gpu.shader.create_from_info(info)


PASS_MODULES = ("screen_probes", "surface_cache", "radiance_cache", "voxel_lighting",
                "screen_trace", "hzb", "ssgi", "rsm", "lpv", "vxgi", "composite", "antialias",
                "direct_light", "sdf_trace")


def declared_passes() -> list:
    """Every compute.Pass the engine's modules declare (imported on call; nothing compiled), for
    the tests and the version matrix that compile them all, not only those a default F12 runs."""
    import importlib

    out = []
    for mod in PASS_MODULES:
        m = importlib.import_module(f"{__package__}.{mod}")
        out += [p for p in vars(m).values() if isinstance(p, Pass)]
    return out


def run(sh, groups_x: int, groups_y: int = 1, groups_z: int = 1):
    """gpu.compute.dispatch of sh after setting the bind guard (last, see new_info)."""
    sh.uniform_int(GUARD, 0)
    gpu.compute.dispatch(sh, int(groups_x), int(groups_y), int(groups_z))


# Bytes per push constant (std430; a VEC3 takes 16) and the limit Vulkan guarantees.
PUSH_BYTES = {'INT': 4, 'FLOAT': 4, 'BOOL': 4, 'VEC2': 8, 'IVEC2': 8, 'VEC3': 16, 'IVEC3': 16,
              'VEC4': 16, 'IVEC4': 16, 'MAT3': 48, 'MAT4': 64}
PUSH_LIMIT = 128
BLOCK_SLOT = 1          # the pass block's binding (GlobalSDFParams has 0)
_VEC = {'FLOAT': 1, 'VEC2': 2, 'VEC3': 3, 'VEC4': 4, 'INT': 1, 'IVEC2': 2, 'IVEC3': 3,
        'IVEC4': 4, 'BOOL': 1}


def push_bytes(push) -> int:
    """Push-constant bytes of a declaration, the bind guard included."""
    return PUSH_BYTES['INT'] + sum(PUSH_BYTES[kind] for kind, _ in push)


def _providers():
    """(library, keyword, declare(info, slot) -> slot, bind(shader, value) -> held): the inputs a
    pass gets from what it #includes, bound by their owner (SceneResources.bind etc.)."""
    from . import voxel_lighting
    from .global_sdf import GlobalSDF
    from .sky_light import SkyLight
    from .surface_cache import SurfaceCache

    def own(sh, v):
        v.bind(sh)

    return (("sdf_lib.glsl", "scene", SceneResources.declare, own),
            ("surface_cache_lib.glsl", "cache", SurfaceCache.declare, own),
            ("global_sdf_lib.glsl", "gsdf", GlobalSDF.declare, own),
            ("sky_lib.glsl", "sky", SkyLight.declare, own),
            ("voxel_lighting_lib.glsl", "voxels", voxel_lighting.declare_radiance,
             voxel_lighting.bind_radiance),
            ("voxel_lighting_trace_lib.glsl", "voxels", voxel_lighting.declare_tiles,
             voxel_lighting.bind_tiles))


# Compile-time variants: a pass that includes `library` and is run with an input `keyword` whose
# `attribute` is true is compiled (and cached) apart with `#define DEFINE 1`, so that code only
# some scenes need costs nothing in the others: the cut-outs' bookkeeping in the shadow cones
# (light_lib.glsl: the direct pass took 1.055x in a scene without a cut-out on llvmpipe when it
# was always compiled in, bench/glsl_ab.py) and in the GI rays (gi_trace_lib.glsl: the probe
# traces 1.02-1.03x).
VARIANTS = (("light_lib.glsl", "scene", "cut_outs", "LIGHT_CUT_OUTS"),
            ("gi_trace_lib.glsl", "scene", "cut_outs", "GI_CUT_OUTS"))


class Pass:
    """One compute pass, declared once and bound from that declaration.

    Pass(name, samplers=, images=, push=) declares glsl/<name>.comp.glsl (and what it
    #includes): 2D float samplers, images (names or (name, format[, qualifiers]), write-only
    RGBA32F unless given) and push constants ((type, name)). `run(size, **inputs)` binds every
    declared input from the keyword of its name (textures, numbers, vectors, matrices) and the
    libraries' owners from theirs (scene= SceneResources for sdf_lib.glsl, cache= SurfaceCache,
    gsdf= GlobalSDF, sky= SkyLight, voxels= VoxelLighting or None), then dispatches over size
    (pixels; `run_groups`: work groups). A missing or unknown input raises ValueError naming
    the pass and the input, so a forgotten bind can no longer go unnoticed.
    Push constants over Vulkan's 128 bytes go into a uniform block instead (one 16-byte slot per
    name, a #define per name: the GLSL body is the same)."""

    def __init__(self, name: str, *, samplers=(), images=("out_image",), push=(),
                 group=(GROUP, GROUP, 1), source=None):
        self.name, self.group, self.text = name, tuple(group), source   # source: tests
        self.samplers = tuple(samplers)
        self.images = tuple((im,) if isinstance(im, str) else tuple(im) for im in images)
        self.push = tuple(push)
        self.block = push_bytes(self.push) > PUSH_LIMIT
        self._ubo = None
        self._files = None
        self._unused = {}            # shader key -> push constants the compiler dropped

    @property
    def shader(self):
        """The compiled shader without variants (built on first use, cached in _SHADERS by
        name)."""
        return self.shader_of(())

    def shader_of(self, defines=()):
        """The shader compiled with `defines` (VARIANTS), cached by name + defines."""
        key = "+".join((self.name,) + tuple(defines))
        if key not in _SHADERS:
            _SHADERS[key] = self._build(tuple(defines))
        return _SHADERS[key]

    def variant_sets(self) -> list:
        """Every set of defines the pass compiles with (none; each VARIANTS attribute's, all of
        one attribute's together as one input sets them), for the tests that compile them all."""
        files = self.files()
        out, by_attr = [()], {}
        for lib, key, attr, define in VARIANTS:
            if lib in files:
                by_attr.setdefault((key, attr), []).append(define)
        out += [tuple(d) for d in by_attr.values()]
        return out

    def defines(self, inputs) -> tuple:
        """The VARIANTS these inputs ask for (empty for a pass that includes none)."""
        files = self.files()
        return tuple(define for lib, key, attr, define in VARIANTS
                     if lib in files and bool(getattr(inputs.get(key), attr, False)))

    def files(self) -> list:
        """The GLSL files of the pass (glsl_include.files), its own last."""
        if self._files is None:
            main = self.name + ".comp.glsl"
            self._files = (glsl_include.files(glsl_include.includes(self.text))
                           if self.text is not None else glsl_include.files(main))
        return self._files

    def providers(self) -> list:
        """(keyword, declare, bind) of the library owners the pass's includes need."""
        files = self.files()
        return [(key, declare, bind) for lib, key, declare, bind in _providers() if lib in files]

    def _build(self, defines=()):
        info = new_info(self.group)
        files = self.files()
        if self.text is not None:   # a test's GLSL: its #include lines name files in glsl/
            libs = glsl_include.includes(self.text)
            text = (glsl_include.source(libs) if libs else "") + "\n" \
                + glsl_include.INCLUDE.sub("", self.text)
        else:
            text = glsl_include.source(files[-1])
        slot = 0
        for _, declare, _ in self.providers():
            slot = declare(info, slot)
        for s in self.samplers:
            info.sampler(slot, 'FLOAT_2D', s)
            slot += 1
        for k, im in enumerate(self.images):
            fmt = im[1] if len(im) > 1 else 'RGBA32F'
            info.image(k, fmt, 'INT_2D' if fmt.endswith('I') else 'FLOAT_2D', im[0],
                       qualifiers=set(im[2] if len(im) > 2 else {'WRITE'}))
        prefix = "".join(f"#define {d} 1\n" for d in defines)
        if self.block:
            from .global_sdf import PARAMS_TYPEDEF
            members = "".join(f"  {_slot_type(kind)} p_{n};\n" for kind, n in self.push)
            # typedef_source replaces: keep GlobalSDFParams when the pass reads the global SDF
            info.typedef_source((PARAMS_TYPEDEF if "global_sdf_lib.glsl" in files else "")
                                + f"struct PassParams {{\n{members}}};\n")
            info.uniform_buf(BLOCK_SLOT, "PassParams", "pass_params")
            prefix += "".join(f"#define {n} pass_params.p_{n}{_swizzle(kind)}\n"
                              for kind, n in self.push)
        else:
            for kind, n in self.push:
                info.push_constant(kind, n)
        return create(info, prefix + text)

    def inputs(self) -> set:
        """Every keyword `run` takes."""
        return ({s for s in self.samplers} | {im[0] for im in self.images}
                | {n for _, n in self.push} | {key for key, _, _ in self.providers()})

    def bind(self, **inputs) -> list:
        """Bind every declared input to the shader they ask for (shader_of(defines(inputs)));
        returns what must be held until the dispatch."""
        return self._bind(self.defines(inputs), inputs)

    def _bind(self, defines, inputs) -> list:
        sh = self.shader_of(defines)
        expected = self.inputs()
        for k in sorted(expected - set(inputs)):
            raise ValueError(f"pass {self.name}: missing input {k!r}")
        for k in sorted(set(inputs) - expected):
            raise ValueError(f"pass {self.name}: unknown input {k!r}")
        held = [bind(sh, inputs[key]) for key, _, bind in self.providers()]
        for s in self.samplers:
            sh.uniform_sampler(s, inputs[s])
        for im in self.images:
            sh.image(im[0], inputs[im[0]])
        if self.block:
            held.append(self._bind_block(sh, inputs))
        else:
            key = defines
            if key not in self._unused:
                self._unused[key] = {n for _, n in self.push if _compiled_out(sh, n)}
            unused = self._unused[key]
            for kind, n in self.push:
                if n in unused:
                    if not kind.startswith('MAT'):
                        _values(kind, n, inputs[n], self.name)     # still checked
                else:
                    _set_push(sh, kind, n, inputs[n], self.name)
        return held

    def _bind_block(self, sh, inputs):
        data = np.zeros(4 * sum(_slots(kind) for kind, _ in self.push), np.float32)
        ints = data.view(np.int32)
        at = 0
        for kind, n in self.push:
            v = inputs[n]
            if kind.startswith('MAT'):
                m = np.asarray(v, np.float32)              # rows; GLSL reads columns
                size = int(kind[3])
                cols = np.zeros((size, 4), np.float32)
                cols[:, :size] = m.reshape(size, size).T
                data[at:at + 4 * size] = cols.reshape(-1)
            else:
                vals = _values(kind, n, v, self.name)
                (ints if kind.startswith(('I', 'B')) else data)[at:at + len(vals)] = vals
            at += 4 * _slots(kind)
        import gpu
        self._ubo = gpu.types.GPUUniformBuf(data)          # held until the next run
        sh.uniform_block("pass_params", self._ubo)
        return self._ubo

    def run(self, size, **inputs):
        """Bind `inputs` and dispatch over size = (width, height) pixels (or width)."""
        w, h = (size, 1) if np.isscalar(size) else size
        self.run_groups((-(-int(w) // self.group[0]), -(-int(h) // self.group[1]), 1), **inputs)

    def run_groups(self, groups, **inputs):
        """Bind `inputs` and dispatch `groups` work groups ((x, y[, z]) or x)."""
        defines = self.defines(inputs)
        held = self._bind(defines, inputs)  # noqa: F841 (held until the dispatch)
        g = (groups,) if np.isscalar(groups) else tuple(groups)
        run(self.shader_of(defines), *g)


def _slots(kind):
    return int(kind[3]) if kind.startswith('MAT') else 1


def _slot_type(kind):
    if kind.startswith('MAT'):
        return kind.lower()
    return 'ivec4' if kind.startswith(('I', 'B')) else 'vec4'


def _swizzle(kind):
    return "" if kind.startswith('MAT') else "." + "xyzw"[:_VEC[kind]]


def _values(kind, name, v, pass_name):
    n = _VEC[kind]
    flat = np.asarray(v, np.float64).reshape(-1)
    if flat.size != n:
        raise ValueError(f"pass {pass_name}: {name} is {kind}, got {flat.size} values")
    if kind.startswith(('I', 'B')):
        return [int(c) for c in flat]
    return [float(c) for c in flat]


def _compiled_out(sh, name) -> bool:
    """Whether the compiler dropped push constant `name` (declared for a library function the
    pass never calls: setting it would raise)."""
    try:
        return sh.uniform_from_name(name) < 0
    except ValueError:
        return True


def _set_push(sh, kind, name, v, pass_name):
    vals = _values(kind, name, v, pass_name) if not kind.startswith('MAT') else None
    if kind.startswith('MAT'):
        import mathutils
        sh.uniform_float(name, v if isinstance(v, mathutils.Matrix)
                         else mathutils.Matrix(np.asarray(v, np.float64).tolist()))
        return
    if kind.startswith(('I', 'B')):
        sh.uniform_int(name, vals[0] if len(vals) == 1 else vals)
    else:
        sh.uniform_float(name, vals[0] if len(vals) == 1 else vals)


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


_COUNTER = None


def read_counter(tex) -> int:
    """The int in texel (0, 0) of an R32I texture (an atomic counter), read back: the size of a
    dispatch over a list a pass built (Blender's gpu module has no indirect dispatch). An R32I
    texture reads back as zeros (Blender 5.0), so a one-texel pass copies it to R32F first.
    Waits for the GPU: on llvmpipe, which runs each dispatch as it is issued, nothing; on a GPU
    the rest of the frame is issued once the passes before it are done."""
    global _COUNTER
    if _COUNTER is None:
        _COUNTER = Pass("read_counter", source="""
void main()
{
  imageStore(out_image, ivec2(0, 0), vec4(float(imageLoad(counter, ivec2(0, 0)).x)));
}
""", images=("out_image", ("counter", 'R32I', {'READ'})), group=(1, 1, 1))
    out = texture((1, 1))
    _COUNTER.run_groups(1, counter=tex, out_image=out)
    return int(read(out).reshape(-1)[0])
