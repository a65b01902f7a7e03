"""GPU textures of a scene bake's mip-0 SDFs (needs a GPU context: call from RenderEngine.render).

Four textures, read by glsl/sdf_lib.glsl: the brick atlas, the indirection table, the object
table and the object grid (object_grid.py: per world cell the instances a distance sample there
must visit). The grid is built from the object table whenever that is uploaded (`set_objects`:
the first upload, and every object move through scene_state.py), so the two always agree.

Formats, measured on Mesa llvmpipe (GL 4.5) through Blender 5.0.1's `gpu` module:
- the brick atlas is R8 (unorm) 3D, uploaded from a FLOAT Buffer of code / 255 (exact);
- `gpu.types.GPUTexture(..., format='R32I', data=Buffer('FLOAT', ...))` is accepted but leaves the
  texture zero (the float upload into an integer format fails silently; a non-FLOAT Buffer raises
  "GPUTexture.__new__: Only Buffer of format `FLOAT` is currently supported"). So the R32I
  indirection table is filled by a compute pass from an R32F staging texture (integers < 2^24
  are exact in float), which is then freed.
"""
from __future__ import annotations

import time
from pathlib import Path

import gpu
import numpy as np

from . import glsl_include
from .object_grid import build_object_grid, changed_boxes
from .packing import OBJECT_TEXELS, PARKED, PackedScene, pack_bake, row_table

GLSL = Path(__file__).resolve().parent / "glsl"
_SHADERS = {}


def glsl(names) -> str:
    """glsl/<name> (or several names) with the libraries it #includes (glsl_include.py)."""
    return glsl_include.source(names, GLSL)


def row_texture(rows, pad=None):
    """A GPUTexture RGBA32F of row_table(rows, pad)."""
    table = row_table(rows, pad)
    return gpu.types.GPUTexture((table.shape[1], table.shape[0]), format='RGBA32F',
                                data=float_buffer(table))


def float_buffer(array) -> "gpu.types.Buffer":
    a = np.ascontiguousarray(array, np.float32).reshape(-1)
    return gpu.types.Buffer('FLOAT', a.size, a)


def read_texture(tex, shape=None) -> np.ndarray:
    """float32 copy of a texture's contents (waits for the GPU), [height, width, channels] unless
    `shape` says otherwise (e.g. [n, n, n] for a flattened 3D texture).

    Reads the gpu.types.Buffer through the buffer protocol: 0.3-0.5 ms for 640x360 RGBA32F,
    against 250-370 ms for Buffer.to_list() (measured on bpy 4.2.0, 5.0.1, 5.3.0). Blender up to
    5.0 reports a C-ordered buffer with reversed (Fortran) strides, 5.3 with C strides; ravel in
    memory order ('K') is the texels in row order either way."""
    flat = np.asarray(tex.read()).ravel(order='K')
    if shape is None:
        shape = (tex.height, tex.width, -1)
    return flat.astype(np.float32).reshape(shape)


def _copy_shader():
    from . import compute   # compute imports this module

    if "copy_int" not in _SHADERS:
        info = compute.new_info((8, 8, 1))
        info.sampler(0, 'FLOAT_2D', 'src')
        info.image(0, 'R32I', 'INT_2D', 'dst', qualifiers={'WRITE'})
        _SHADERS["copy_int"] = compute.create(
            info,
            "void main() {\n"
            "  ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
            "  if (p.x >= imageSize(dst).x || p.y >= imageSize(dst).y) { return; }\n"
            "  imageStore(dst, p, ivec4(int(round(texelFetch(src, p, 0).x)), 0, 0, 0));\n"
            "}\n")
    return _SHADERS["copy_int"]


def int_texture_2d(values: np.ndarray) -> "gpu.types.GPUTexture":
    from . import compute

    """R32I 2D texture of int32 values [rows, width] (|v| < 2^24), via an R32F staging texture."""
    rows, width = values.shape
    staging = gpu.types.GPUTexture((width, rows), format='R32F', data=float_buffer(values))
    tex = gpu.types.GPUTexture((width, rows), format='R32I')
    sh = _copy_shader()
    sh.uniform_sampler('src', staging)
    sh.image('dst', tex)
    compute.run(sh, -(-width // 8), -(-rows // 8), 1)
    del staging
    return tex


class SceneResources:
    """The four textures of a packed scene. `bind(shader)` sets the samplers sdf_lib.glsl reads."""

    def __init__(self, packed: PackedScene):
        if not len(packed.objects):
            raise ValueError("the bake has no objects to trace")
        t0 = time.perf_counter()
        self.packed = packed
        ax, ay, az = packed.atlas_size
        self.atlas = gpu.types.GPUTexture((ax, ay, az), format='R8',
                                          data=float_buffer(packed.atlas.astype(np.float32) / 255.0))
        self.indirection = int_texture_2d(packed.indirection)
        self.set_objects(packed.objects)
        self.upload_seconds = time.perf_counter() - t0

    def set_objects(self, rows: np.ndarray):
        """Upload the object table rows [n, OBJECT_TEXELS, 4] and the object grid built from them."""
        if not len(rows):
            raise ValueError("the bake has no objects to trace")
        t0 = time.perf_counter()
        old = getattr(self.packed, "objects", None)
        boxes = changed_boxes(old, rows, self.CHANGE_ROWS)
        self._log_changes(boxes)
        self.packed.objects = rows
        # the last line's unused rows parked (a bounding sphere 1e30 m away: every loop over
        # the objects, sdf_object_count's, skips them)
        parked = np.array(rows[-1], np.float32)
        parked[8] = (PARKED, PARKED, PARKED, 0.0)
        self.objects = row_texture(rows, pad=parked)
        # only the cells near what changed are measured again (the same texels as a full build)
        previous = getattr(self, "grid_info", {}).get("lists")
        texels, self.grid_info = build_object_grid(rows, previous=previous, boxes=boxes)
        # an instance is a cut-out (texel 9 z, its holes' share, over 0): the passes that trace
        # shadows or GI rays compile its bookkeeping in (compute.VARIANTS)
        self.cut_outs = bool((rows[:, 9, 2] > 0.0).any())
        self._log_region(self.grid_info["region"])
        self.grid_shape = texels.shape
        self.grid = gpu.types.GPUTexture((texels.shape[1], texels.shape[0]), format='RGBA32F',
                                         data=float_buffer(texels))
        self.grid_info["seconds"] = time.perf_counter() - t0

    CHANGE_LOG = 64        # object-table changes kept for consumers that lag behind
    CHANGE_ROWS = 256      # rows changed at once beyond which a change counts as everything

    def _log_changes(self, boxes):
        """Record which world boxes the new object rows change (objects_version + 1): the old and
        new world AABBs (object_grid.changed_boxes) of every row that differs, or None
        (everything) when the table's size changed or more than CHANGE_ROWS rows did (a parent
        moving thousands of children). A value of the scene SDF changes only within those
        boxes, so the global SDF refreshes only their cells and the object grid only the
        cells within its reach of them."""
        if not hasattr(self, "objects_version"):
            self.objects_version, self.changes = 0, []
            return
        self.objects_version += 1
        self.changes = (self.changes + [(self.objects_version, boxes)])[-self.CHANGE_LOG:]

    def _log_region(self, region):
        """Record where the new object grid's sdf_scene values may differ from the last one's
        (object_grid.build_object_grid's `region`), for objects_version."""
        if not hasattr(self, "regions"):
            self.regions = []
            return
        self.regions = (self.regions + [(self.objects_version, region)])[-self.CHANGE_LOG:]

    def regions_since(self, version: int):
        """The world boxes outside which sdf_scene returns the same values as it did at
        object-table version `version` (boxes unbounded on some sides), or None when that is not
        known: then anywhere. Why: a pass that keeps results traced through the scene SDF (the
        viewport's progressive direct light) needs to redo only the rays that pass through
        them."""
        return self._since(self.regions, version)

    def boxes_since(self, version: int):
        """The world boxes (lo, hi) that changed after object-table version `version`, or None
        when that is unknown (a size change, or older than the log): then everything did."""
        return self._since(self.changes, version)

    def _since(self, log, version: int):
        """The boxes a change log ([(version, boxes or None)]) holds after `version`; None where
        one is None or the log no longer reaches back that far."""
        if version == self.objects_version:
            return []
        later = [b for v, b in log if v > version]
        if len(later) != self.objects_version - version or any(b is None for b in later):
            return None
        return [box for b in later for box in b]

    @classmethod
    def from_bake(cls, bake, mip: int = 0) -> "SceneResources":
        return cls(pack_bake(bake, mip))

    @staticmethod
    def declare(info, first_slot: int = 0) -> int:
        """Declare sdf_lib.glsl's samplers on a GPUShaderCreateInfo; returns the next free slot."""
        info.sampler(first_slot, 'FLOAT_3D', 'sdf_atlas')
        info.sampler(first_slot + 1, 'INT_2D', 'sdf_indirection')
        info.sampler(first_slot + 2, 'FLOAT_2D', 'sdf_objects')
        info.sampler(first_slot + 3, 'FLOAT_2D', 'sdf_grid')
        return first_slot + 4

    def bind(self, shader):
        shader.uniform_sampler('sdf_atlas', self.atlas)
        shader.uniform_sampler('sdf_indirection', self.indirection)
        shader.uniform_sampler('sdf_objects', self.objects)
        shader.uniform_sampler('sdf_grid', self.grid)

    def stats(self) -> dict:
        """GPU bytes per texture, from the sizes and formats actually allocated."""
        ax, ay, az = self.packed.atlas_size
        rows, width = self.packed.indirection.shape
        return {
            "atlas": ax * ay * az * 1,                               # R8
            "indirection": width * rows * 4,                         # R32I
            "objects": OBJECT_TEXELS * len(self.packed.objects) * 16,  # RGBA32F
            "object_grid": self.grid_shape[0] * self.grid_shape[1] * 16,  # RGBA32F
        }
