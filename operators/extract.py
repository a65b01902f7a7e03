"""Blender scene -> `ObjectInput`s: every visible mesh instance of the evaluated depsgraph.

Evaluated meshes are used, so modifiers, geometry nodes, collection instances and particle
instances bake as they show in the viewport. Vertex and triangle arrays are read with
`foreach_get` (one C copy each, no Python loop) and extracted once per evaluated mesh: linked
duplicates without modifiers and every instance of the same geometry share the arrays, and the
bake's content hash then bakes them once.
"""
import numpy as np

from ..lumen_addon.bake import ObjectInput

_EMPTY_V = np.zeros((0, 3), np.float64)
_EMPTY_T = np.zeros((0, 3), np.int64)


def mesh_arrays(obj_eval):
    """(vertices (V,3) float64 local space, triangles (T,3) int64) of an evaluated mesh object."""
    mesh = obj_eval.to_mesh()
    if mesh is None:
        return _EMPTY_V, _EMPTY_T
    try:
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        tris = mesh.loop_triangles
        idx = np.empty(len(tris) * 3, np.int32)
        tris.foreach_get("vertices", idx)
    finally:
        obj_eval.to_mesh_clear()
    return co.reshape(-1, 3).astype(np.float64), idx.reshape(-1, 3).astype(np.int64)


def _visible(inst, view_layer):
    """Whether a depsgraph instance shows in the viewport.

    An instance's own source object may sit in a hidden or excluded collection (that is how
    collection instancing is usually set up), so instances follow their instancer's visibility.
    """
    if inst.is_instance:
        owner = inst.parent.original if inst.parent is not None else None
        return owner is None or owner.visible_get(view_layer=view_layer)
    return inst.show_self and inst.object.original.visible_get(view_layer=view_layer)


def extract_objects(depsgraph, view_layer=None):
    """Collect every visible mesh instance of `depsgraph` as an ObjectInput (world matrix copied).

    Names are the object's name, or `instancer/source.N` for instances, so errors and stats
    can point at what the user sees in the outliner.
    """
    view_layer = view_layer or depsgraph.view_layer
    cache = {}          # evaluated mesh pointer -> arrays
    counts = {}         # instancer name -> instances seen
    out = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != 'MESH' or not _visible(inst, view_layer):
            continue
        key = obj.data.as_pointer() if obj.data is not None else ("object", obj.as_pointer())
        arrays = cache.get(key)
        if arrays is None:
            arrays = cache[key] = mesh_arrays(obj)
        source = obj.original
        if inst.is_instance:
            parent = inst.parent.original.name if inst.parent is not None else "?"
            label = source.name if source.name != parent else (obj.data.name if obj.data else "mesh")
            n = counts[parent] = counts.get(parent, 0) + 1
            name = f"{parent}/{label}.{n:03d}"
        else:
            name = source.name
        props = getattr(source, "lumen", None)
        out.append(ObjectInput(
            name=name, vertices=arrays[0], triangles=arrays[1],
            matrix_world=np.array(inst.matrix_world, dtype=np.float64),
            two_sided=bool(props.two_sided) if props is not None else False,
            resolution_scale=float(props.resolution_scale) if props is not None else 1.0))
    return out


def register():
    pass


def unregister():
    pass
