"""The card atlas packer (lumen_addon/atlas.py: a skyline over several widths) on a real card set:
the 'yard' benchmark scene's 30 cards (bench/quality_scenes.py; two 281x281 cards and many
thin ones). One fixed width (the square root of 1.1 x the area, rounded up to 64) packed them
into 512x616 texels, 61% occupied; xatlas, given each card as its own chart, 84%
(bench/atlas_packing.py)."""
import numpy as np

from lumen_addon.atlas import PADDING, pack

YARD = [(281, 7)] * 4 + [(281, 281)] * 2 + [(7, 57)] * 2 + [(121, 57)] * 2 + [(121, 7)] * 2 + \
    [(41, 4)] * 2 + [(81, 4)] * 2 + [(81, 41)] * 2 + [(15, 15)] * 6 + [(17, 25)] * 4 + \
    [(17, 17)] * 2


def reservations_ok(pos, sizes, size, padding):
    r = np.concatenate([pos - padding, pos + sizes + padding], axis=1)
    inside = (r[:, :2] >= 0).all() and (r[:, 2] <= size[0]).all() and (r[:, 3] <= size[1]).all()
    overlap = ((r[:, None, 0] < r[None, :, 2]) & (r[None, :, 0] < r[:, None, 2])
               & (r[:, None, 1] < r[None, :, 3]) & (r[None, :, 1] < r[:, None, 3]))
    np.fill_diagonal(overlap, False)
    return inside and not overlap.any()


def test_packer_fills_the_atlas_of_a_real_card_set():
    sizes = np.array(YARD)
    pos, size = pack(sizes, PADDING)
    assert reservations_ok(pos, sizes, size, PADDING)
    occupancy = (sizes[:, 0] * sizes[:, 1]).sum() / (size[0] * size[1])
    assert occupancy > 0.85, (size, occupancy)          # 0.61 with one width, xatlas 0.84
    # the lighting atlas's use: no padding, sizes in whole 4x4 blocks stay block-aligned
    blocks = -(-sizes // 4) * 4
    pos, size = pack(blocks, 0)
    assert reservations_ok(pos, blocks, size, 0) and not (pos % 4).any()
    assert (blocks[:, 0] * blocks[:, 1]).sum() / (size[0] * size[1]) > 0.9
