"""The object grid's incremental update (gpu_shaders/object_grid.py: build_object_grid with
`previous` and `boxes`): after rows of the object table change, measuring again only the cells
within the reach of their old and new boxes gives exactly the texels of a full build, over
chains of moves, with crowded (capped) cells, and when a move changes the grid's box (then it
builds everything, and says so). numpy only."""
import numpy as np
import pytest

from gpu_shaders.object_grid import (FINE_CELLS, GRID_MAX, _coarse_box, _layout,
                                     build_object_grid, changed_boxes)
from gpu_shaders.packing import object_row


def _row(rng, location, half, voxel, angle=0.0, scale=1.0):
    """An object-table row: a box mesh of half-size `half` placed at `location` (rotated about z,
    uniformly scaled)."""
    c, s = np.cos(angle), np.sin(angle)
    mw = np.eye(4)
    mw[:3, :3] = scale * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    mw[:3, 3] = location
    h = np.asarray(half, np.float64)
    return object_row(np.linalg.inv(mw), -h, voxel, (1, 1, 1), 4.0, -h, h, 0, scale)


def _scene(rng, n):
    rows = [_row(rng, (0.0, 0.0, -0.05), (10.0, 10.0, 0.05), 0.1)]       # the floor: the box
    for _ in range(n):
        rows.append(_row(rng, (*rng.uniform(-9.0, 9.0, 2), rng.uniform(0.2, 1.0)),
                         rng.uniform(0.05, 0.4, 3), rng.choice([0.02, 0.05]),
                         rng.uniform(0.0, 6.28), rng.uniform(0.7, 1.3)))
    return np.stack(rows)


def _move(rng, rows, k, step=0.5):
    new = rows.copy()
    for i in rng.choice(np.arange(1, len(rows)), k, replace=False):
        mw = np.linalg.inv(rows[i, 0:4].astype(np.float64))
        mw[:3, 3] += (*rng.uniform(-step, step, 2), 0.0)
        half = (rows[i, 7, :3] - rows[i, 6, :3]) / 2
        new[i] = object_row(np.linalg.inv(mw), -half, rows[i, 4, 3], (1, 1, 1), 4.0, -half,
                            half, 0, float(rows[i, 7, 3]))
    return new


@pytest.mark.parametrize("cap", [1024, 3])
def test_incremental_grid_equals_a_full_build(cap):
    rng = np.random.default_rng(5)
    rows = _scene(rng, 300)
    _, info = build_object_grid(rows, cap=cap)
    assert not info["incremental"]
    done = 0
    for k in (1, 1, 3, 12, 1):
        new = _move(rng, rows, k)
        boxes = changed_boxes(rows, new, 256)
        assert len(boxes) >= 1
        texels, info = build_object_grid(new, cap=cap, previous=info["lists"], boxes=boxes)
        full, full_info = build_object_grid(new, cap=cap)
        assert info["incremental"]
        np.testing.assert_array_equal(texels, full)
        skip = ("lists", "incremental", "region")
        assert {k: v for k, v in info.items() if k not in skip} == \
            {k: v for k, v in full_info.items() if k not in skip}
        rows, done = new, done + 1
    assert done == 5
    if cap == 3:
        assert info["truncated"] + info["overflow"] > 0       # crowded cells were exercised

    # nothing changed: the same texels from the kept lists
    same, info2 = build_object_grid(rows, cap=cap, previous=info["lists"],
                                    boxes=changed_boxes(rows, rows, 256))
    assert info2["incremental"] and info2["region"] == []
    np.testing.assert_array_equal(same, build_object_grid(rows, cap=cap)[0])


def test_a_move_that_grows_the_grid_builds_it_all():
    rng = np.random.default_rng(9)
    rows = _scene(rng, 60)
    _, info = build_object_grid(rows)
    new = rows.copy()
    new[5] = _row(rng, (14.0, 0.0, 0.5), (0.2, 0.2, 0.2), 0.05)          # beyond the floor
    texels, info = build_object_grid(new, previous=info["lists"],
                                     boxes=changed_boxes(rows, new, 256))
    assert not info["incremental"] and info["region"] is None
    np.testing.assert_array_equal(texels, build_object_grid(new)[0])
    # too many rows changed, or the table's size: everything (None)
    assert changed_boxes(rows, _move(rng, rows, 40), 16) is None
    assert changed_boxes(rows, rows[:-1], 256) is None


def test_a_far_move_gives_two_regions():
    """An object moved far (its old and new boxes apart) changes two places: the region is two
    boxes, not one spanning the floor between them, and outside both nothing changed."""
    rng = np.random.default_rng(7)
    rows = _scene(rng, 300)
    texels, info = build_object_grid(rows)
    new = rows.copy()
    mw = np.linalg.inv(rows[1, 0:4].astype(np.float64))
    mw[:3, 3] = (-7.0, -7.0, 0.5) if mw[0, 3] > 0 else (7.0, 7.0, 0.5)
    half = (rows[1, 7, :3] - rows[1, 6, :3]) / 2
    new[1] = object_row(np.linalg.inv(mw), -half, rows[1, 4, 3], (1, 1, 1), 4.0, -half, half, 0,
                        float(rows[1, 7, 3]))
    boxes = changed_boxes(rows, new, 256)
    assert len(boxes) == 2                       # old and new place apart
    new_texels, new_info = build_object_grid(new, previous=info["lists"], boxes=boxes)
    regions = new_info["region"]
    assert len(regions) == 2, regions
    (lo0, hi0), (lo1, hi1) = regions
    assert np.any(hi0 < lo1) or np.any(hi1 < lo0)          # apart
    centre, cb, entries = _cell_contents(texels)
    _, new_cb, new_entries = _cell_contents(new_texels)
    out = np.ones(len(centre), bool)
    for lo, hi in regions:
        out &= ~np.all((centre > lo) & (centre < hi), axis=1)
    np.testing.assert_array_equal(cb[out], new_cb[out])
    keep = out[entries[:, 0].astype(np.int64)]
    new_keep = out[new_entries[:, 0].astype(np.int64)]
    np.testing.assert_array_equal(entries[keep], new_entries[new_keep])
    # the two boxes leave out most of what one box around both would hold
    lo_all, hi_all = np.minimum(lo0, lo1), np.maximum(hi0, hi1)
    between = ~np.all((centre > lo_all) & (centre < hi_all), axis=1)
    assert out.mean() > between.mean() + 0.2, (out.mean(), between.mean())


def _cell_contents(texels):
    """Per fine cell of a grid texture: its world centre, (count, B), and its list entries as
    (cell, instance, distance) rows sorted (first list texels differ between builds)."""
    tex = np.asarray(texels, np.float64).reshape(-1, 4)
    lo, cell = tex[0, :3], tex[0, 3]
    dims = np.floor(tex[1, :3] + 0.5).astype(np.int64)
    first_list = int(tex[1, 3])
    n = int(dims.prod())
    ct = tex[3:3 + n]
    idx = np.arange(n)
    xyz = np.stack([idx % dims[0], (idx // dims[0]) % dims[1], idx // (dims[0] * dims[1])], 1)
    centre = lo + (xyz + 0.5) * cell
    counts = np.maximum(np.round(ct[:, 1]).astype(np.int64), 0)
    pairs = tex[first_list:].reshape(-1, 2)
    owner = np.repeat(idx, counts)
    start = np.round(ct[:, 0]).astype(np.int64)
    entry = start[owner] + (np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts))
    rows = np.column_stack([owner, pairs[entry]])
    return centre, ct[:, 1:3], rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("n, cap", [(200, 1024), (600, 1024), (600, 3)])
def test_values_change_only_inside_the_region(n, cap):
    """build_object_grid's `region` (what the viewport's direct light restarts from): outside it
    every cell lists the same instances at the same distances with the same bound B (crowded
    cells capped the same way), so sdf_scene returns there what it did before the move, and no
    moved row is listed there. The region is the re-measured cells that changed: in a denser
    scene, less than the moved object's whole reach."""
    rng = np.random.default_rng(11)
    rows = _scene(rng, n)
    texels, info = build_object_grid(rows, cap=cap)
    for k in (1, 2):
        new = _move(rng, rows, k, step=0.8)
        moved = np.flatnonzero((new != rows).reshape(len(rows), -1).any(axis=1))
        new_texels, new_info = build_object_grid(new, cap=cap, previous=info["lists"],
                                                 boxes=changed_boxes(rows, new, 256))
        assert new_info["incremental"] and new_info["region"]
        centre, cb, entries = _cell_contents(texels)
        _, new_cb, new_entries = _cell_contents(new_texels)
        out = np.ones(len(centre), bool)
        for lo, hi in new_info["region"]:
            out &= ~np.all((centre > lo) & (centre < hi), axis=1)
        assert 0.2 < out.mean() < 1.0          # the region is neither everything nor nothing
        if n == 600 and k == 1:   # one object moved: a part of the cells its reach re-measured
            lay = _layout(new, GRID_MAX, FINE_CELLS)
            a, b = _coarse_box(lay, changed_boxes(rows, new, 256))
            reach_xy = np.prod((b - a + 1)[:2] * lay["cell"])
            grid_lo, grid_hi = lay["lo"], lay["lo"] + lay["dims"] * lay["cell"]
            region_xy = sum(np.prod((np.minimum(hi, grid_hi) - np.maximum(lo, grid_lo))[:2])
                            for lo, hi in new_info["region"])
            assert region_xy < 0.5 * reach_xy, (region_xy, reach_xy)
        np.testing.assert_array_equal(cb[out], new_cb[out])
        keep = out[entries[:, 0].astype(np.int64)]
        new_keep = out[new_entries[:, 0].astype(np.int64)]
        np.testing.assert_array_equal(entries[keep], new_entries[new_keep])
        assert not np.isin(new_entries[new_keep, 1], moved).any()
        # and inside it something did change (else the test shows nothing)
        assert not np.array_equal(cb[~out], new_cb[~out]) or \
            not np.array_equal(entries[~keep], new_entries[~new_keep])
        rows, texels, info = new, new_texels, new_info
