"""The surface-cache atlas: every card of every mesh packed into one set of layer images.

Packing is a bottom-left skyline over the cards' rectangles, tallest first, never rotated (a card
keeps u along x and v along y, so the shaders need no per-card orientation), at the best of
several atlas widths. Each card sits inside a border of PADDING texels that repeat its edge
texels, so bilinear filtering at a card's edge reads that card and nothing else. (xatlas packs
the same rectangles exactly when each is its own UV chart, but into atlases 3-30% larger on the
demo and benchmark scenes, and more slowly: bench/atlas_packing.py.)

Texel (i, j) of a card (column i along u, row j along v) is atlas pixel [y + j, x + i] of its
`rect` = (x, y, w, h); row 0 of the arrays is the first scanline of the image files.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cards import Card, MeshCards

PADDING = 2
LAYERS = {"albedo": 3, "normal": 3, "depth": 1, "emissive": 3, "opacity": 1}


@dataclass
class Atlas:
    size: tuple                        # (width, height) in texels
    layers: dict                       # name -> float32 (height, width, channels)
    table: list = field(default_factory=list)   # per card: dict, see card_entry()


WIDTH_STEP = 16          # atlas widths tried are multiples of this
MAX_WIDTHS = 16          # most widths tried (fewer for thousands of cards: see pack)


def pack(sizes, padding: int = PADDING):
    """Positions (N, 2) of each (w, h) rectangle's first texel, and the atlas (width, height).

    Every rectangle is reserved with `padding` texels on each side; no two reservations overlap.
    The skyline is run for several atlas widths (0.7 to 1.6 x the side of a square of the same
    area) and the smallest atlas kept: one fixed width left 30-40% of some scenes' atlases empty
    (bench/atlas_packing.py).
    """
    sizes = np.asarray(sizes, np.int64).reshape(-1, 2)
    if not len(sizes):
        return np.zeros((0, 2), np.int64), (0, 0)
    outer = sizes + 2 * padding
    side = float(np.sqrt(float((outer[:, 0] * outer[:, 1]).sum())))
    lo = max(int(outer[:, 0].max()), int(0.7 * side))
    steps = np.arange(-(-lo // WIDTH_STEP), -(-max(lo, int(1.6 * side)) // WIDTH_STEP) + 1)
    count = int(np.clip(6000 // len(sizes), 3, MAX_WIDTHS))   # each width is a full packing
    if len(steps) > count:
        steps = np.unique(steps[np.linspace(0, len(steps) - 1, count).round().astype(int)])
    best = None
    for width in steps * WIDTH_STEP:                       # a loop over widths, not texels
        pos, height = _skyline(outer, max(int(width), int(outer[:, 0].max())))
        size = (int(max(width, outer[:, 0].max())), -(-height // 4) * 4)
        if best is None or (size[0] * size[1], abs(size[0] - size[1])) < best[0]:
            best = ((size[0] * size[1], abs(size[0] - size[1])), pos, size)
    return best[1] + padding, best[2]


def _skyline(outer, width):
    """Bottom-left skyline of the reserved rectangles `outer` in an atlas `width` wide, tallest
    first, then widest: (first texel of each reservation, height used)."""
    order = np.lexsort((-outer[:, 0], -outer[:, 1]))       # tallest first, then widest
    sky = [[0, width, 0]]                                  # skyline segments: x, width, top y
    pos = np.zeros_like(outer)
    for k in order:                                        # a loop over cards, not texels
        w, h = int(outer[k, 0]), int(outer[k, 1])
        best = None
        for i, (x, _, _) in enumerate(sky):
            if x + w > width:
                break
            y, rem, j = 0, w, i
            while rem > 0:
                y = max(y, sky[j][2])
                rem -= sky[j][1]
                j += 1
            if best is None or (y, x) < best[:2]:
                best = (y, x, i)
        y, x, i = best
        pos[k] = (x, y)
        _raise_skyline(sky, i, x, w, y + h)
    return pos, max(seg[2] for seg in sky)


def _raise_skyline(sky, i, x, w, top):
    """Replace the skyline under [x, x + w) by one segment at `top`."""
    end = x + w
    j = i
    while j < len(sky) and sky[j][0] < end:
        j += 1
    tail = sky[j - 1]
    rest = tail[0] + tail[1] - end
    new = [[x, w, top]] + ([[end, rest, tail[2]]] if rest > 0 else [])
    sky[i:j] = new
    k = 0
    while k + 1 < len(sky):                                 # merge equal neighbours
        if sky[k][2] == sky[k + 1][2]:
            sky[k][1] += sky[k + 1][1]
            del sky[k + 1]
        else:
            k += 1


def build_atlas(meshes: dict, padding: int = PADDING) -> Atlas:
    """Pack every card of {mesh hash: MeshCards} into one atlas of LAYERS."""
    entries = [(key, n, c) for key, mc in meshes.items() for n, c in enumerate(mc.cards)]
    pos, (width, height) = pack([c.resolution for _, _, c in entries], padding)
    layers = {name: np.zeros((height, width, ch), np.float32) for name, ch in LAYERS.items()}
    table = []
    for (key, n, c), (x, y) in zip(entries, pos):
        w, h = c.resolution
        for name, ch in LAYERS.items():
            data = getattr(c, name).reshape(h, w, ch)
            block = np.pad(data, ((padding, padding), (padding, padding), (0, 0)), mode="edge")
            layers[name][y - padding:y + h + padding, x - padding:x + w + padding] = block
        table.append(card_entry(key, n, c, (int(x), int(y), int(w), int(h))))
    return Atlas((width, height), layers, table)


def card_entry(mesh: str, index: int, c: Card, rect) -> dict:
    return {"mesh": mesh, "index": index, "axis": int(c.axis), "rect": list(rect),
            "rect_min": [float(x) for x in c.rect_min], "rect_max": [float(x) for x in c.rect_max],
            "near": float(c.near), "far": float(c.far)}


def split_atlas(atlas: Atlas, coverage: dict) -> dict:
    """The inverse of build_atlas: {mesh hash: MeshCards} with each card's layers copied out."""
    out = {}
    for e in sorted(atlas.table, key=lambda e: (e["mesh"], e["index"])):
        x, y, w, h = e["rect"]
        c = Card(int(e["axis"]), np.array(e["rect_min"]), np.array(e["rect_max"]), float(e["near"]),
                 float(e["far"]), (int(w), int(h)))
        for name, ch in LAYERS.items():
            block = atlas.layers[name][y:y + h, x:x + w].copy()
            setattr(c, name, block if ch > 1 else block[:, :, 0])
        out.setdefault(e["mesh"], MeshCards([], float(coverage.get(e["mesh"], 0.0)))).cards.append(c)
    return out
