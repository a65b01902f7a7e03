"""The scene's world -> an equirectangular radiance map -> lumen_addon.sky.SkyMaps (no gpu import).

Any node tree: a world that is not one flat colour is rendered by Cycles through a panoramic
equirectangular camera (1024 x 512, a few samples, in a scratch scene that is removed after),
so an HDRI, a Sky Texture, a Mapping rotation or a node group evaluate exactly as Cycles does.
A flat colour (no nodes, or a Background whose Color and Strength are not linked) needs no
render. Captures are remembered by the world's content signature (`signature`: every node's
inputs, properties, images and links), so a capture happens when the world changes, never per
frame; up to four worlds are kept.

Cycles is only called on Blender's main thread (a headless `bpy.ops.render.render()`, the
viewport's callbacks, a timer). In the UI, F12 renders in a job thread, so the capture is made
ahead: a depsgraph handler sees the world (or an image, or a node tree) change in a scene that
renders with Lumen GI, and a timer captures it on the main thread; so does loading a file. A job
thread that still finds no capture uses the flat fallback (the Background's colour) with a note.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import threading
from collections import OrderedDict

import bpy
import numpy as np

from ..lumen_addon import sky

CAPTURE_SIZE = (1024, 512)
CAPTURE_SAMPLES = 4
_MAPS = OrderedDict()          # signature -> SkyMaps (memo of derived data, not render state)
_KEEP = 4
_PENDING = set()
# Nodes whose output in the capture is not what lights the scene: the capture sees camera rays.
_VIEW_DEPENDENT = {"LIGHT_PATH": "it tells camera rays from light rays, and the capture sees "
                                 "only camera rays",
                   "TEX_COORD": "its Window/Camera/Reflection outputs depend on the camera"}


def _value(v, depth=0):
    if hasattr(v, "__len__") and not isinstance(v, str):
        try:
            return tuple(_value(x, depth) for x in v)
        except TypeError:
            pass
    if hasattr(v, "bl_rna"):                       # an ID or struct pointer
        if getattr(v, "bl_rna", None) is not None and v.bl_rna.identifier == "Image":
            return ("Image", v.name, v.filepath, v.source, v.is_dirty,
                    getattr(v, "frame_duration", 0))
        if hasattr(v, "nodes"):
            return ("Tree", tree_signature(v))
        if isinstance(v, bpy.types.ID) or depth >= 2:
            return (v.bl_rna.identifier, getattr(v, "name", ""))
        # a node's own struct (an Environment Texture's texture_mapping rotation, a colour
        # ramp's stops): its values, so editing them re-captures the world
        return (v.bl_rna.identifier,) + tuple(
            (p.identifier, _value(getattr(v, p.identifier, None), depth + 1))
            for p in v.bl_rna.properties if p.identifier != "rna_type")
    return v


_BASE = None


def tree_signature(tree) -> tuple:
    global _BASE
    if _BASE is None:
        _BASE = {p.identifier for p in bpy.types.Node.bl_rna.properties}
    nodes = []
    for node in tree.nodes:
        props = tuple((p.identifier, _value(getattr(node, p.identifier, None)))
                      for p in node.bl_rna.properties
                      if p.identifier not in _BASE and p.type != 'COLLECTION')
        inputs = tuple((s.identifier, s.is_linked, _value(getattr(s, "default_value", None)))
                       for s in node.inputs)
        nodes.append((node.bl_idname, node.name, node.mute, props, inputs,
                      getattr(node, "is_active_output", None)))
    links = tuple(sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
                          lk.to_socket.identifier, lk.is_muted) for lk in tree.links))
    return tuple(nodes), links


def signature(world) -> str:
    """A hash of everything the world's radiance depends on."""
    if world is None:
        return "none"
    tree = world.node_tree if _uses_nodes(world) else None
    parts = (tuple(world.color), None if tree is None else tree_signature(tree))
    return hashlib.sha1(repr(parts).encode()).hexdigest()[:16]


def _uses_nodes(world) -> bool:
    # Blender 4.2-5.0 have World.use_nodes; from 5.x on a world always uses its tree.
    return world.node_tree is not None and getattr(world, "use_nodes", True)


def _output_node(tree):
    outputs = [n for n in tree.nodes if n.type == 'OUTPUT_WORLD']
    active = [n for n in outputs if n.is_active_output and n.target in {'ALL', 'CYCLES'}]
    return (active or outputs or [None])[0]


def _flat_colour(world):
    """(linear RGB, None) when the world is one colour everywhere; (None, reason) otherwise."""
    if not _uses_nodes(world):
        return np.asarray(world.color[:3], np.float64), None
    out = _output_node(world.node_tree)
    if out is None or not out.inputs["Surface"].is_linked:
        return np.zeros(3), None
    node = out.inputs["Surface"].links[0].from_node
    while node.type == 'REROUTE' and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    if node.type == 'BACKGROUND' and not node.mute:
        colour, strength = node.inputs["Color"], node.inputs["Strength"]
        if not colour.is_linked and not strength.is_linked:
            return np.asarray(colour.default_value[:3], np.float64) * strength.default_value, None
    return None, node


def _fallback(world, node):
    """A flat colour for a world that could not be captured (never black when it has light)."""
    if node is not None and node.type == 'BACKGROUND':
        c = np.asarray(node.inputs["Color"].default_value[:3], np.float64)
        return c * float(node.inputs["Strength"].default_value)
    return np.asarray(world.color[:3], np.float64)


def _view_dependent_notes(world) -> list:
    notes = []
    if not _uses_nodes(world):
        return notes
    for node in world.node_tree.nodes:
        why = _VIEW_DEPENDENT.get(node.type)
        if why is None:
            continue
        if node.type == 'TEX_COORD' and not any(
                node.outputs[k].is_linked for k in ("Window", "Camera", "Reflection")):
            continue
        notes.append(f"world '{world.name}': node '{node.name}' ({node.bl_label}) is lit as the "
                     f"camera sees it: {why}")
    return notes


def scratch_scene(name: str, size, samples: int):
    """A new scene rendering with Cycles on the CPU at `size` (w, h), `samples` per pixel, no
    adaptive sampling, no denoiser, a one-pixel box filter, neither compositor nor sequencer:
    what the captures render with (this world's, material_capture's). The caller removes it
    (remove_blocks)."""
    scene = bpy.data.scenes.new(name)
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 1.0
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    return scene


def remove_blocks(blocks):
    """Remove (datablock, bpy.data collection name) pairs in order; one already gone (None,
    removed with its user) is passed over."""
    for block, coll in blocks:
        if block is not None:
            try:
                getattr(bpy.data, coll).remove(block)
            except (ReferenceError, RuntimeError):
                pass


def capture_equirect(world, size=CAPTURE_SIZE, samples: int = CAPTURE_SAMPLES) -> np.ndarray:
    """float32 [h, w, 3]: the world's radiance rendered by Cycles through an equirectangular
    camera (rows top first; sky.py's layout). Main thread only. Raises RuntimeError on failure."""
    import OpenImageIO as oiio

    folder = tempfile.mkdtemp(prefix="lumen_world_")
    scene = cam = cam_ob = None
    try:
        scene = scratch_scene("Lumen World Capture", size, samples)
        scene.world = world
        scene.render.film_transparent = False
        scene.render.image_settings.file_format = 'OPEN_EXR'
        scene.render.image_settings.color_depth = '32'
        scene.render.filepath = os.path.join(folder, "world.exr")
        cam = bpy.data.cameras.new("Lumen World Capture")
        cam.type = 'PANO'
        if hasattr(cam, "panorama_type"):
            cam.panorama_type = 'EQUIRECTANGULAR'
        else:                                       # before Blender 4.0
            cam.cycles.panorama_type = 'EQUIRECTANGULAR'
        cam_ob = bpy.data.objects.new("Lumen World Capture", cam)
        # Looking along +X with +Z up: the image's middle column is +X, a quarter across is +Y,
        # the layout of an Environment Texture (measured with a Generated-coordinate world).
        cam_ob.rotation_euler = (np.pi / 2, 0.0, -np.pi / 2)
        scene.collection.objects.link(cam_ob)
        scene.camera = cam_ob
        bpy.ops.render.render(scene=scene.name, write_still=True)
        path = os.path.join(folder, "world.exr")
        if not os.path.isfile(path):
            raise RuntimeError("Cycles wrote no image")
        buf = oiio.ImageBuf(path)
        px = buf.get_pixels(oiio.FLOAT)
        if px is None or px.ndim != 3 or px.shape[:2] != (size[1], size[0]) or px.shape[2] < 3:
            raise RuntimeError(f"unexpected capture {getattr(px, 'shape', None)}")
        return np.ascontiguousarray(px[..., :3], np.float32)
    finally:
        remove_blocks(((cam_ob, "objects"), (cam, "cameras"), (scene, "scenes")))
        shutil.rmtree(folder, ignore_errors=True)


def _remember(key, maps):
    _MAPS[key] = maps
    _MAPS.move_to_end(key)
    while len(_MAPS) > _KEEP:
        _MAPS.popitem(last=False)


def world_light(scene):
    """(lumen_addon.sky.SkyMaps, notes) of the scene's world (see the module doc)."""
    world = scene.world
    key = signature(world)
    if key in _MAPS:
        _MAPS.move_to_end(key)
        return _MAPS[key], (_view_dependent_notes(world) if world is not None else [])
    if world is None:
        maps = sky.constant((0.0, 0.0, 0.0))
        _remember(key, maps)
        return maps, []
    colour, node = _flat_colour(world)
    if colour is not None:
        maps = sky.constant(colour)
        _remember(key, maps)
        return maps, []
    notes = _view_dependent_notes(world)
    if threading.current_thread() is not threading.main_thread():
        return sky.constant(_fallback(world, node)), notes + [
            f"world '{world.name}' is not captured yet: this frame uses its flat colour"]
    try:
        maps = sky.sky_maps(capture_equirect(world))
    except Exception as exc:   # noqa: BLE001 - any failure falls back, named, never black
        label = node.name if node is not None else world.name
        return sky.constant(_fallback(world, node)), notes + [
            f"world '{world.name}' could not be captured with Cycles ({exc}); node '{label}' "
            f"is lit as one flat colour"]
    _remember(key, maps)
    return maps, notes


def _schedule(scene_name: str):
    """Capture the scene's world on Blender's main thread soon (a timer), then redraw."""
    if scene_name in _PENDING:
        return
    _PENDING.add(scene_name)

    def run():
        _PENDING.discard(scene_name)
        scene = bpy.data.scenes.get(scene_name)
        if scene is not None and scene.world is not None:
            world_light(scene)
            wm = bpy.context.window_manager
            for window in (wm.windows if wm is not None else ()):
                for area in window.screen.areas:
                    if area.type == 'VIEW_3D':
                        area.tag_redraw()
        return None

    bpy.app.timers.register(run, first_interval=0.0)


def _needs_capture(scene) -> bool:
    return (scene.render.engine == 'LUMEN_GI' and scene.world is not None
            and signature(scene.world) not in _MAPS)


@bpy.app.handlers.persistent
def _on_depsgraph(scene, depsgraph):
    """A world, image or node tree changed: capture ahead of the next F12 (UI only; headless
    renders capture inline)."""
    if not any(depsgraph.id_type_updated(t) for t in ('WORLD', 'IMAGE', 'NODETREE', 'SCENE')):
        return
    if _needs_capture(scene):
        _schedule(scene.name)


@bpy.app.handlers.persistent
def _on_load(*_args):
    for scene in bpy.data.scenes:
        if _needs_capture(scene):
            _schedule(scene.name)


def register():
    if bpy.app.background:
        return
    bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph)
    bpy.app.handlers.load_post.append(_on_load)


def unregister():
    for handlers, fn in ((bpy.app.handlers.depsgraph_update_post, _on_depsgraph),
                         (bpy.app.handlers.load_post, _on_load)):
        if fn in handlers:
            handlers.remove(fn)
    _MAPS.clear()
