"""Lay out the surface cache for the GPU: one lighting atlas of every (instance, card) pair (numpy only).

The bake's card atlas (lumen_addon.atlas) holds each *mesh's* cards once: albedo, normal, depth,
emissive, opacity are properties of the mesh. Lighting is not: two instances of one mesh stand in
different light. So the lighting lives in a second atlas with one rectangle per (instance, card),
packed with the same skyline packer (no padding: the shaders clamp their reads to the card's own
rectangle; each card reserves whole 4x4 blocks, so every block of the surface cache's radiosity
probes lies on one card), and every lighting texel knows its card row.

Arrays (uploaded by surface_cache.py as they are, x fastest):
- `cards`: float32 [rows, CARD_TEXELS, 4], one row per (instance, card), rows grouped by instance:
    texel 0 = (instance, axis, lighting x, lighting y)
    texel 1 = (card-atlas x, card-atlas y, width, height)        texels, as atlas.card_entry's rect
    texel 2 = (rect_min u, rect_min v, rect_max u, rect_max v)   mesh-local metres, cards.PLANE axes
    texel 3 = (near, far, emissive texels, 0)                    depth = AXES[axis] . p_local;
              emissive texels: 0 here, counted by surface_cache.mark_emissive_cards
- `instances`: float32 [instances, 1, 4] = (first card row, card count, emissive cards, 0) per
  object-table row (the emissive count set by surface_cache.mark_emissive_cards).
- `texel_card`: float32 [H, W] lighting texel -> its card row, -1 where no card is.
Integers in float texels are exact below 2^24 (checked).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:                                   # inside the extension package
    from ..lumen_addon.atlas import pack
    from ..lumen_addon.cards import AXES, PLANE
except ImportError:                    # gpu_shaders imported on its own (tests, scripts)
    from lumen_addon.atlas import pack
    from lumen_addon.cards import AXES, PLANE

CARD_TEXELS = 4
PROBE_BLOCK = 4          # texels per surface-cache probe side (surface_cache_probe_lib.glsl)
FLOAT_EXACT = 1 << 24


@dataclass
class PackedCards:
    cards: np.ndarray             # float32 [rows, CARD_TEXELS, 4]
    instances: np.ndarray         # float32 [instances, 1, 4]
    texel_card: np.ndarray        # float32 [H, W]
    lighting_size: tuple          # (W, H) texels of the lighting atlas
    card_atlas_size: tuple        # (W, H) texels of the bake's card atlas
    texels: int = 0               # lighting texels that belong to a card

    @property
    def rows(self) -> int:
        return len(self.cards)


def pack_cards(atlas, instance_cards) -> PackedCards:
    """`atlas`: the bake's lumen_addon.atlas.Atlas (or None: no cards); `instance_cards`: the cards
    hash of each object-table row, in order (lumen_addon.bake.Instance.cards)."""
    table = list(atlas.table) if atlas is not None else []
    by_mesh = {}
    for e in sorted(table, key=lambda e: (e["mesh"], e["index"])):
        by_mesh.setdefault(e["mesh"], []).append(e)
    entries, inst_rows = [], np.zeros((len(instance_cards), 1, 4), np.float32)
    for i, key in enumerate(instance_cards):
        mine = by_mesh.get(key, [])
        inst_rows[i, 0, :2] = (len(entries), len(mine))
        entries += [(i, e) for e in mine]
    # Reserve whole 4x4 blocks per card: a surface-cache probe's block then lies on one card.
    sizes = [(-(-e["rect"][2] // PROBE_BLOCK) * PROBE_BLOCK, -(-e["rect"][3] // PROBE_BLOCK) * PROBE_BLOCK)
             for _, e in entries]
    pos, (width, height) = pack(sizes, padding=0) if entries else (np.zeros((0, 2)), (1, 1))
    width, height = max(int(width), 1), max(int(height), 1)
    if len(entries) >= FLOAT_EXACT or width * height >= FLOAT_EXACT:
        raise ValueError(f"{len(entries)} cards / {width}x{height} texels: beyond exact float integers")
    cards = np.zeros((max(len(entries), 1), CARD_TEXELS, 4), np.float32)
    texel_card = np.full((height, width), -1.0, np.float32)
    texels = 0
    for row, ((i, e), (lx, ly)) in enumerate(zip(entries, pos)):   # a loop over cards, not texels
        x, y, w, h = e["rect"]
        cards[row, 0] = (i, e["axis"], lx, ly)
        cards[row, 1] = (x, y, w, h)
        cards[row, 2] = (*e["rect_min"], *e["rect_max"])
        cards[row, 3] = (e["near"], e["far"], 0.0, 0.0)
        texel_card[ly:ly + h, lx:lx + w] = row
        texels += w * h
    # at least 1 x 1: a bake whose every object is under Min Card Size has an empty atlas
    size = tuple(max(int(s), 1) for s in atlas.size) if atlas is not None else (1, 1)
    return PackedCards(cards, inst_rows, texel_card, (width, height), size, texels)


def card_texel_world(packed: PackedCards, layers: dict, matrices) -> dict:
    """numpy twin of surface_cache_lib.glsl's sc_texel_surface for every lighting texel: world
    position, world normal, albedo and the texel mask (tests compare the GPU against it).
    `layers`: the bake atlas layers (atlas.Atlas.layers); `matrices`: world 4x4 per instance."""
    h, w = packed.texel_card.shape
    rows = packed.texel_card.astype(np.int64)
    ys, xs = np.nonzero(rows >= 0)
    r = rows[ys, xs]
    c = packed.cards[r]
    inst, axis = c[:, 0, 0].astype(np.int64), c[:, 0, 1].astype(np.int64)
    i = xs - c[:, 0, 2].astype(np.int64)
    j = ys - c[:, 0, 3].astype(np.int64)
    ax_, ay_ = c[:, 1, 0].astype(np.int64) + i, c[:, 1, 1].astype(np.int64) + j
    res = c[:, 1, 2:4].astype(np.float64)
    rect_min, rect_max = c[:, 2, 0:2].astype(np.float64), c[:, 2, 2:4].astype(np.float64)
    uv = rect_min + (np.stack([i, j], 1) + 0.5) * (rect_max - rect_min) / res
    depth = layers["depth"][ay_, ax_, 0]
    p = np.zeros((len(r), 3))
    plane = np.array([PLANE[a] for a in range(6)])[axis]
    p[np.arange(len(r)), plane[:, 0]] = uv[:, 0]
    p[np.arange(len(r)), plane[:, 1]] = uv[:, 1]
    p += AXES[axis] * (c[:, 3, 0:1] + depth[:, None])
    mats = np.asarray(matrices, np.float64)[inst]
    pw = np.einsum("nij,nj->ni", mats[:, :3, :3], p) + mats[:, :3, 3]
    nl = layers["normal"][ay_, ax_]
    nw = np.einsum("nji,nj->ni", np.linalg.inv(mats[:, :3, :3]), nl)
    nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-12)
    valid = layers["opacity"][ay_, ax_, 0] > 0.5
    out = {"position": np.zeros((h, w, 3)), "normal": np.zeros((h, w, 3)),
           "albedo": np.zeros((h, w, 3)), "valid": np.zeros((h, w), bool)}
    out["position"][ys, xs], out["normal"][ys, xs] = pw, nw
    out["albedo"][ys, xs] = layers["albedo"][ay_, ax_]
    out["valid"][ys, xs] = valid
    return out
