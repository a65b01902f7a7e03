"""Blender materials -> `lumen_addon.materials.Material`: the shader node trees read node by node.

What the preview keeps of a material is what a diffuse GI preview can use: a base colour (a
value, an Image Texture linked straight in, through a Mapping node, or a colour attribute), an
emission, an opacity (glass and alpha are see-through: extract.clear_faces), a cut-out (the
Base Color image's own alpha), a tangent-space normal map. Read: a Principled BSDF, a Diffuse
BSDF, an Emission shader, clear shaders (Glass, Refraction, Transparent) and Mix and Add Shaders
of them, weighed as Cycles weighs them (_Closure). Anything else is rendered by Cycles
(material_capture.py) when it can be (the main thread), else it takes the material's viewport
display colour. Nothing here raises for bad materials: every fallback is a warning naming the
material (and, through extract.py, the objects), and images are read once per extraction.
"""
from __future__ import annotations

import dataclasses
import threading

import numpy as np

from ..lumen_addon.materials import DEFAULT_ALBEDO, Material

# Colour spaces whose byte pixels are already linear (or data: normal maps, masks).
_LINEAR_SPACES = {"Non-Color", "scene_linear", "ACEScg", "ACES2065-1", "Linear Rec.709",
                  "Linear Rec.2020", "Linear CIE-XYZ D65", "Linear CIE-XYZ E",
                  "Linear DCI-P3 D65", "Linear FilmLight E-Gamut", "Raw", "Linear"}


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), elementwise, float32."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / np.float32(12.92),
                    ((np.maximum(c, 0.04045) + np.float32(0.055)) / np.float32(1.055))
                    ** np.float32(2.4)).astype(np.float32)


# -- node trees ----------------------------------------------------------------------------------

def _follow(socket):
    """(node, output socket) feeding `socket`, through reroutes; None when unlinked or muted."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None
        node = link.from_node
        if node.type == 'REROUTE':
            socket, seen = node.inputs[0], seen + 1
            continue
        return node, link.from_socket
    return None


def _display_colour(mat):
    return tuple(float(c) for c in mat.diffuse_color[:3])


def _rgb(socket):
    return tuple(float(c) for c in socket.default_value[:3])


def surface_of(mat):
    """((node, socket) feeding the active Material Output's Surface, None) or (None, why not)."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return None, "has no shader nodes"
    out = tree.get_output_node('EEVEE') or tree.get_output_node('CYCLES')
    if out is None:
        return None, "has no active Material Output node"
    src = _follow(out.inputs["Surface"])
    if src is None:
        return None, "has nothing connected to the Material Output's Surface"
    return src, None


def material_emits(mat) -> bool:
    """Whether `mat` emits as the bake reads it (a Principled BSDF's Emission Strength or an
    Emission shader's Strength, with a colour above black or an Image Texture linked to it,
    also inside the Mix and Add Shaders the conversion follows), without reading any image:
    cheap enough for the N-panel's estimate (bake.too_small_for_cards keeps an emitter's cards)."""
    return _emits(surface_of(mat)[0], 0)


def _emits(src, depth: int) -> bool:
    if src is None or depth > MAX_SHADER_DEPTH:
        return False
    node = src[0]
    if node.type in ('MIX_SHADER', 'ADD_SHADER'):
        first = 1 if node.type == 'MIX_SHADER' else 0
        return any(_emits(_follow(node.inputs[i]), depth + 1) for i in (first, first + 1))
    names = EMISSION_INPUTS.get(node.type)
    if names is None or float(node.inputs[names[1]].default_value) == 0.0:
        return False
    socket = node.inputs[names[0]]
    linked = _follow(socket)
    if linked is not None and linked[0].type == 'TEX_IMAGE' and linked[0].image is not None:
        return True
    return max(_rgb(socket)) > 0.0


# The emitting shaders' (colour, strength) inputs
EMISSION_INPUTS = {'BSDF_PRINCIPLED': ("Emission Color", "Emission Strength"),
                   'EMISSION': ("Color", "Strength")}
MAX_SHADER_DEPTH = 16     # Mix and Add Shaders followed at most this deep


# Shaders that let light and the camera through (Cycles: transmission or transparency); a
# surface made of them is see-through (lumen_addon.materials.SEE_THROUGH)
CLEAR_SHADERS = {'BSDF_GLASS', 'BSDF_REFRACTION', 'BSDF_TRANSPARENT'}


def _value(node, *names, default=0.0):
    """(value of the first input of `node` named in `names`, whether a link drives it)."""
    for name in names:
        socket = node.inputs.get(name)
        if socket is not None:
            return float(socket.default_value), _follow(socket) is not None
    return default, False


def principled_opacity(node, cut_out: bool = False):
    """(opacity, warnings) of a Principled BSDF: the share of light it stops, Alpha x (1 - the
    transmission lobe's weight), that lobe being Transmission Weight x (1 - Metallic) as in
    Cycles' Principled BSDF. Values only: a driven Alpha is opaque (a cut-out of the Base Color
    image, cut_out, is the G-buffer's; anything else is named in a warning); a driven
    Transmission Weight or Metallic uses its value."""
    notes = []
    alpha, alpha_linked = _value(node, "Alpha", default=1.0)
    if alpha_linked:
        if not cut_out:
            notes.append("Alpha is driven by a node (only the Alpha of the Base Color image is "
                         "read, as a cut-out); drawn opaque")
        alpha = 1.0
    transmission, t_linked = _value(node, "Transmission Weight", "Transmission")
    metallic, m_linked = _value(node, "Metallic")
    if t_linked or (m_linked and transmission > 0.0):
        notes.append(f"Transmission Weight or Metallic is driven by a node (not supported); "
                     f"using the values {transmission:g} and {metallic:g}")
    lobe = min(max(transmission, 0.0), 1.0) * (1.0 - min(max(metallic, 0.0), 1.0))
    return float(min(max(alpha, 0.0), 1.0) * (1.0 - lobe)), notes


# Light Path outputs whose value is known for the light the preview carries (shadow and bounce
# rays, never camera rays): the usual "glass that lets shadows through" trick mixes on these
_LIGHT_RAY = {"Is Shadow Ray": 1.0, "Is Camera Ray": 0.0}

# Rec. 709 luminance: how Blender turns a colour socket into a value (scene-linear Rec. 709)
LUMINANCE = (0.2126, 0.7152, 0.0722)


def uv_mapping(node):
    """((A 2x2, b 2), None) of a Mapping node on UVs as Blender computes it (Point: rotate(v x
    Scale) + Location; Texture: its inverse; Vector: no Location), u and v of the 3D result of
    (u, v, 0); or (None, why) when its inputs are driven or its type is Normal."""
    import mathutils

    kind = node.vector_type
    names = ("Location", "Rotation", "Scale")
    if any(_follow(node.inputs[n]) is not None for n in names if n in node.inputs):
        return None, "a Mapping node's Location, Rotation or Scale is driven (not supported)"
    if kind not in ('POINT', 'TEXTURE', 'VECTOR'):
        return None, f"a Mapping node of type {kind.title()} (not supported)"
    loc = np.array(node.inputs["Location"].default_value[:3], np.float64) \
        if "Location" in node.inputs else np.zeros(3)
    rot = np.array(mathutils.Euler(node.inputs["Rotation"].default_value[:3]).to_matrix(),
                   np.float64)
    scale = np.array(node.inputs["Scale"].default_value[:3], np.float64)
    if kind == 'VECTOR':
        loc = np.zeros(3)
    m = rot @ np.diag(scale)
    if kind == 'TEXTURE':           # the inverse: (R^-1 (v - L)) / S
        if np.any(np.abs(scale) < 1e-12):
            return None, "a Texture Mapping node with a zero Scale (not supported)"
        m = np.diag(1.0 / scale) @ rot.T
        loc = -m @ loc
    return (m[:2, :2].copy(), loc[:2].copy()), None


def mix_factor(node):
    """(factor, warnings) of a Mix Shader for the light the preview carries: its value, or a
    Light Path output's (_LIGHT_RAY); None (with a warning) when anything else drives it."""
    socket = node.inputs[0]
    linked = _follow(socket)
    if linked is None:
        return min(max(float(socket.default_value), 0.0), 1.0), []
    src, out = linked
    if src.type == 'LIGHT_PATH' and out.name in _LIGHT_RAY:
        return _LIGHT_RAY[out.name], []
    return None, [f"the Mix Shader's Factor is driven by a {src.bl_label} node (cut-outs are "
                  f"read only from the Alpha of the Base Color image); drawn opaque"]


class _Texture:
    """An Image Texture feeding a socket: its image, output (Color/Alpha) and UV map name."""

    def __init__(self, node, output, uv_map, notes, mapping=None):
        self.node, self.image, self.output = node, node.image, output
        self.uv_map = uv_map            # None: the mesh's active render UV map
        self.notes = notes              # warnings about coordinates/projection (texture still used)
        self.mapping = mapping          # (A 2x2, b 2): a Mapping node's u, v -> A (u, v) + b


class MaterialInfo:
    """A converted material: the Material, the UV map its textures use, and its warnings."""

    def __init__(self, material, uv_maps=(), textured=False, warnings=(), attribute=None):
        self.material = material
        self.uv_maps = list(uv_maps)    # UV map names the textures use (None: active render)
        self.textured = textured
        self.warnings = list(warnings)
        self.attribute = attribute      # the colour attribute its base colour reads ("": the
                                        # mesh's render colour attribute), or None
        self.mapping = None             # its textures' UV Mapping (A, b), or None
        self.captured = False           # its textures are material_capture's (UVs optional)


@dataclasses.dataclass
class _Closure:
    """What the preview keeps of a shader: the light it reflects diffusely (`reflect`: colour x
    the share of light that reaches it, so that mixing adds), its base texture, its emission,
    its opacity (the share of light it stops) and the warnings and UV maps on the way."""
    reflect: tuple = (0.0, 0.0, 0.0)
    base_tex: object = None
    base: tuple = (0.0, 0.0, 0.0)          # the colour of the part that carries base_tex
    emission: tuple = (0.0, 0.0, 0.0)
    strength: float = 0.0
    emit_tex: object = None
    opacity: float = 1.0
    uv_maps: list = dataclasses.field(default_factory=list)
    warnings: list = dataclasses.field(default_factory=list)
    share: float = 1.0                      # the weight of the part that carries base_tex
    attr: object = None                     # a colour attribute's name in place of base_tex
    clip: bool = False                      # base_tex's alpha cuts the surface out
    normal_tex: object = None               # a tangent-space normal map (linear data)
    normal_strength: float = 1.0
    bump: bool = False                      # normal_tex is a Bump node's scaled height
    holdout: bool = False                   # all of it a Holdout shader (rgba 0 for the camera)

    def set_base(self, rgb, tex, uv_map, notes, attr, weight: float):
        self.reflect = tuple(weight * float(x) for x in rgb)
        self.base, self.base_tex, self.attr = tuple(map(float, rgb)), tex, attr
        self.warnings += notes
        if tex is not None:
            self.uv_maps.append(uv_map)

    @staticmethod
    def combine(sides, weights, opacity):
        out = _Closure(opacity=float(opacity))
        out.reflect = tuple(float(sum(w * s.reflect[k] for s, w in zip(sides, weights)))
                            for k in range(3))
        held = [s.holdout for s, w in zip(sides, weights) if w > 0.0]
        out.holdout = bool(held) and all(held)
        if any(held) and not out.holdout:
            out.warnings.append("mixes a Holdout shader with another (a partial holdout: not "
                                "supported); its share is drawn black")
        for s in sides:
            out.uv_maps += [u for u in s.uv_maps if u not in out.uv_maps]
            out.warnings += s.warnings
        textured = [(w * s.share, s) for s, w in zip(sides, weights)
                    if s.base_tex is not None or s.attr is not None]
        if textured:
            share, s = max(textured, key=lambda x: x[0])
            out.base_tex, out.attr, out.base, out.share = s.base_tex, s.attr, s.base, share
            out.clip = s.clip
            if any(w > 0.0 and o is not s and max(o.reflect) > 0.0
                   for o, w in zip(sides, weights)):
                out.warnings.append("a Mix or Add Shader blends a texture with another "
                                    "surface's colour (not supported); using the texture")
        mapped = [s for s in sides if s.normal_tex is not None]
        if mapped:
            out.normal_tex, out.normal_strength = mapped[0].normal_tex, mapped[0].normal_strength
            out.bump = mapped[0].bump
        lit = [(w * s.strength, s) for s, w in zip(sides, weights) if w * s.strength != 0.0]
        emitted = [e for e in lit if e[1].emit_tex is not None]
        if emitted:
            out.strength, src = max(emitted, key=lambda x: abs(x[0]))
            out.emit_tex, out.emission = src.emit_tex, src.emission
            if len(lit) > 1:
                out.warnings.append("a Mix or Add Shader blends an emission texture with other "
                                    "emission (not supported); using the texture")
        elif lit:
            out.strength = float(sum(x for x, _ in lit))
            out.emission = tuple(float(sum(x * s.emission[k] for x, s in lit) / out.strength)
                                 if out.strength else 0.0 for k in range(3))
        return out

    @staticmethod
    def mix(a, b, fac):
        f = min(max(float(fac), 0.0), 1.0)
        return _Closure.combine((a, b), (1.0 - f, f), (1.0 - f) * a.opacity + f * b.opacity)

    @staticmethod
    def add(a, b):
        clear = min((1.0 - a.opacity) + (1.0 - b.opacity), 1.0)
        return _Closure.combine((a, b), (1.0, 1.0), 1.0 - clear)

    def info(self, mat):
        """The MaterialInfo: the base colour is what the opaque part reflects (reflect /
        opacity; a texture's part keeps its texture), clamped to 1."""
        if self.base_tex is not None or self.attr is not None:
            base = self.base
        elif self.opacity > 1e-6:
            base = tuple(min(max(x / self.opacity, 0.0), 1.0) for x in self.reflect)
        else:                                   # all clear: its faces are left out
            base = self.base if max(self.base) > 0.0 else _display_colour(mat)
        material = Material(name=mat.name, base_color=base, base_color_texture=self.base_tex,
                            emission_color=self.emission, emission_strength=self.strength,
                            emission_texture=self.emit_tex, opacity=float(self.opacity),
                            vertex_colors=self.attr is not None,
                            alpha_clip=self.clip and self.base_tex is not None,
                            normal_texture=self.normal_tex,
                            normal_strength=float(self.normal_strength),
                            bump=bool(self.bump and self.normal_tex is not None),
                            holdout=bool(self.holdout))
        return MaterialInfo(material, self.uv_maps, bool(self.uv_maps), self.warnings,
                            attribute=self.attr)


DISPLAY_COLOUR = "using its viewport display colour"


def _same_mapping(a, b) -> bool:
    if a is None or b is None:
        return a is b
    return np.allclose(a[0], b[0]) and np.allclose(a[1], b[1])


def colour_attribute(linked):
    """The name of the colour attribute a socket reads straight from a Color Attribute node
    ("" for the mesh's render colour attribute) or an Attribute node's Color output (geometry
    attributes); None otherwise."""
    if linked is None:
        return None
    node, out = linked
    if node.type == 'VERTEX_COLOR' and out.name == "Color":
        return node.layer_name or ""
    if node.type == 'ATTRIBUTE' and out.name == "Color" and node.attribute_type == 'GEOMETRY':
        return node.attribute_name
    return None


_DRY_IMAGE = np.zeros((1, 1, 3), np.float32)


def bpy_materials():
    import bpy
    return list(bpy.data.materials)


def needs_capture(mat) -> bool:
    """Whether the extraction reads `mat` only in part (a shader or a colour input it does not
    follow), so that its colours come from material_capture. Loads no image."""
    src, _why = surface_of(mat)
    if src is None:
        return False
    ex = MaterialReader(dry=True)
    closure, _why = ex._shader(mat, src[0], 0)
    return closure is None or bool(ex._unread)


class MaterialReader:
    """Converted materials and images of one extraction (extract.Extractor adds its warnings).
    dry: only whether materials can be read (needs_capture): no image loaded, no capture."""

    def __init__(self, dry: bool = False):
        self.materials = {}     # material pointer -> MaterialInfo
        self.images = {}        # (image pointer, output) -> (array or None, reason)
        self._unread = []       # the material being converted: what it could not read
        self._mapping = False   # ... and its textures' Mapping (None: none; False: no texture)
        self.dry = dry

    # images ------------------------------------------------------------------------------------

    def image_array(self, image, output="Color"):
        """float32 (H, W, C) linear pixels of an image, row 0 at v = 0; or (None, reason)."""
        if self.dry:
            return _DRY_IMAGE, None
        image = image.original if getattr(image, "is_evaluated", False) else image
        key = (image.as_pointer(), output)
        if key not in self.images:
            self.images[key] = self._convert_image(image, output)
        return self.images[key]

    @staticmethod
    def _convert_image(image, output):
        label = f"image '{image.name}'"
        if image.source == 'TILED':
            return None, f"{label} is a UDIM tile set (not supported)"
        if image.source in {'MOVIE', 'SEQUENCE', 'VIEWER'}:
            return None, f"{label} is a {image.source.lower()} image (not supported)"
        try:
            w, h = image.size[:]          # reading the size loads the pixels
            n = len(image.pixels) if w and h else 0
        except Exception as exc:          # pragma: no cover - defensive (corrupt file)
            return None, f"{label} could not be read ({exc})"
        if not (w and h and n and image.has_data):
            where = f" from '{image.filepath}'" if image.filepath else ""
            return None, f"{label} has no pixel data (file missing or unreadable{where})"
        channels = n // (w * h)
        pixels = np.empty(n, np.float32)
        image.pixels.foreach_get(pixels)
        pixels = pixels.reshape(h, w, channels)
        if output == "Alpha":
            alpha = pixels[:, :, 3:4] if channels == 4 else np.ones((h, w, 1), np.float32)
            return np.ascontiguousarray(alpha), None
        if channels == 2:                 # grey + alpha
            pixels = pixels[:, :, :1]
            channels = 1
        if channels not in (1, 3, 4):
            return None, f"{label} has {channels} channels per pixel (not supported)"
        space = image.colorspace_settings.name
        if (image.is_float or image.colorspace_settings.is_data or space in _LINEAR_SPACES
                or space.startswith("Linear ")):
            return pixels, None           # Blender keeps float buffers in scene-linear already
        colour = min(channels, 3)
        pixels[:, :, :colour] = srgb_to_linear(pixels[:, :, :colour])
        note = None if "sRGB" in space else f"{label}: colour space '{space}' treated as sRGB"
        return pixels, note

    # materials ---------------------------------------------------------------------------------

    def material_info(self, mat):
        key = mat.as_pointer()
        if key not in self.materials:
            try:
                self.materials[key] = self._convert_material(mat)
            except Exception as exc:      # never let an odd node tree stop the bake
                self.materials[key] = MaterialInfo(
                    Material(name=mat.name, base_color=_display_colour(mat)),
                    warnings=[f"could not be read ({type(exc).__name__}: {exc}); "
                              f"using its viewport display colour"])
        return self.materials[key]

    def _convert_material(self, mat):
        fallback = Material(name=mat.name, base_color=_display_colour(mat))
        src, why = surface_of(mat)
        if src is None:
            return MaterialInfo(fallback, warnings=[f"{why}; {DISPLAY_COLOUR}"])
        self._unread, self._mapping = [], False
        closure, why = self._shader(mat, src[0], 0)
        if closure is None or self._unread:
            reason = why if closure is None else "; ".join(self._unread)
            means = None if self.dry else self._captured(mat)
            if means is not None:
                # the means are the colours where a mesh has no UVs (the textures' elsewhere;
                # a texture is scaled by the strength, 1)
                emits = means.emission_tex is not None or max(means.emission) > 0.0
                info = MaterialInfo(
                    Material(name=mat.name, base_color=means.albedo,
                             base_color_texture=means.albedo_tex,
                             emission_color=means.emission,
                             emission_strength=1.0 if emits else 0.0,
                             emission_texture=means.emission_tex, opacity=means.opacity),
                    uv_maps=[None], textured=True,
                    warnings=[f"{reason}; using its colours rendered by Cycles over its UV "
                              f"square"])
                info.captured = True      # its textures need no UV map: the means serve
                return info
            if closure is None:
                return MaterialInfo(fallback, warnings=[f"{reason}; {DISPLAY_COLOUR}"])
            closure.warnings += [f"{r}; {DISPLAY_COLOUR}" for r in self._unread]
        info = closure.info(mat)
        info.mapping = self._mapping or None
        return info

    def _captured(self, mat):
        """material_capture.Means of a material read only in part, rendered with every other
        material in the file that needs it and is not remembered (one Cycles image), or None."""
        from . import material_capture

        key = material_capture.signature(mat)       # a walk over its nodes: once
        hit = material_capture.remembered(key)
        if hit is not None or threading.current_thread() is not threading.main_thread():
            return hit            # a job thread (the UI's F12) cannot render: display colour
        others = [m for m in bpy_materials() if m != mat and m.users and needs_capture(m)]
        return material_capture.means(mat, others, key)

    def _shader(self, mat, node, depth):
        """(_Closure of the shader `node`, None) or (None, why it is not read): a Principled,
        Diffuse or Emission shader, a clear one (CLEAR_SHADERS) or a Mix or Add Shader of
        those."""
        kind = node.type
        if kind == 'BSDF_PRINCIPLED':
            return self._principled(mat, node), None
        if kind == 'BSDF_DIFFUSE':
            c = _Closure()
            c.set_base(*self._colour(mat, node.inputs["Color"], "Color"), weight=1.0)
            self._normal_map(c, node.inputs["Normal"])
            return c, None
        if kind == 'EMISSION':
            c = _Closure(reflect=(0.0, 0.0, 0.0))
            self._emission(c, node.inputs["Color"], node.inputs["Strength"], "Color", "Strength")
            return c, None
        if kind in CLEAR_SHADERS:
            return _Closure(reflect=(0.0, 0.0, 0.0), opacity=0.0), None
        if kind == 'HOLDOUT':       # Cycles: no light from it, nothing seen through it
            return _Closure(reflect=(0.0, 0.0, 0.0), holdout=True), None
        if kind in ('MIX_SHADER', 'ADD_SHADER') and depth < MAX_SHADER_DEPTH:
            first = 1 if kind == 'MIX_SHADER' else 0
            sides = []
            for i in (first, first + 1):
                src = _follow(node.inputs[i])
                if src is None:                # an empty input: no light from it, opaque black
                    sides.append(_Closure(reflect=(0.0, 0.0, 0.0)))
                    continue
                side, why = self._shader(mat, src[0], depth + 1)
                if side is None:
                    return None, why
                sides.append(side)
            if kind == 'ADD_SHADER':
                return _Closure.add(*sides), None
            fac, notes = mix_factor(node)
            if fac is None:                     # a cut-out: the side that is not clear
                fac = 1.0 if sides[0].opacity < sides[1].opacity else 0.0
                solid = sides[int(fac)]
                if fac == 1.0 and sides[0].opacity == 0.0 and self._cut_out(
                        solid, _follow(node.inputs[0])):
                    notes = []
            mixed = _Closure.mix(sides[0], sides[1], fac)
            mixed.warnings += notes
            return mixed, None
        what = (f"node group '{node.node_tree.name}'" if kind == 'GROUP' and node.node_tree
                else f"a {node.bl_label} node")
        return None, (f"surface is {what}, not a Principled, Diffuse or Emission shader (or a "
                      f"mix of them)")

    def _colour(self, mat, socket, label):
        """(rgb, texture or None, UV map, warnings, colour attribute or None) of a colour
        socket: its value, an Image Texture or a colour attribute (a Color Attribute node, an
        Attribute node's Color) linked straight to it; else the material's viewport display
        colour."""
        linked = _follow(socket)
        attr = colour_attribute(linked)
        if attr is not None:    # its colour in a Mix or Add Shader's: unknown, the default
            return DEFAULT_ALBEDO, None, None, [], attr
        rgb = _rgb(socket)
        tex, uv_map, notes, unsupported = self._linked_texture(socket, label)
        if unsupported:                   # _convert_material says what it used instead
            rgb = _display_colour(mat)
            self._unread.append(notes.pop())
        return rgb, tex, uv_map, notes, None

    def _normal_map(self, c, socket):
        """A tangent-space Normal Map node into a shader's Normal, its Color an Image Texture
        linked straight in: the closure's normal_tex and Strength (the G-buffer's shading
        normal, as Cycles'); or a Bump node (_bump); other normal inputs (object or world space)
        are left out with a warning: the geometric normal."""
        src = _follow(socket)
        if src is None:
            return
        node = src[0]
        if node.type == 'BUMP':
            self._bump(c, node)
            return
        if node.type != 'NORMAL_MAP' or node.space != 'TANGENT':
            what = (f"a {node.bl_label} node" if node.type != 'NORMAL_MAP'
                    else f"a Normal Map in {node.space.lower().replace('_', ' ')} space")
            c.warnings.append(f"Normal is driven by {what} (not supported); the geometric "
                              f"normal is used")
            return
        strength, driven = _value(node, "Strength", default=1.0)
        if driven:
            c.warnings.append(f"the Normal Map's Strength is driven by a node (not supported); "
                              f"using its value {strength:g}")
        tex, uv_map, notes, unsupported = self._linked_texture(node.inputs["Color"],
                                                               "Normal Map Color")
        if unsupported:
            notes[-1] += "; the geometric normal is used"
        c.warnings += notes
        if tex is None:
            return
        c.normal_tex, c.normal_strength = tex, strength
        c.uv_maps.append(node.uv_map or uv_map)

    def _bump(self, c, node):
        """A Bump node whose Height is an Image Texture linked straight in (its Color as Blender
        turns a colour into a value, Rec. 709 luminance, or its Alpha): the closure's normal_tex
        is that height times Distance (negated by Invert) and normal_strength its Strength; the
        G-buffer perturbs the normal by the height's screen derivatives as Cycles' bump does by
        its ray differentials (gbuffer.glsl bumped). A normal into the Bump node is left out."""
        strength, driven = _value(node, "Strength", default=1.0)
        distance, driven_d = _value(node, "Distance", default=1.0)
        if driven or driven_d:
            c.warnings.append(f"the Bump node's Strength or Distance is driven by a node (not "
                              f"supported); using {strength:g} and {distance:g}")
        if _follow(node.inputs["Normal"]) is not None:
            c.warnings.append("a normal into the Bump node is not read; the bump is applied to "
                              "the geometric normal")
        tex, uv_map, notes, unsupported = self._linked_texture(node.inputs["Height"],
                                                               "Bump Height")
        if unsupported:
            notes[-1] += "; the geometric normal is used"
        c.warnings += notes
        if tex is None or self.dry:
            return
        t = np.asarray(tex, np.float32)
        height = (t[..., :3] @ np.array(LUMINANCE, np.float32) if t.ndim == 3 and t.shape[2] >= 3
                  else (t[..., 0] if t.ndim == 3 else t))
        scale = -distance if getattr(node, "invert", False) else distance
        c.normal_tex = np.ascontiguousarray(height * np.float32(scale))
        c.normal_strength, c.bump = min(max(strength, 0.0), 1.0), True
        c.uv_maps.append(uv_map)

    def _cut_out(self, c, alpha) -> bool:
        """Whether `alpha` (what drives an Alpha or a Mix Factor) is the Alpha of the very image
        the closure's base colour reads: a cut-out (leaves, a fence), which the G-buffer
        discards where that alpha is under 0.5 (c.clip); the SDFs and cards keep the faces (the
        shadow cones let the holes' share through: materials.shadow_transmission)."""
        if alpha is None or c.base_tex is None:
            return False
        node, out = alpha
        if node.type != 'TEX_IMAGE' or out.name != "Alpha" or node.image is None:
            return False
        arr, _why = self.image_array(node.image, "Color")
        if arr is not c.base_tex or arr.ndim != 3 or arr.shape[2] != 4:
            return False
        c.clip = True
        c.warnings.append("is a cut-out (its Base Color image's Alpha): the camera sees through "
                          "its holes; its shadows let the holes' share of light through, evenly "
                          "(the holes' pattern is not cast), as the sky's and bounce light do")
        return True

    def _emission(self, c, colour_socket, strength_socket, colour_label, strength_label):
        strength = float(strength_socket.default_value)
        if _follow(strength_socket) is not None:
            c.warnings.append(f"{strength_label} is driven by a node (not supported); using "
                              f"its value {strength:g}")
        c.emission, c.strength = _rgb(colour_socket), strength
        if strength != 0.0:
            tex, uv_map, notes, unsupported = self._linked_texture(colour_socket, colour_label)
            if unsupported:
                notes[-1] += f"; using the {colour_label} value"
            c.warnings += notes
            if tex is not None:
                c.emit_tex = tex
                c.uv_maps.append(uv_map)

    def _principled(self, mat, node):
        c = _Closure()
        c.set_base(*self._colour(mat, node.inputs["Base Color"], "Base Color"), weight=1.0)
        cut = self._cut_out(c, _follow(node.inputs["Alpha"]))
        self._normal_map(c, node.inputs["Normal"])
        opacity, notes = principled_opacity(node, cut)
        c.reflect = tuple(opacity * x for x in c.reflect)
        self._emission(c, node.inputs["Emission Color"], node.inputs["Emission Strength"],
                       "Emission Color", "Emission Strength")
        c.opacity = opacity
        c.warnings += notes
        return c

    def _linked_texture(self, socket, label):
        """(array, UV map, warnings, unsupported) for an Image Texture linked straight to socket.

        unsupported: something else drives the socket (the caller names its fallback in the
        last warning). An image without pixels falls back to the socket's own value."""
        linked = _follow(socket)
        if linked is None:
            return None, None, [], False
        tex, why = self._socket_texture(linked, label)
        if tex is None:
            return None, None, [why], True
        notes = list(tex.notes)
        arr, why = self.image_array(tex.image, tex.output)
        if arr is None:
            return None, None, notes + [f"{label} {why}; using the {label} value"], False
        if self._mapping is False:           # the material's first texture
            self._mapping = tex.mapping
        elif not _same_mapping(self._mapping, tex.mapping):
            notes.append("the material's textures use different Mapping nodes; all are "
                         "sampled with the first's")
        return arr, tex.uv_map, notes + ([why] if why else []), False

    @staticmethod
    def _socket_texture(linked, socket_name):
        """The Image Texture linked straight to a socket, or (None, why not)."""
        node, output = linked
        if node.type != 'TEX_IMAGE':
            return None, f"{socket_name} is driven by a {node.bl_label} node (not supported)"
        if output.name not in ("Color", "Alpha"):
            return None, f"{socket_name} uses output '{output.name}' of '{node.name}'"
        if node.image is None:
            return None, f"{socket_name} texture node '{node.name}' has no image"
        notes, uv_map = [], None
        if node.projection != 'FLAT':
            notes.append(f"texture '{node.name}' uses {node.projection.lower()} projection "
                         f"(not supported); sampled with UVs")
        coords = _follow(node.inputs["Vector"])
        mapping = None
        if coords is not None and coords[0].type == 'MAPPING':
            mapping, why = uv_mapping(coords[0])
            if mapping is None:
                notes.append(f"texture '{node.name}': {why}; sampled with the UV map as it is")
            coords = _follow(coords[0].inputs["Vector"])
            if coords is None:           # a Mapping's own Vector is (0, 0, 0) when unlinked
                notes.append(f"texture '{node.name}' reads a Mapping node whose Vector is not "
                             f"linked (not supported); sampled with the UV map")
                mapping = None
        if coords is not None:
            src, out = coords
            if src.type == 'UVMAP':
                uv_map = src.uv_map or None
            elif not (src.type == 'TEX_COORD' and out.name == "UV"):
                notes.append(f"texture '{node.name}' takes coordinates from a {src.bl_label} "
                             f"node (not supported); sampled with the UV map")
                mapping = None
        return _Texture(node, output.name, uv_map, notes, mapping), None
