"""Materials the extraction cannot read node by node -> their colours, rendered by Cycles.

`operators/extract.py` reads a Principled, Diffuse or Emission shader, clear shaders and Mix and
Add Shaders of them, with colours that are values or Image Textures linked straight in. Anything
else (a node group, a Toon BSDF, a Color Ramp or a procedural texture before Base Color) used to
fall back to the viewport display colour, which is Blender's default grey unless the artist set
it: a room of asset-library materials bounced grey light. Here such materials are rendered by
Cycles, as the world is (world_capture.py): one flat 1 m swatch per material, seen from above by
an orthographic camera, SWATCH x SWATCH pixels each, its passes read back:
    albedo      Diffuse Color + Glossy Color (what the surface reflects, as one diffuse albedo),
                over the swatch's alpha (the colour of its opaque part), per pixel and its mean
    emission    the Emission pass
    opacity     Combined alpha over a transparent film, glass counted transparent
                (film_transparent_roughness 1): extract.py's see-through rule then applies
The swatch's texture coordinates are its UVs (0..1) and a 1 m square: its SWATCH x SWATCH
pixels are the material over its UV square, which the extraction uses as textures sampled with
the mesh's UVs (a Color Ramp or Mix on an image, a procedural texture in UV space keep their
pattern; Generated or Object coordinates are the swatch's, not the mesh's: their pattern is
approximate, their colours right), and their means serve meshes without UVs; a colour
attribute reads ATTRIBUTE_GREY (the mesh's own colours are not the material's).
Captures are remembered by the material's content signature (its nodes, inputs, links and node
groups: world_capture.tree_signature), so a material is rendered once until it is edited; every
material a capture finds missing is rendered in the same image (one Cycles start: 0.04 s for
one material, 0.37 s for 32, 2 cores). Main thread only: a job thread (the UI's F12) that finds
no capture falls back to the display colour with a note.
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

from ..lumen_addon.materials import DEFAULT_ALBEDO
from .world_capture import remove_blocks, scratch_scene, tree_signature

SWATCH = 32             # pixels per swatch side: the material over its UV square
SAMPLES = 16
_MEANS = OrderedDict()  # signature -> Means (memo of derived data, not render state)
_KEEP = 512             # 24 KB each (two 32 x 32 RGB float textures)


class Means:
    """A material's mean albedo (linear RGB), emission (linear RGB radiance) and opacity, and
    the albedo and emission over its UV square (float32 [SWATCH, SWATCH, 3], row 0 at v = 0 as
    Blender's images; the emission's None when nothing emits): textures the G-buffer and the
    cards sample with the mesh's UVs, so a Color Ramp, a Mix or a procedural texture keeps its
    pattern (the mean colours serve a mesh without UVs)."""

    def __init__(self, albedo, emission, opacity, albedo_tex=None, emission_tex=None):
        self.albedo = tuple(float(x) for x in albedo)
        self.emission = tuple(float(x) for x in emission)
        self.opacity = float(opacity)
        self.albedo_tex, self.emission_tex = albedo_tex, emission_tex

    def __repr__(self):
        return f"Means(albedo={self.albedo}, emission={self.emission}, opacity={self.opacity:.3f})"


def signature(mat) -> str:
    tree = mat.node_tree
    parts = (tuple(mat.diffuse_color), None if tree is None else tree_signature(tree))
    return hashlib.sha1(repr(parts).encode()).hexdigest()[:16]


def remembered(key: str):
    """The capture remembered for a material's signature `key`, else None."""
    hit = _MEANS.get(key)
    if hit is not None:
        _MEANS.move_to_end(key)
    return hit


def means(mat, others=(), key: str | None = None):
    """Means of `mat` (its signature `key`, computed when not given): remembered, or rendered
    now together with those of `others` (materials that will be asked for next) that are not
    remembered either. None off the main thread or when Cycles fails (the caller keeps its
    fallback; the exception is not raised)."""
    key = key or signature(mat)
    hit = remembered(key)
    if hit is not None:
        return hit
    if threading.current_thread() is not threading.main_thread():
        return None
    batch, seen = [(key, mat)], {key}
    for m in others:
        k = signature(m)
        if k not in seen and k not in _MEANS:
            seen.add(k)
            batch.append((k, m))
    try:
        found = capture([m for _, m in batch])
    except Exception:   # noqa: BLE001 - a failed capture leaves the display colour, named
        return None
    for (k, _), value in zip(batch, found):
        _MEANS[k] = value
        _MEANS.move_to_end(k)
    while len(_MEANS) > _KEEP:
        _MEANS.popitem(last=False)
    return _MEANS.get(key)


# What a colour attribute reads on a swatch (its mesh's colours are not the material's): the
# default albedo, so that a Color Attribute straight into Base Color reads as the display
# colour did, and an image multiplied by one keeps most of its mean
ATTRIBUTE_GREY = DEFAULT_ALBEDO


def attribute_names(tree, seen=None) -> set:
    """The names of the mesh attributes a node tree reads (Color Attribute and Attribute
    nodes, inside node groups too; "" for the default colour attribute)."""
    seen = set() if seen is None else seen
    names = set()
    if tree is None or tree.as_pointer() in seen:
        return names
    seen.add(tree.as_pointer())
    for node in tree.nodes:
        if node.type == 'VERTEX_COLOR':
            names.add(node.layer_name)
        elif node.type == 'ATTRIBUTE' and node.attribute_type == 'GEOMETRY':
            names.add(node.attribute_name)
        elif node.type == 'GROUP':
            names |= attribute_names(node.node_tree, seen)
    return names


def _layers(path) -> dict:
    """{pass name: float32 [h, w, c]} of a multilayer EXR (OpenImageIO: one subimage per pass,
    channels named ViewLayer.<pass>.<channel>)."""
    import OpenImageIO as oiio

    out = {}
    first = oiio.ImageBuf(path)
    for k in range(max(first.nsubimages, 1)):
        buf = oiio.ImageBuf(path, k, 0)
        names = buf.spec().channelnames
        if not names:
            continue
        px = buf.get_pixels(oiio.FLOAT)
        parts = names[0].split(".")
        if px is not None and len(parts) >= 2:
            out[parts[-2]] = np.asarray(px, np.float32)
    return out


def capture(materials) -> list:
    """[Means] of `materials`, rendered by Cycles in one image (module doc). Main thread only.
    Raises RuntimeError when Cycles writes nothing usable."""
    n = len(materials)
    if not n:
        return []
    cols = int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    folder = tempfile.mkdtemp(prefix="lumen_materials_")
    made = []                      # (datablock, bpy.data collection), removed in reverse
    try:
        scene = scratch_scene("Lumen Material Capture", (cols * SWATCH, rows * SWATCH), SAMPLES)
        made.append((scene, "scenes"))
        scene.cycles.film_transparent_glass = True
        scene.cycles.film_transparent_roughness = 1.0
        scene.render.film_transparent = True
        settings = scene.render.image_settings
        if hasattr(settings, "media_type"):          # Blender 5.0 on
            settings.media_type = 'MULTI_LAYER_IMAGE'
        else:
            settings.file_format = 'OPEN_EXR_MULTILAYER'
        settings.color_depth = '32'
        path = os.path.join(folder, "materials.exr")
        scene.render.filepath = path
        layer = scene.view_layers[0]
        layer.use_pass_diffuse_color = True
        layer.use_pass_glossy_color = True
        layer.use_pass_emit = True
        uv = np.array([0, 0, 1, 0, 1, 1, 0, 1], np.float32)
        grey = np.tile(np.float32([*ATTRIBUTE_GREY, 1.0]), 4)
        for i, mat in enumerate(materials):
            x, y = i % cols, rows - 1 - i // cols
            mesh = bpy.data.meshes.new("Lumen Material Swatch")
            made.append((mesh, "meshes"))
            mesh.from_pydata([(x, y, 0), (x + 1, y, 0), (x + 1, y + 1, 0), (x, y + 1, 0)], [],
                             [(0, 1, 2, 3)])
            mesh.uv_layers.new(name="UVMap").data.foreach_set("uv", uv)
            for name in sorted(attribute_names(mat.node_tree)):   # colour attributes: grey
                attr = mesh.color_attributes.new(name or "Color", 'FLOAT_COLOR', 'CORNER')
                attr.data.foreach_set("color", grey)
            mesh.materials.append(mat)
            ob = bpy.data.objects.new("Lumen Material Swatch", mesh)
            made.append((ob, "objects"))
            scene.collection.objects.link(ob)
        cam = bpy.data.cameras.new("Lumen Material Capture")
        made.append((cam, "cameras"))
        cam.type = 'ORTHO'
        cam.ortho_scale = float(max(cols, rows))
        cam_ob = bpy.data.objects.new("Lumen Material Capture", cam)
        made.append((cam_ob, "objects"))
        cam_ob.location = (cols / 2.0, rows / 2.0, 5.0)
        scene.collection.objects.link(cam_ob)
        scene.camera = cam_ob
        bpy.ops.render.render(scene=scene.name, write_still=True)
        if not os.path.isfile(path):
            raise RuntimeError("Cycles wrote no image")
        layers = _layers(path)
        want = (rows * SWATCH, cols * SWATCH)
        for name in ("Combined", "Diffuse Color", "Glossy Color", "Emission"):
            if name not in layers or layers[name].shape[:2] != want:
                raise RuntimeError(f"the capture has no {name} pass of {want}")
        out = []
        for i in range(n):
            x, y = i % cols, i // cols                     # rows top first in the file
            block = (slice(y * SWATCH, (y + 1) * SWATCH), slice(x * SWATCH, (x + 1) * SWATCH))

            def tile(name):                                # row 0 at v = 0
                return np.ascontiguousarray(layers[name][block][::-1, :, :3], np.float32)
            alpha_px = np.clip(layers["Combined"][block][::-1, :, 3], 0.0, 1.0)
            alpha = float(alpha_px.mean())
            reflect = tile("Diffuse Color") + tile("Glossy Color")
            # the colour of the opaque part, as the mean's (reflect / alpha)
            tex = np.clip(reflect / np.maximum(alpha_px, 1e-3)[..., None], 0.0, 1.0)
            tex = np.where(alpha_px[..., None] > 1e-3, tex, reflect).astype(np.float32)
            mean = reflect.reshape(-1, 3).mean(0)
            albedo = np.clip(mean / max(alpha, 1e-3), 0.0, 1.0) if alpha > 1e-3 else mean
            emit = np.maximum(tile("Emission"), 0.0)
            out.append(Means(albedo, emit.reshape(-1, 3).mean(0), alpha, tex,
                             emit if emit.max() > 0.0 else None))
        return out
    finally:
        remove_blocks(reversed(made))
        shutil.rmtree(folder, ignore_errors=True)


def register():
    pass


def unregister():
    _MEANS.clear()
