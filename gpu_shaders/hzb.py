"""Screen pyramids for SSGI (lecture 21, "Hierarchical Tracing" and "Cone Tracing with Mipmap
Filtering"): a hierarchical-Z (HZB) MIN chain of the G-buffer's window depth, and a mean chain of
the scene colour (premultiplied by surface coverage). Blender 5.0's GPUTexture has no mip levels a
compute pass can write, so each pyramid is one atlas texture (glsl/mip_lib.glsl: level 0 at the
origin, the others stacked to its right; `mip_layout` is its numpy twin). One dispatch per level.

Why window depth and MIN: the depth buffer's z is affine along a screen-space line, so a ray is a
straight line in (pixel x, pixel y, depth) and a cell's MIN (the nearest surface it shows) tells
whether a ray segment passes entirely in front of the cell (skip it, climb a level) or may touch
something (descend). The background stores 1.0 (the far plane). Needs a GPU context.
"""
from __future__ import annotations

import numpy as np

from . import compute

MIP = (('INT', 'level'), ('IVEC2', 'base'))
# 8 x 8 work groups: hzb_depth.comp.glsl's HZB_TILE (a group shares its tile's depths)
DEPTH = compute.Pass("hzb_depth", samplers=("gbuf_position",), images=(("hzb", 'R32F'),),
                     push=(('MAT4', 'view_proj'),), group=(8, 8, 1))
REDUCE = compute.Pass("hzb_reduce", images=(("hzb", 'R32F', {'READ', 'WRITE'}),), push=MIP)
COLOUR_MIP = compute.Pass("colour_mip", samplers=("source", "gbuf_position"),
                          images=(("colour", 'RGBA32F', {'READ', 'WRITE'}),), push=MIP)

def mip_layout(width: int, height: int):
    """([(x, y, w, h) per level], (atlas width, atlas height)): glsl/mip_lib.glsl's layout."""
    w, h = int(width), int(height)
    rects = [(0, 0, w, h)]
    y = 0
    while w > 1 or h > 1:
        w, h = -(-w // 2), -(-h // 2)
        rects.append((int(width), y, w, h))
        y += h
    atlas_w = int(width) + (rects[1][2] if len(rects) > 1 else 0)
    return rects, (atlas_w, max(int(height), y))


def levels_of(atlas: np.ndarray, width: int, height: int) -> list:
    """The levels of a read-back atlas [H, W, C] as arrays [h, w, C] (tests, debug views)."""
    rects, _ = mip_layout(width, height)
    return [atlas[y:y + h, x:x + w] for x, y, w, h in rects]


def _reduce(mip: compute.Pass, width: int, height: int, first_level: int, **inputs):
    """Each level from first_level on, from the one before it (inputs: the atlas and samplers)."""
    rects, _ = mip_layout(width, height)
    for level in range(first_level, len(rects)):
        mip.run(rects[level][2:4], level=level, base=(int(width), int(height)), **inputs)


def depth_pyramid(gbuf: dict, view_proj, width: int, height: int):
    """The HZB of this frame's G-buffer: an R32F atlas of window depths, each level the MIN of
    its children."""
    _, size = mip_layout(width, height)
    atlas = compute.texture(size, 'R32F')
    DEPTH.run((width, height), gbuf_position=gbuf["textures"]["position"], view_proj=view_proj,
              hzb=atlas)
    _reduce(REDUCE, width, height, 1, hzb=atlas)
    return atlas


def colour_pyramid(source, gbuf: dict, width: int, height: int):
    """The cone-filter pyramid of a lit image (`source`, RGBA): RGBA32F atlas, rgb premultiplied
    by coverage (a: the share of the cell that shows a surface), each level the mean of its
    children."""
    _, size = mip_layout(width, height)
    atlas = compute.texture(size)
    _reduce(COLOUR_MIP, width, height, 0, source=source,
            gbuf_position=gbuf["textures"]["position"], colour=atlas)
    return atlas
