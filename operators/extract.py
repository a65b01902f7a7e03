"""Blender scene -> `ObjectInput`s: every visible mesh instance of the evaluated depsgraph.

Evaluated meshes are used, so modifiers, geometry nodes, collection instances and particle
instances bake as they show in the viewport. Every per-vertex, per-corner and per-triangle array
is read with `foreach_get` (one C copy each, no Python loop) and gathered with numpy by the
loop triangles' vertex and loop indices. Arrays are extracted once per evaluated mesh (and per
distinct set of materials on it): linked duplicates without modifiers and every instance of the
same geometry share them, and the bake's content hash then bakes them once.

Materials become `lumen_addon.materials.Material`s the way Workbench and the cards need them:
a Principled BSDF feeding the active Material Output gives Base Color, Emission Color and
Emission Strength, each a value or an Image Texture linked straight to the socket (through
reroutes); a Diffuse BSDF its Color, an Emission shader its Color and Strength, Mix and Add
Shaders of these their weighted sum (_Closure), and glass, Alpha and Transparent BSDFs an
opacity (see-through faces are left out: clear_faces). Anything else falls back to the
material's viewport display colour. Nothing here
raises for bad materials: every fallback is recorded as a warning naming the object and the
material, and `extract_scene` returns those warnings for the operator to report.

The render engine does not call `extract_scene` every frame: its `ExtractionCache` keeps each
unique mesh's MeshData between frames and re-reads only what view_update found in
depsgraph.updates (and everything on its first frame: F12 makes a new one per render).
"""
from __future__ import annotations

import dataclasses
import threading

import numpy as np

from ..lumen_addon.bake import ObjectInput
from ..lumen_addon.materials import SEE_THROUGH, Material

_EMPTY_V = np.zeros((0, 3), np.float64)
_EMPTY_T = np.zeros((0, 3), np.int64)

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


# -- geometry -----------------------------------------------------------------------------------

def _read(collection, attr, count, dtype, width=1):
    out = np.empty(count * width, dtype)
    if count:
        collection.foreach_get(attr, out)
    return out if width == 1 else out.reshape(count, width)


def mesh_arrays(obj_eval):
    """(vertices (V,3) float64 local space, triangles (T,3) int64) of an evaluated mesh object."""
    mesh = obj_eval.to_mesh()
    if mesh is None:
        return _EMPTY_V, _EMPTY_T
    try:
        return _geometry(mesh)
    finally:
        obj_eval.to_mesh_clear()


def _geometry(mesh):
    co = _read(mesh.vertices, "co", len(mesh.vertices), np.float32, 3)
    tris = _read(mesh.loop_triangles, "vertices", len(mesh.loop_triangles), np.int32, 3)
    return co.astype(np.float64), tris.astype(np.int64)


def _corner_loops(mesh):
    """(T, 3) loop (corner) indices of the loop triangles."""
    return _read(mesh.loop_triangles, "loops", len(mesh.loop_triangles), np.int32, 3)


def corner_normals(mesh, loops):
    """(T, 3, 3) float32 per-corner normals (smooth/flat shading, sharp edges, custom normals)."""
    normals = _read(mesh.corner_normals, "vector", len(mesh.corner_normals), np.float32, 3)
    return normals[loops]


def material_indices(mesh):
    return _read(mesh.loop_triangles, "material_index", len(mesh.loop_triangles), np.int32)


def corner_tangents(mesh, loops, layer, warnings):
    """(T, 3, 4) float32 MikkTSpace tangents (xyz) and bitangent signs of `layer` (a UV map) at
    each triangle corner, as Blender computes them for its Normal Map node; None (with a
    warning) when Blender cannot (faces of more than four corners)."""
    try:
        mesh.calc_tangents(uvmap=layer.name)
    except RuntimeError as exc:
        warnings.append(f"normal maps ignored: Blender cannot compute tangents here "
                        f"({str(exc).strip()})")
        return None
    n = len(mesh.loops)
    tan = _read(mesh.loops, "tangent", n, np.float32, 3)
    sign = _read(mesh.loops, "bitangent_sign", n, np.float32)
    out = np.concatenate([tan, sign[:, None]], axis=1)
    return out[loops]


def corner_uvs(mesh, loops, layer):
    """(T, 3, 2) float32 UVs of `layer` (a MeshUVLoopLayer) at each triangle corner."""
    uv = _read(layer.uv, "vector", len(layer.uv), np.float32, 2)
    return uv[loops]


# -- materials ----------------------------------------------------------------------------------

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


def material_emits(mat) -> bool:
    """Whether `mat` emits as the bake reads it (a Principled BSDF's Emission Strength or an
    Emission shader's Strength, with a colour above black or an Image Texture linked to it,
    also inside the Mix and Add Shaders the conversion follows), without reading any image:
    cheap enough for the N-panel's estimate (bake.too_small_for_cards keeps an emitter's cards)."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return False
    out = tree.get_output_node('EEVEE') or tree.get_output_node('CYCLES')
    return _emits(_follow(out.inputs["Surface"]) if out is not None else None, 0)


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
        for s in sides:
            out.uv_maps += [u for u in s.uv_maps if u not in out.uv_maps]
            out.warnings += s.warnings
        textured = [(w * s.share, s) for s, w in zip(sides, weights)
                    if s.base_tex is not None or s.attr is not None]
        if textured:
            share, s = max(textured, key=lambda x: x[0])
            out.base_tex, out.attr, out.base, out.share = s.base_tex, s.attr, s.base, share
            out.clip = s.clip
        mapped = [s for s in sides if s.normal_tex is not None]
        if mapped:
            out.normal_tex, out.normal_strength = mapped[0].normal_tex, mapped[0].normal_strength
            if any(w > 0.0 and o is not s and max(o.reflect) > 0.0
                   for o, w in zip(sides, weights)):
                out.warnings.append("a Mix or Add Shader blends a texture with another "
                                    "surface's colour (not supported); using the texture")
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
                            normal_strength=float(self.normal_strength))
        return MaterialInfo(material, self.uv_maps, bool(self.uv_maps), self.warnings,
                            attribute=self.attr)


DISPLAY_COLOUR = "using its viewport display colour"
# what a colour attribute's reflected light counts for in a Mix or Add Shader's colour (unknown
# per material; the default albedo)
ATTRIBUTE_MEAN = (0.8, 0.8, 0.8)


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


def corner_colours(mesh, name, triangles, loops):
    """(T, 3, 3) float32 linear RGB of the attribute `name` ("" the render colour attribute)
    at each triangle corner, from its point, corner or face domain (byte colours linearised by
    Blender); None when the mesh has no such attribute of a colour, float or vector type."""
    if name:
        layer = mesh.attributes.get(name)
    else:                              # by name: an evaluated mesh may list them in another order
        ca = mesh.color_attributes
        default = getattr(ca, "default_color_name", "")
        layer = ca.get(default) if default else None
        if layer is None:
            i = ca.render_color_index
            layer = ca[i] if 0 <= i < len(ca) else ca.active_color
    if layer is None:
        return None
    n = len(layer.data)
    kind = layer.data_type
    if kind in ('FLOAT_COLOR', 'BYTE_COLOR'):
        vals = _read(layer.data, "color", n, np.float32, 4)[:, :3]
    elif kind == 'FLOAT':
        vals = np.repeat(_read(layer.data, "value", n, np.float32)[:, None], 3, axis=1)
    elif kind == 'FLOAT_VECTOR':
        vals = _read(layer.data, "vector", n, np.float32, 3)
    else:
        return None
    if layer.domain == 'POINT':
        return vals[triangles]
    if layer.domain == 'CORNER':
        return vals[loops]
    if layer.domain == 'FACE':
        poly = _read(mesh.loop_triangles, "polygon_index", len(mesh.loop_triangles), np.int32)
        return np.repeat(vals[poly][:, None], 3, axis=1)
    return None
_DRY_IMAGE = np.zeros((1, 1, 3), np.float32)


def bpy_materials():
    import bpy
    return list(bpy.data.materials)


def needs_capture(mat) -> bool:
    """Whether the extraction reads `mat` only in part (a shader or a colour input it does not
    follow), so that its colours come from material_capture. Loads no image."""
    tree = getattr(mat, "node_tree", None)
    if tree is None:
        return False
    out = tree.get_output_node('EEVEE') or tree.get_output_node('CYCLES')
    src = _follow(out.inputs["Surface"]) if out is not None else None
    if src is None:
        return False
    ex = Extractor(dry=True)
    closure, _why = ex._shader(mat, src[0], 0)
    return closure is None or bool(ex._unread)


class Extractor:
    """One extraction pass: caches converted materials and images (textures are shared) and
    collects warnings as {message: [object names]}."""

    def __init__(self, dry: bool = False):
        self.materials = {}     # material pointer -> MaterialInfo
        self.images = {}        # (image pointer, output) -> (array or None, reason)
        self._warnings = {}
        self._unread = []       # the material being converted: what it could not read
        self._mapping = False   # ... and its textures' Mapping (None: none; False: no texture)
        self.dry = dry          # only whether materials can be read: no image loaded, no capture

    # warnings ----------------------------------------------------------------------------------

    def warn(self, obj_name, message):
        self._warnings.setdefault(message, [])
        if obj_name not in self._warnings[message]:
            self._warnings[message].append(obj_name)

    def warnings(self):
        """[(object name, message)], one per distinct problem; more objects are counted."""
        out = []
        for message, names in self._warnings.items():
            who = names[0] if len(names) == 1 else f"{names[0]} (and {len(names) - 1} more objects)"
            out.append((who, message))
        return out

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
        tree = mat.node_tree
        if tree is None:
            return MaterialInfo(fallback, warnings=["has no shader nodes; using its viewport "
                                                    "display colour"])
        out = tree.get_output_node('EEVEE') or tree.get_output_node('CYCLES')
        if out is None:
            return MaterialInfo(fallback, warnings=["has no active Material Output node; using "
                                                    "its viewport display colour"])
        src = _follow(out.inputs["Surface"])
        if src is None:
            return MaterialInfo(fallback, warnings=["has nothing connected to the Material "
                                                    "Output's Surface; using its viewport "
                                                    "display colour"])
        self._unread, self._mapping = [], False
        closure, why = self._shader(mat, src[0], 0)
        if closure is None or self._unread:
            reason = why if closure is None else "; ".join(self._unread)
            means = None if self.dry else self._captured(mat)
            if means is not None:
                emits = means.emission_tex is not None
                info = MaterialInfo(
                    Material(name=mat.name, base_color=means.albedo,
                             base_color_texture=means.albedo_tex,
                             emission_color=means.emission if not emits else (1.0, 1.0, 1.0),
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

        hit = material_capture.remembered(mat)
        if hit is not None or threading.current_thread() is not threading.main_thread():
            return hit            # a job thread (the UI's F12) cannot render: display colour
        others = [m for m in bpy_materials() if m != mat and m.users and needs_capture(m)]
        return material_capture.means(mat, others)

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
        if attr is not None:
            return ATTRIBUTE_MEAN, None, None, [], attr
        rgb = _rgb(socket)
        tex, uv_map, notes, unsupported = self._linked_texture(socket, label)
        if unsupported:                   # _convert_material says what it used instead
            rgb = _display_colour(mat)
            self._unread.append(notes.pop())
        return rgb, tex, uv_map, notes, None

    def _normal_map(self, c, socket):
        """A tangent-space Normal Map node into a shader's Normal, its Color an Image Texture
        linked straight in: the closure's normal_tex and Strength (the G-buffer's shading
        normal, as Cycles'); other normal inputs (a Bump node, object or world space) are left
        out with a warning: the geometric normal."""
        src = _follow(socket)
        if src is None:
            return
        node = src[0]
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

    def _cut_out(self, c, alpha) -> bool:
        """Whether `alpha` (what drives an Alpha or a Mix Factor) is the Alpha of the very image
        the closure's base colour reads: a cut-out (leaves, a fence), which the G-buffer
        discards where that alpha is under 0.5 (c.clip); the SDFs and cards keep the faces."""
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
                          "its holes; its shadows and bounce light are the whole faces'")
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
            notes.append(f"the material's textures use different Mapping nodes; all are "
                         f"sampled with the first's")
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


# -- objects ------------------------------------------------------------------------------------

class MeshData:
    """Everything extracted from one evaluated mesh with one set of materials, and the warnings
    that apply to every object showing it. `see_through`: triangles left out because their
    material is see-through (clear_faces)."""

    def __init__(self, vertices, triangles, normals=None, uvs=None, material_ids=None,
                 materials=(), warnings=(), see_through: int = 0, colors=None, tangents=None):
        self.vertices, self.triangles = vertices, triangles
        self.colors = colors            # (T, 3, 3) colour attribute values (vertex_colors)
        self.tangents = tangents        # (T, 3, 4) tangent xyz, bitangent sign (normal maps)
        self.normals, self.uvs, self.material_ids = normals, uvs, material_ids
        self.materials = list(materials)
        self.warnings = list(warnings)
        self.see_through = int(see_through)


def clear_faces(materials, ids) -> np.ndarray | None:
    """bool [T]: the triangles whose material is see-through (opacity at or under
    SEE_THROUGH: glass, Alpha, a mix with a Transparent BSDF), or None when there are none.
    They are left out of everything the preview draws and traces, as Lumen leaves translucent
    surfaces out of its scene: light and the camera pass them (a glass pane drawn opaque kept
    the sun out of the room behind it)."""
    if not len(materials) or ids is None or not len(ids):
        return None
    clear = np.array([m.opacity <= SEE_THROUGH for m in materials], bool)
    if not clear.any():
        return None
    return clear[np.clip(ids, 0, len(materials) - 1)]


def _without(vertices, triangles, normals, ids, drop):
    """The arrays without the triangles `drop` marks, the vertices they alone used dropped too
    (numpy only)."""
    keep = ~drop
    tris = triangles[keep]
    used = np.unique(tris)
    remap = np.full(len(vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[tris], normals[keep], ids[keep], keep


def _uv_layer(mesh, name, mat_names, warnings):
    """The UV layer to sample textures with (None if the mesh has none)."""
    layers = mesh.uv_layers
    if not len(layers):
        warnings.append(f"image textures of {mat_names} need a UV map, but the mesh has "
                        f"none; using the material's colour values")
        return None
    default = next((layer for layer in layers if layer.active_render), layers[0])
    if name is None:
        return default
    layer = layers.get(name)
    if layer is None:
        warnings.append(f"image textures of {mat_names} use UV map '{name}', which the mesh "
                        f"does not have; using '{default.name}'")
        return default
    return layer


def extract_mesh(obj_eval, ex: Extractor, geometry_cache=None):
    """MeshData of an evaluated mesh object (its temporary mesh is released before returning).

    Only the material slots that some face uses are converted (unused ones get a placeholder,
    and their images are not loaded)."""
    slots = list(obj_eval.material_slots)
    mesh = obj_eval.to_mesh()
    if mesh is None:
        return MeshData(_EMPTY_V, _EMPTY_T)
    try:
        key = obj_eval.data.as_pointer() if obj_eval.data is not None else None
        geo = geometry_cache.get(key) if geometry_cache is not None and key else None
        if geo is None:
            loops = _corner_loops(mesh)
            geo = _geometry(mesh) + (loops, corner_normals(mesh, loops), material_indices(mesh))
            if geometry_cache is not None and key:
                geometry_cache[key] = geo
        vertices, triangles, loops, normals, ids = geo

        warnings, materials, uv_names, textured = [], [], [], []
        attributes = {}                   # slot -> colour attribute name its base colour reads
        mappings = {}                     # slot -> its textures' Mapping (A, b)
        used = set(np.unique(np.clip(ids, 0, len(slots) - 1)).tolist()) if slots else set()
        for i, slot in enumerate(slots):
            mat = slot.material
            if mat is None:
                if i in used:
                    warnings.append(f"material slot {i + 1} is empty; using default grey")
                materials.append(Material(name=f"(empty slot {i + 1})"))
                continue
            if i not in used:
                materials.append(Material(name=mat.name))
                continue
            info = ex.material_info(mat)
            warnings += [f"material '{mat.name}' {message}" for message in info.warnings]
            materials.append(info.material)
            if info.attribute is not None:
                attributes[i] = (mat.name, info.attribute)
            if info.mapping is not None:
                mappings[i] = info.mapping
            if info.textured:
                if not (info.captured and not len(mesh.uv_layers)):
                    textured.append(mat.name)
                for uv_name in info.uv_maps:
                    if uv_name not in uv_names:
                        uv_names.append(uv_name)

        colors = None
        if attributes:
            colors = np.zeros((len(triangles), 3, 3), np.float32)
            slot_of = np.clip(ids, 0, len(slots) - 1)
            for i, (mat_name, name) in attributes.items():
                vals = corner_colours(mesh, name, triangles, loops)
                if vals is None:
                    label = f"'{name}'" if name else "(the render colour attribute)"
                    warnings.append(f"material '{mat_name}' reads colour attribute {label}, "
                                    f"which the mesh does not have; black, as in Cycles")
                    continue
                sel = slot_of == i
                colors[sel] = vals[sel]
        drop = clear_faces(materials, ids)
        see_through = 0
        keep = None
        if drop is not None:
            see_through = int(drop.sum())
            vertices, triangles, normals, ids, keep = _without(vertices, triangles, normals, ids,
                                                               drop)
            loops = loops[keep]
            colors = colors[keep] if colors is not None else None
        uvs = tangents = None
        if textured and len(triangles):
            names = ("material " if len(textured) == 1 else "materials ") + ", ".join(
                f"'{n}'" for n in textured)
            if len(uv_names) > 1:
                listed = ", ".join(repr(n or "(active render)") for n in uv_names)
                warnings.append(f"image textures of {names} use different UV maps ({listed}); "
                                f"all are sampled with the first")
            layer = _uv_layer(mesh, uv_names[0], names, warnings)
            if layer is not None:
                uvs = corner_uvs(mesh, loops, layer)
                if any(getattr(m, "normal_texture", None) is not None for m in materials):
                    tangents = corner_tangents(mesh, loops, layer, warnings)
                slot_of = np.clip(ids, 0, max(len(slots) - 1, 0))
                for i, (a, b) in mappings.items():     # each material's Mapping node
                    sel = slot_of == i
                    uvs[sel] = (uvs[sel].astype(np.float64) @ a.T + b).astype(np.float32)
        return MeshData(vertices, triangles, normals, uvs, ids, materials, warnings, see_through,
                        colors, tangents)
    finally:
        obj_eval.to_mesh_clear()


def _visible(inst, view_layer):
    """Whether a depsgraph instance shows in the viewport.

    An instance's own source object may sit in a hidden or excluded collection (that is how
    collection instancing is usually set up), so instances follow their instancer's visibility.
    """
    if inst.is_instance:
        owner = inst.parent.original if inst.parent is not None else None
        return owner is None or owner.visible_get(view_layer=view_layer)
    return inst.show_self and inst.object.original.visible_get(view_layer=view_layer)


def mesh_instances(depsgraph, view_layer=None):
    """(depsgraph instance, its name) of every visible mesh instance that has faces, in
    depsgraph order.

    Names are the object's name, or `instancer/source.N` for instances, so errors and stats
    can point at what the user sees in the outliner. The bake's instances and every frame's
    placement use these names: an instance whose name the scene no longer yields has left it.
    """
    view_layer = view_layer or depsgraph.view_layer
    # F12's depsgraph holds what renders (objects hidden in the viewport only, by the eye or
    # Disable in Viewports, render in Cycles and EEVEE: F12 dropped them)
    rendering = getattr(depsgraph, "mode", "VIEWPORT") == 'RENDER'
    counts = {}         # instancer name -> instances seen
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != 'MESH' or not (inst.is_instance or inst.show_self if rendering
                                      else _visible(inst, view_layer)):
            continue
        if obj.data is not None and len(obj.data.polygons) == 0:
            # no surface (a geometry-nodes scatter's points, whose instances come as their
            # own entries; a vertex or edge helper): Cycles draws nothing of it, and the bake
            # refused the whole scene over it ("mesh has no faces")
            continue
        source = obj.original
        if inst.is_instance:
            parent = inst.parent.original.name if inst.parent is not None else "?"
            label = source.name if source.name != parent else (obj.data.name if obj.data else "mesh")
            n = counts[parent] = counts.get(parent, 0) + 1
            yield inst, f"{parent}/{label}.{n:03d}"
        else:
            yield inst, source.name


class LayerFlags:
    """What the view layer says of an instance for camera rays, asked once per object and
    instancer in a walk (a particle system's thousands of instances share one answer; an
    instance also takes its instancer's): `holdout` (Object > Visibility > Holdout or a holdout
    collection: Object.holdout_get covers both) and `indirect_only` (Cycles' Indirect Only
    collections: not seen by the camera, still casting and bouncing light, as visible_camera
    off)."""

    def __init__(self, depsgraph, view_layer=None):
        self.view_layer = view_layer or depsgraph.view_layer
        self.known = {}

    def _of(self, ob, what: str) -> bool:
        key = (ob.as_pointer(), what)
        hit = self.known.get(key)
        if hit is None:
            try:
                hit = bool(getattr(ob, what + "_get")(view_layer=self.view_layer))
            except (TypeError, RuntimeError, ReferenceError, AttributeError):
                # not in this view layer (or a Blender without it): the object's own flag
                hit = bool(getattr(ob, "is_holdout", False)) if what == "holdout" else False
            self.known[key] = hit
        return hit

    def _either(self, inst, what: str) -> bool:
        if self._of(inst.object.original, what):
            return True
        return bool(inst.is_instance and inst.parent is not None
                    and self._of(inst.parent.original, what))

    def holdout(self, inst) -> bool:
        return self._either(inst, "holdout")

    def indirect_only(self, inst) -> bool:
        return self._either(inst, "indirect_only")


def instance_matrices(depsgraph, view_layer=None) -> dict:
    """{name: world 4x4} of every visible mesh instance (extract_scene's names), without reading
    any mesh: the trace debug views place the bake with it."""
    return {name: np.array(inst.matrix_world, np.float64)
            for inst, name in mesh_instances(depsgraph, view_layer)}


GEOMETRY_TYPES = ('MESH', 'META', 'CURVE', 'FONT', 'SURFACE')   # evaluate to meshes we bake


def _is_viewport_node(tree, seen) -> bool:
    if tree is None or tree.as_pointer() in seen:
        return False
    seen.add(tree.as_pointer())
    return any(node.bl_idname == "GeometryNodeIsViewport"
               or (node.type == 'GROUP' and _is_viewport_node(node.node_tree, seen))
               for node in tree.nodes)


def renders_differently(obj) -> bool:
    """Whether an object evaluates differently in F12 than in the viewport (what the bake
    sees): a modifier shown in only one of them, subdivision or multires render levels,
    geometry nodes that ask Is Viewport, or a metaball's, curve's, text's or surface's own
    render resolution (a metaball's default is twice as fine as its viewport's)."""
    data = getattr(obj, "data", None)
    if obj.type == 'META' and data is not None and data.render_resolution != data.resolution:
        return True
    if obj.type in ('CURVE', 'FONT', 'SURFACE') and data is not None:
        for axis in ("u", "v") if obj.type == 'SURFACE' else ("u",):
            render = getattr(data, f"render_resolution_{axis}", 0)
            if render and render != getattr(data, f"resolution_{axis}", render):
                return True
    for mod in getattr(obj, "modifiers", ()):
        if mod.show_viewport != mod.show_render:
            return True
        if mod.type in ('SUBSURF', 'MULTIRES') and mod.levels != mod.render_levels:
            return True
        if mod.type == 'NODES' and _is_viewport_node(mod.node_group, set()):
            return True
    return False


def render_only_geometry(depsgraph) -> set:
    """Names of the objects whose F12 geometry is not what the bake saw (a render
    depsgraph evaluates modifiers at render settings; the bake, a viewport one): staleness
    cannot judge their content there. Empty for a viewport depsgraph."""
    if getattr(depsgraph, "mode", "VIEWPORT") != 'RENDER':
        return set()
    return {ob.original.name for ob in depsgraph.objects
            if ob.type in GEOMETRY_TYPES and renders_differently(ob.original)}


def extract_scene(depsgraph, view_layer=None):
    """(ObjectInputs of every visible mesh instance, [(object name, warning)]).

    Names are mesh_instances' (the object's, or `instancer/source.N`). World matrices are copied.
    """
    ex = Extractor()
    cache = {}          # (evaluated mesh pointer, material pointers) -> MeshData
    geometry = {}       # evaluated mesh pointer -> shared geometry arrays
    out = []
    flags = LayerFlags(depsgraph, view_layer)
    for inst, name in mesh_instances(depsgraph, view_layer):
        obj = inst.object
        source = obj.original
        mesh_key = obj.data.as_pointer() if obj.data is not None else ("object", obj.as_pointer())
        key = (mesh_key, tuple(s.material.as_pointer() if s.material else 0
                               for s in obj.material_slots))
        data = cache.get(key)
        if data is None:
            data = cache[key] = extract_mesh(obj, ex, geometry)
        for message in data.warnings:
            ex.warn(name, message)
        if not len(data.triangles):       # all see-through (a glass pane): nothing to draw
            continue
        props = getattr(source, "lumen", None)
        out.append(ObjectInput(
            name=name, vertices=data.vertices, triangles=data.triangles,
            matrix_world=np.array(inst.matrix_world, dtype=np.float64),
            two_sided=bool(props.two_sided) if props is not None else False,
            resolution_scale=float(props.resolution_scale) if props is not None else 1.0,
            normals=data.normals, uvs=data.uvs, material_ids=data.material_ids,
            materials=data.materials, colors=data.colors, tangents=data.tangents,
            camera_visible=(bool(getattr(source, "visible_camera", True))
                            and not flags.indirect_only(inst)),
            holdout=flags.holdout(inst),
            casts_shadow=bool(getattr(source, "visible_shadow", True))))
    if getattr(depsgraph, "mode", "VIEWPORT") != 'RENDER':
        for name in hidden_renderable(view_layer or depsgraph.view_layer):
            ex.warn(name, "hidden in the viewport, so not baked; F12 renders it without its "
                          "shadows and bounce light: show it and press Bake")
    return out, ex.warnings()


def hidden_renderable(view_layer) -> list:
    """Names of the objects that F12 renders but the viewport hides (the eye, Disable in
    Viewports): a viewport depsgraph does not evaluate them, so the bake cannot hold them."""
    return [obj.name for obj in view_layer.objects
            if obj.type in GEOMETRY_TYPES and not obj.hide_render
            and not obj.visible_get(view_layer=view_layer)
            and all(not c.hide_render for c in obj.users_collection)
            and not (obj.type == 'MESH' and not obj.modifiers and not obj.data.polygons)]


def mesh_key(inst) -> tuple:
    """What identifies an instance's evaluated mesh + materials across frames (ExtractionCache):
    the original Mesh's name when the object evaluates to it unchanged (linked duplicates share
    it), else the object's own name (modifiers or shape keys give each object its mesh), and
    the names of its material slots' materials. An instance (collection, particles, geometry
    nodes) is keyed by its evaluated mesh's pointer as well: one instancer can show several
    meshes under one source object, and a re-evaluated one is then simply read again."""
    obj = inst.object
    source = obj.original
    data = getattr(source, "data", None)
    if inst.is_instance:
        geo = ("instance", source.name, obj.data.name if obj.data is not None else "",
               obj.data.as_pointer() if obj.data is not None else 0)
    elif data is None or len(obj.modifiers) or getattr(data, "shape_keys", None) is not None:
        geo = ("object", source.name)
    else:
        geo = ("mesh", data.name)
    return geo + (tuple(s.material.name if s.material else "" for s in obj.material_slots),)


class _Cached:
    """A MeshData kept between frames and what invalidates it: the outliner names of the
    objects and meshes it came from, its materials, whether it samples image textures, and a
    cheap signature of the evaluated mesh (vertex and face counts) checked every frame."""

    def __init__(self, data, objects, mesh, materials, signature):
        self.data, self.objects, self.mesh = data, objects, mesh
        self.materials, self.signature = materials, signature
        self.textured = data.uvs is not None


def _signature(obj) -> tuple:
    data = obj.data
    return (len(data.vertices), len(data.polygons)) if data is not None else (0, 0)


class ExtractionCache:
    """The scene's extraction kept by a render engine instance between frames, re-read only
    where the depsgraph said something changed (view_update calls `mark` with the names it
    found in depsgraph.updates); everything on the first frame, on F12 (a new cache per render)
    and when unsure. A frame after a view_update (`mark`) walks every instance for its name, key
    and matrix (what Blender's depsgraph gives only per instance), but reads no mesh data unless
    a mesh is new, edited, re-materialled or changed its vertex/face counts. A frame with no
    view_update since the last walk (a still redraw: navigation, progressive refinement) returns
    the last walk's result without walking: Blender calls view_update before a draw whenever the
    depsgraph changed, and the walk is a Python loop over every instance (24 ms at 1,000,
    bench/object_scaling.py). `walked` says whether the last update walked; `reads` counts the
    meshes read by the last update (tests: a still frame reads none)."""

    def __init__(self):
        self.cache = {}           # mesh_key -> _Cached
        self.everything = True
        self.objects, self.meshes, self.materials = set(), set(), set()
        self.images = False
        self.reads = 0            # meshes read by the last update
        self.reads_total = 0
        self.names = None         # instance names of the last update
        self.changed = True       # the last update read a mesh or the instance set changed
        self.dirty = True         # a view_update since the last walk (or none walked yet)
        self.walked = True        # the last update walked the depsgraph
        self.last = None          # the last walk's result
        self.matrices = {}        # {instance name: world 4x4} of the last walk (one dict object)
        self.no_shadow = frozenset()  # instance names that cast no shadow (the last walk's)
        self.lights = None        # light_table rows of the last light walk
        self.light_dirty = True
        self.moved = set()        # objects that only moved since the last update (mark_moved)
        self.index = {}           # {instance name: its index in the last walk}
        self.instancers = set()   # objects whose instances the last walk listed

    def mark(self, objects=(), meshes=(), materials=(), images=False, everything=False):
        """Objects with a geometry update, meshes with one, edited materials (names), any image
        edited, or unsure (everything is read again): the next update re-reads what they
        concern. Any call (every view_update makes one) lets the next update walk again."""
        self.dirty = self.light_dirty = True
        self.objects.update(objects)
        self.meshes.update(meshes)
        self.materials.update(materials)
        self.images = self.images or bool(images)
        self.everything = self.everything or bool(everything)

    def mark_lights(self):
        """Only lights changed (their objects or data, view_update): the next light_rows reads
        them again, and the next update returns the last walk without walking the meshes (a
        light dragged among 1,000 objects walked all of them each redraw)."""
        self.light_dirty = True

    def mark_moved(self, names):
        """Objects (names) that only moved, none of them an instancer (view_update: updates that
        are all transforms of such objects): unless something else is marked first, the next
        update reads only their new matrices into the last walk's result instead of walking
        every instance again (the walk: 14 ms of each redraw of a drag among 1,000 objects,
        bench/object_scaling.py --drag). An object the last walk did not list (hidden, a
        camera, an empty) is passed over: a move does not change what is listed. One whose
        instances the last walk listed walks again (a geometry-nodes scatter is no
        `is_instancer`, yet its instances move with it)."""
        self.light_dirty = True
        self.moved.update(names)

    def _move_in_place(self, depsgraph) -> bool:
        """Apply mark_moved's objects to the last walk's result (a new result tuple, matrices
        array and `matrices` dict: what sync and the G-buffer compare by identity); False when
        one of them cannot be found (then the caller walks)."""
        if self.moved & self.instancers:
            return False          # its instances moved too (geometry nodes: not is_instancer)
        objects, warnings, keys, meshes, mats, visible, holdout = self.last
        objects, mats, matrices = list(objects), mats.copy(), dict(self.matrices)
        found = getattr(depsgraph, "objects", None)
        for name in self.moved:
            i = self.index.get(name)
            if i is None:
                continue
            ev = found.get(name) if found is not None else None
            if ev is None:
                return False
            m = np.array(ev.matrix_world, dtype=np.float64)
            mats[i] = m
            objects[i] = dataclasses.replace(objects[i], matrix_world=m)
            matrices[name] = m
        self.last = (objects, warnings, keys, meshes, mats, visible, holdout)
        self.matrices = matrices
        self.moved = set()
        return True

    def _invalidate(self):
        if self.everything:
            self.cache = {}
        elif self.objects or self.meshes or self.materials or self.images:
            self.cache = {k: c for k, c in self.cache.items()
                          if not (c.objects & self.objects or c.mesh in self.meshes
                                  or c.materials & self.materials
                                  or (self.images and c.textured))}
        self.everything, self.images = False, False
        self.objects, self.meshes, self.materials = set(), set(), set()

    def update(self, depsgraph, view_layer=None):
        """(ObjectInputs, warnings, keys, MeshData by key, matrices float64 [n, 4, 4], camera
        visibility bool [n], holdout bool [n]) of every visible mesh instance, as
        extract_scene's."""
        if not self.dirty and self.last is not None and (
                not self.moved or self._move_in_place(depsgraph)):
            self.walked, self.changed, self.reads = False, False, 0
            return self.last
        self.moved = set()
        self._invalidate()
        ex = Extractor()
        geometry = {}
        used, keys, objects, matrices, visible = {}, [], [], [], []
        reads = 0
        flags = LayerFlags(depsgraph, view_layer)
        instancers = set()
        for inst, name in mesh_instances(depsgraph, view_layer):
            obj = inst.object
            if inst.is_instance and inst.parent is not None:
                instancers.add(inst.parent.original.name)
            key = mesh_key(inst)
            hit = used.get(key)
            if hit is None:
                hit = self.cache.get(key)
                sig = _signature(obj)
                if hit is None or hit.signature != sig:
                    source = obj.original
                    owners = {source.name}
                    if inst.is_instance and inst.parent is not None:
                        owners.add(inst.parent.original.name)
                    data = getattr(source, "data", None)
                    hit = _Cached(extract_mesh(obj, ex, geometry), owners,
                                  data.name if data is not None else None, set(key[-1]), sig)
                    reads += 1
                used[key] = hit
            data = hit.data
            for message in data.warnings:
                ex.warn(name, message)
            if not len(data.triangles):   # all see-through (a glass pane): nothing to draw
                continue
            source = obj.original
            props = getattr(source, "lumen", None)
            m = np.array(inst.matrix_world, dtype=np.float64)
            cam = bool(getattr(source, "visible_camera", True)) and not flags.indirect_only(inst)
            keys.append(key)
            matrices.append(m)
            visible.append(cam)
            objects.append(ObjectInput(
                name=name, vertices=data.vertices, triangles=data.triangles, matrix_world=m,
                two_sided=bool(props.two_sided) if props is not None else False,
                resolution_scale=float(props.resolution_scale) if props is not None else 1.0,
                normals=data.normals, uvs=data.uvs, material_ids=data.material_ids,
                materials=data.materials, colors=data.colors, tangents=data.tangents,
                camera_visible=cam,
                holdout=flags.holdout(inst),
                casts_shadow=bool(getattr(source, "visible_shadow", True))))
        names = [o.name for o in objects]
        self.changed = bool(reads) or names != self.names
        self.names, self.cache = names, used
        self.reads = reads
        self.reads_total += reads
        meshes = {k: c.data for k, c in used.items()}
        mats = np.stack(matrices) if matrices else np.zeros((0, 4, 4))
        self.dirty, self.walked = False, True
        self.last = (objects, ex.warnings(), keys, meshes, mats, np.array(visible, bool),
                     np.array([o.holdout for o in objects], bool))
        self.matrices = {o.name: o.matrix_world for o in objects}
        self.index = {name: i for i, name in enumerate(names)}
        self.instancers = instancers
        # instances that cast no shadow (the same object until the next walk: sync's check)
        self.no_shadow = frozenset(o.name for o in objects if not o.casts_shadow)
        return self.last

    def light_rows(self, depsgraph):
        """operators.lights.light_table, walked again only after a view_update (as update)."""
        if self.light_dirty or self.lights is None:
            from .lights import light_table
            self.lights, self.light_dirty = light_table(depsgraph), False
        return self.lights


def extract_objects(depsgraph, view_layer=None):
    """ObjectInputs of every visible mesh instance (warnings dropped; see `extract_scene`)."""
    return extract_scene(depsgraph, view_layer)[0]


def register():
    pass


def unregister():
    pass
