"""Blender scene -> `ObjectInput`s: every visible mesh instance of the evaluated depsgraph.

Evaluated meshes are used, so modifiers, geometry nodes, collection instances and particle
instances bake as they show in the viewport. Every per-vertex, per-corner and per-triangle array
is read with `foreach_get` (one C copy each, no Python loop) and gathered with numpy by the
loop triangles' vertex and loop indices. Arrays are extracted once per evaluated mesh (and per
distinct set of materials on it): linked duplicates without modifiers and every instance of the
same geometry share them, and the bake's content hash then bakes them once.

Materials are read by material_nodes.py (the Extractor is its MaterialReader; the warnings it
records name the objects, and `extract_scene` returns them for the operator to report). Here
they act on the mesh: faces of see-through materials are left out (clear_faces), colour
attributes are read per corner (corner_colours), Mapping nodes map the UVs and normal maps get
Blender's tangents (corner_tangents).

The render engine does not call `extract_scene` every frame: its `ExtractionCache` keeps each
unique mesh's MeshData between frames and re-reads only what view_update found in
depsgraph.updates (and everything on its first frame: F12 makes a new one per render).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..lumen_addon.bake import ObjectInput
from ..lumen_addon.materials import SEE_THROUGH, Material, shadow_transmission
from .material_nodes import MaterialReader

_EMPTY_V = np.zeros((0, 3), np.float64)
_EMPTY_T = np.zeros((0, 3), np.int64)

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

class Extractor(MaterialReader):
    """One extraction pass: caches converted materials and images (textures are shared:
    material_nodes.MaterialReader) and collects warnings as {message: [object names]}."""

    def __init__(self):
        super().__init__()
        self._warnings = {}

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


# -- objects ------------------------------------------------------------------------------------

class MeshData:
    """Everything extracted from one evaluated mesh with one set of materials, and the warnings
    that apply to every object showing it. `see_through`: triangles left out because their
    material is see-through (clear_faces)."""

    def __init__(self, vertices, triangles, normals=None, uvs=None, material_ids=None,
                 materials=(), warnings=(), see_through: int = 0, colors=None, tangents=None,
                 transmission: float = 0.0):
        self.vertices, self.triangles = vertices, triangles
        self.transmission = float(transmission)   # light through its cut-outs' holes (shadows)
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
                if any(getattr(m, "normal_texture", None) is not None
                       and not getattr(m, "bump", False) for m in materials):
                    tangents = corner_tangents(mesh, loops, layer, warnings)
                slot_of = np.clip(ids, 0, max(len(slots) - 1, 0))
                for i, (a, b) in mappings.items():     # each material's Mapping node
                    sel = slot_of == i
                    uvs[sel] = (uvs[sel].astype(np.float64) @ a.T + b).astype(np.float32)
        return MeshData(vertices, triangles, normals, uvs, ids, materials, warnings, see_through,
                        colors, tangents,
                        shadow_transmission(vertices, triangles, uvs, ids, materials))
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
            casts_shadow=bool(getattr(source, "visible_shadow", True)),
            diffuse_visible=bool(getattr(source, "visible_diffuse", True)),
            shadow_transmission=data.transmission))
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
        self.shadow_pass = {}     # {instance name: (share of light its shadow lets pass, share
                                  # its GI rays pass)} of the last walk's instances that let
                                  # some pass (shadow_pass())
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
                casts_shadow=bool(getattr(source, "visible_shadow", True)),
                diffuse_visible=bool(getattr(source, "visible_diffuse", True)),
                shadow_transmission=data.transmission))
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
        # instances whose shadows let light pass (the same dict until the next walk: sync's check)
        self.shadow_pass = shadow_pass(objects)
        return self.last

    def light_rows(self, depsgraph):
        """operators.lights.light_table, walked again only after a view_update (as update)."""
        if self.light_dirty or self.lights is None:
            from .lights import light_table
            self.lights, self.light_dirty = light_table(depsgraph), False
        return self.lights


def shadow_pass(objects) -> dict:
    """{name: (share of light its shadow lets pass, share its GI rays pass)} of the ObjectInputs
    that let some pass (scene_state.SceneState.sync: the object table's texel 9 y and z). The
    shadow's: 1 for one that casts no shadow (Ray Visibility > Shadow off), else its
    shadow_transmission (a cut-out's holes); the GI rays': 1 for one diffuse rays do not see
    (Ray Visibility > Diffuse off), else the holes'."""
    out = {}
    for o in objects:
        holes = min(max(float(o.shadow_transmission), 0.0), 1.0)
        share = 1.0 if not o.casts_shadow else holes
        gi = 1.0 if not o.diffuse_visible else holes
        if share > 0.0 or gi > 0.0:
            out[o.name] = (share, gi)
    return out


def extract_objects(depsgraph, view_layer=None):
    """ObjectInputs of every visible mesh instance (warnings dropped; see `extract_scene`)."""
    return extract_scene(depsgraph, view_layer)[0]


def register():
    pass


def unregister():
    pass
