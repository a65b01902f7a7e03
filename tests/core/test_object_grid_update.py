"""The object grid's incremental update (gpu_shaders/object_grid.py: build_object_grid with
`previous` and `boxes`): after rows of the object table change, measuring again only the cells
within the reach of their old and new boxes gives exactly the texels of a full build, over
chains of moves, with crowded (capped) cells, and when a move changes the grid's box (then it
builds everything, and says so). numpy only."""
import numpy as np
import pytest

from gpu_shaders.object_grid import build_object_grid, changed_boxes
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
        assert {k: v for k, v in info.items() if k not in ("lists", "incremental")} == \
            {k: v for k, v in full_info.items() if k not in ("lists", "incremental")}
        rows, done = new, done + 1
    assert done == 5
    if cap == 3:
        assert info["truncated"] + info["overflow"] > 0       # crowded cells were exercised

    # nothing changed: the same texels from the kept lists
    same, info2 = build_object_grid(rows, cap=cap, previous=info["lists"],
                                    boxes=changed_boxes(rows, rows, 256))
    assert info2["incremental"]
    np.testing.assert_array_equal(same, build_object_grid(rows, cap=cap)[0])


def test_a_move_that_grows_the_grid_builds_it_all():
    rng = np.random.default_rng(9)
    rows = _scene(rng, 60)
    _, info = build_object_grid(rows)
    new = rows.copy()
    new[5] = _row(rng, (14.0, 0.0, 0.5), (0.2, 0.2, 0.2), 0.05)          # beyond the floor
    texels, info = build_object_grid(new, previous=info["lists"],
                                     boxes=changed_boxes(rows, new, 256))
    assert not info["incremental"]
    np.testing.assert_array_equal(texels, build_object_grid(new)[0])
    # too many rows changed, or the table's size: everything (None)
    assert changed_boxes(rows, _move(rng, rows, 40), 16) is None
    assert changed_boxes(rows, rows[:-1], 256) is None
