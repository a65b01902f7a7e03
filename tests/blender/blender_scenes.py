"""Small scenes and checks for the Blender tests; imported inside the bpy subprocess."""
from __future__ import annotations

import hashlib
from pathlib import Path

import bpy
import numpy as np


def empty_scene(voxel_density: float = 4.0, cache_dir: str | None = None):
    """A new empty file with low-resolution bake settings (fast tests), anti-aliasing off: the
    tests compare pixels with closed forms and point-sampled references (pixel masks from the
    unjittered G-buffer); tests/gpu/test_antialias.py and test_view_draw.py turn it on."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.lumen.bake.voxel_density = voxel_density
    scene.lumen.engine.aa_samples = 1
    if cache_dir is not None:
        scene.lumen.bake.cache_dir = str(cache_dir)
    return scene


def link(obj, collection=None):
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def cube(name: str, size: float = 1.0, location=(0, 0, 0)):
    bpy.ops.mesh.primitive_cube_add(size=size, location=location)
    obj = bpy.context.object
    obj.name = name
    return obj


def sphere(name: str, location=(0, 0, 0), subdivide: int = 0):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=4, radius=0.5, location=location)
    obj = bpy.context.object
    obj.name = name
    if subdivide:
        obj.modifiers.new("Subdivision", 'SUBSURF').levels = subdivide
    return obj


def loose_vertices(name: str):
    """A mesh object with vertices and no faces."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [])
    return link(bpy.data.objects.new(name, mesh))


def set_nan_vertex(obj):
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    co[0] = np.nan
    obj.data.vertices.foreach_set("co", co)
    obj.data.update()


def collection_instancer(name: str, collection, location=(0, 0, 0)):
    empty = bpy.data.objects.new(name, None)
    empty.instance_type = 'COLLECTION'
    empty.instance_collection = collection
    empty.location = location
    return link(empty)


def geometry_nodes_scatter(name: str, instance_node: str = "GeometryNodeMeshIcoSphere",
                           keep_plane: bool = True):
    """A plane whose geometry nodes put one mesh instance on each of its 4 vertices and keep
    the plane itself (Join Geometry; keep_plane=False: only the instances, so the object's own
    mesh has no faces)."""
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plane = bpy.context.object
    plane.name = name
    tree = bpy.data.node_groups.new(name, 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = tree.nodes, tree.links
    group_in, group_out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    on_points, mesh = nodes.new("GeometryNodeInstanceOnPoints"), nodes.new(instance_node)
    join = nodes.new("GeometryNodeJoinGeometry")
    links.new(group_in.outputs[0], on_points.inputs["Points"])
    links.new(mesh.outputs["Mesh"], on_points.inputs["Instance"])
    links.new(on_points.outputs["Instances"], join.inputs[0])
    if keep_plane:
        links.new(group_in.outputs[0], join.inputs[0])
    links.new(join.outputs[0], group_out.inputs[0])
    plane.modifiers.new("Scatter", 'NODES').node_group = tree
    return plane


def aimed_camera(location, target=(0.0, 0.0, 0.0), name="Cam"):
    """A new camera at `location` looking at `target`, made the scene camera."""
    import mathutils

    cam = link(bpy.data.objects.new(name, bpy.data.cameras.new(name)))
    cam.location = location
    cam.rotation_euler = (mathutils.Vector(target) - cam.location).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = cam
    return cam


def bake(op=None, **kwargs):
    """Run an operator; returns (result set or None, error text or None)."""
    op = op or bpy.ops.lumen.bake
    try:
        return sorted(op(**kwargs)), None
    except RuntimeError as exc:
        return None, str(exc)


def render_lumen(save=(), quality: str = "LOW", exr: str | None = None):
    """F12 with Lumen GI (render quality `quality`, anti-aliasing off: one G-buffer sample at
    each pixel centre, as Cycles' 0.01 px filter). Saves LAST_RENDER's images named in `save`
    as <name>.npy (rows bottom first), writes the render as the multilayer EXR `exr` when
    given, and returns LAST_RENDER; a render error fails the snippet with its traceback."""
    from lumen_gi.gpu_shaders import engine

    scene = bpy.context.scene
    scene.render.engine = "LUMEN_GI"
    scene.lumen.engine.render_quality = quality
    scene.lumen.engine.aa_samples = 1
    if exr is not None:
        _multilayer(scene, exr)
    bpy.ops.render.render(write_still=exr is not None)
    R = engine.LAST_RENDER
    assert "error" not in R, R.get("traceback", R.get("error"))
    for name in save:
        np.save(f"{name}.npy", R[name])
    return R


def render_cycles(samples: int = 16, exr: str | None = None, passes=(), bounces=None):
    """The same scene by Cycles on the CPU (no denoiser, a 0.01 px filter: pixel centres):
    the multilayer EXR `exr` with the View Layer passes named in `passes` (use_pass_* names),
    or, without `exr`, Combined as cycles.npy (float32 [h, w, 4], rows bottom first)."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.device = "CPU"
    scene.render.filter_size = 0.01
    if bounces is not None:
        scene.cycles.max_bounces = bounces
    layer = scene.view_layers[0]
    for name in passes:
        setattr(layer, name, True)
    if exr is not None:
        _multilayer(scene, exr)
        bpy.ops.render.render(write_still=True)
        return
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = 'IMAGE'
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    scene.render.filepath = str(Path("cycles.exr").resolve())
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(scene.render.filepath)
    px = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(px)
    w, h = img.size
    np.save("cycles.npy", px.reshape(h, w, 4))


def _multilayer(scene, path):
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):            # Blender 5.0 on
        settings.media_type = 'MULTI_LAYER_IMAGE'
    else:
        settings.file_format = 'OPEN_EXR_MULTILAYER'
    settings.color_depth = '32'
    scene.render.filepath = str(Path(path).resolve())


def snapshot(folder) -> dict:
    """sha256 of every file in a folder, to prove a failed bake touched nothing."""
    folder = Path(folder)
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir()) if p.is_file()}


def scene_stats(scene) -> dict:
    """The scene's last-bake statistics (scene.lumen.last_bake) as a dict."""
    s = scene.lumen.last_bake
    return {k: getattr(s, k) for k in ("objects", "unique_meshes", "bricks", "bytes", "reused",
                                       "seconds", "status")}


def closed_room(mat, half=(1.5, 1.2, 1.0), t: float = 0.2):
    """Six slabs `t` thick around the box [-half, half], all of material `mat` (the closed room
    of the GI tests: every ray from inside hits a wall). Returns the walls, named Wall<axis><+/->."""
    walls = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            size = [2 * h + 2 * t for h in half]
            size[axis] = t
            loc = [0.0, 0.0, 0.0]
            loc[axis] = sign * (half[axis] + t / 2)
            bpy.ops.mesh.primitive_cube_add(size=1.0, location=loc)
            ob = bpy.context.object
            ob.name = f"Wall{axis}{'+' if sign > 0 else '-'}"
            ob.scale = size
            bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
            ob.data.materials.append(mat)
            walls.append(ob)
    return walls


# -- materials and images -----------------------------------------------------------------------

def principled(name: str, base=(0.8, 0.8, 0.8), emission=None, strength: float = 0.0):
    """A new material (Principled BSDF -> Material Output, Blender's default tree)."""
    mat = bpy.data.materials.new(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
    bsdf.inputs["Emission Strength"].default_value = strength
    return mat


def image_texture(mat, image, socket: str = "Base Color", uv_map: str | None = None):
    """Link an Image Texture of `image` straight into the Principled socket (optionally through
    a UV Map node naming `uv_map`); returns the texture node."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs[socket])
    if uv_map is not None:
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_map
        links.new(uv.outputs["UV"], tex.inputs["Vector"])
    return tex


def replace_surface(mat, node_type: str):
    """Feed the Material Output from a new node of `node_type` instead of the Principled BSDF."""
    nodes = mat.node_tree.nodes
    node = nodes.new(node_type)
    mat.node_tree.links.new(node.outputs[0], nodes["Material Output"].inputs["Surface"])
    return node


def checker_png(path, width: int = 8, height: int = 4):
    """Save a small RGBA PNG with distinct byte values per texel and load it back from disk, so
    it has a filepath like a user's texture. Returns (image, its pixels as (H, W, 4) floats in
    Blender's order, row 0 at v = 0)."""
    rng = np.random.default_rng(7)
    px = (rng.integers(0, 256, (height, width, 4)) / 255.0).astype(np.float32)
    px[0, 0, :3] = (0.0, 128 / 255, 1.0)       # both ends and the middle of the sRGB curve
    img = bpy.data.images.new("checker-src", width, height, alpha=True)
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = str(path)
    img.file_format = 'PNG'
    img.save()
    bpy.data.images.remove(img)
    img = bpy.data.images.load(str(path))
    return img, px


def corner_values(mesh, values_of_loop):
    """(T, 3, k) per-triangle-corner values by a plain Python loop (the test's reference)."""
    return np.array([[values_of_loop(li) for li in tri.loops] for tri in mesh.loop_triangles])


def add_uv_map(obj, name: str, scale=(1.0, 1.0), offset=(0.0, 0.0)):
    """A new UV map: the first one's UVs scaled and offset (so the two differ)."""
    mesh = obj.data
    base = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers[0].uv.foreach_get("vector", base)
    layer = mesh.uv_layers.new(name=name)
    uv = base.reshape(-1, 2) * np.float32(scale) + np.float32(offset)
    layer.uv.foreach_set("vector", uv.ravel())
    return layer


# -- panels -------------------------------------------------------------------------------------

class RecordingLayout:
    """A stand-in for bpy.types.UILayout (headless Blender has no UI to draw into): records
    ('prop', name) / ('operator', idname) / ('label', text) / ('progress', text) and checks every
    property and operator name against the real registered RNA, so a typo fails the test."""
    use_property_split = use_property_decorate = False
    active = enabled = True

    def __init__(self, log):
        self.log = log

    def _child(self, *a, **k):
        return RecordingLayout(self.log)
    column = row = box = split = _child

    def prop(self, data, name, **k):
        assert name in data.bl_rna.properties, name
        self.log.append(("prop", name))

    def operator(self, idname, **k):
        mod, name = idname.split(".")
        getattr(getattr(bpy.ops, mod), name).get_rna_type()
        self.log.append(("operator", idname))

    def label(self, **k):
        self.log.append(("label", k.get("text")))

    def progress(self, **k):
        self.log.append(("progress", k.get("text")))


def draw_panels(classes, context=None) -> dict:
    """Draw each panel class (parents before children, as registered) whose poll passes and whose
    parent was drawn, as Blender would; returns {class name: [(kind, name), ...]}."""
    context = context or bpy.context
    drawn = {}
    for cls in classes:
        parent = getattr(cls, "bl_parent_id", "")
        if parent and parent not in drawn:
            continue
        if hasattr(cls, "poll") and not cls.poll(context):
            continue
        log = []
        # Panels cannot be instantiated outside Blender's UI: draw with a stand-in `self` that
        # has the class's methods (begin, ...) and a recording layout.
        methods = {k: v for c in reversed(cls.__mro__) if c.__module__ == cls.__module__
                   for k, v in vars(c).items() if callable(v) and not k.startswith("__")}
        cls.draw(type("P", (), {**methods, "layout": RecordingLayout(log)})(), context)
        drawn[cls.__name__] = log
    return drawn


def run_in_gpu_context(job):
    """Call job() inside a RenderEngine render() that holds Blender's GPU context (what the gpu
    module's textures, compute shaders and read-backs need headless), on a 4x4 render of the
    current scene with a camera; re-raise whatever job() raised, with its traceback."""
    import traceback

    errors = []

    class GPUJobEngine(bpy.types.RenderEngine):
        bl_idname = "LUMEN_TEST_GPU_JOB"
        bl_label = "GPU job (tests)"
        bl_use_gpu_context = True

        def render(self, depsgraph):
            try:
                job()
            except Exception:
                errors.append(traceback.format_exc())
            self.end_result(self.begin_result(0, 0, 4, 4))

    bpy.utils.register_class(GPUJobEngine)
    try:
        scene = bpy.context.scene
        if scene.camera is None:
            cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
            scene.collection.objects.link(cam)
            scene.camera = cam
        scene.render.engine = GPUJobEngine.bl_idname
        scene.render.resolution_x = scene.render.resolution_y = 4
        bpy.ops.render.render()
    finally:
        bpy.utils.unregister_class(GPUJobEngine)
    assert not errors, errors[0]
