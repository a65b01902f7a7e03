"""`lumen.open_atlas`: load the surface-cache atlas of the scene's cache folder as Blender images.

Each layer listed in the manifest's `atlas.layers` becomes the image `Lumen Atlas <layer>`
(loaded again from disk when it already exists, so a new bake shows up). Layers that hold data
rather than colour (normal, depth, opacity) get the Non-Color colour space. With a UI, the first
layer is shown in an Image Editor of the current screen if there is one.
"""
import json

import bpy

from ..lumen_addon.cache import MANIFEST
from .bake_op import scene_cache_folder

IMAGE_PREFIX = "Lumen Atlas "
DATA_LAYERS = {"normal", "depth", "opacity"}


def atlas_layers(folder):
    """(size, [(layer, path)]) of the atlas in a cache folder's manifest; ValueError says why not."""
    manifest = folder / MANIFEST
    if not manifest.is_file():
        raise ValueError(f"no Lumen cache in {folder} (bake first)")
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read {manifest}: {exc}") from exc
    atlas = data.get("atlas") if isinstance(data, dict) else None
    layers = atlas.get("layers") if isinstance(atlas, dict) else None
    if not isinstance(layers, dict) or not layers:
        raise ValueError(f"the cache in {folder} has no surface-cache atlas (bake again)")
    out = []
    for layer, entry in layers.items():
        name = entry.get("file") if isinstance(entry, dict) else None
        if not isinstance(name, str) or not name or "/" in name or "\\" in name or name in {".", ".."}:
            raise ValueError(f"{manifest}: atlas layer '{layer}' has no valid file name")
        out.append((str(layer), folder / name))
    return atlas.get("size"), out


def load_layer(layer, path):
    """The image `Lumen Atlas <layer>` showing `path`, loaded or reloaded from disk."""
    name = IMAGE_PREFIX + layer
    image = bpy.data.images.get(name)
    if image is not None and image.library is None:
        if bpy.path.abspath(image.filepath) != str(path):
            image.filepath = str(path)
        image.reload()
    else:
        count = len(bpy.data.images)
        image = bpy.data.images.load(str(path), check_existing=True)
        if len(bpy.data.images) == count:      # an existing image of that file: show the new bake
            image.reload()
        image.name = name
    if layer in DATA_LAYERS:
        image.colorspace_settings.name = 'Non-Color'
    return image


class LUMEN_OT_open_atlas(bpy.types.Operator):
    """Load the mesh-card atlas of the cache folder as images (Lumen Atlas albedo, normal, ...)"""

    bl_idname = "lumen.open_atlas"
    bl_label = "Open Atlas"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        try:
            return self._execute(context)
        except Exception as exc:   # never let an exception escape into Blender
            import traceback
            traceback.print_exception(exc)
            self.report({'ERROR'}, f"Lumen atlas: unexpected {type(exc).__name__}: {exc}")
            return {'CANCELLED'}

    def _execute(self, context):
        folder = scene_cache_folder(context.scene)
        try:
            size, layers = atlas_layers(folder)
        except ValueError as exc:
            self.report({'ERROR'}, f"Lumen atlas: {exc}")
            return {'CANCELLED'}
        images, missing = [], []
        for layer, path in layers:
            if not path.is_file():
                missing.append(path.name)
                continue
            try:
                images.append(load_layer(layer, path))
            except RuntimeError as exc:   # bpy.data.images.load: unreadable file
                missing.append(f"{path.name} ({exc})")
        if missing:
            self.report({'ERROR'} if not images else {'WARNING'},
                        f"Lumen atlas: cannot load {', '.join(missing)} in {folder}")
        if not images:
            return {'CANCELLED'}
        self._show(context, images[0])
        dims = "x".join(map(str, size)) if isinstance(size, (list, tuple)) else "?"
        self.report({'INFO'}, f"Loaded {len(images)} atlas layers ({dims}) from {folder}")
        return {'FINISHED'}

    @staticmethod
    def _show(context, image):
        if bpy.app.background or context.screen is None:
            return
        for area in context.screen.areas:
            if area.type == 'IMAGE_EDITOR':
                area.spaces.active.image = image
                area.tag_redraw()
                return


def register():
    bpy.utils.register_class(LUMEN_OT_open_atlas)


def unregister():
    bpy.utils.unregister_class(LUMEN_OT_open_atlas)
