"""global_sdf_ref.merge_boxes: the changed cell boxes a global-SDF level refreshes, merged where
they overlap or touch (a dragged object's boxes, one per redraw, become one refresh)."""
import numpy as np

from gpu_shaders.global_sdf_ref import merge_boxes


def test_a_drag_becomes_one_box_and_apart_stays_apart():
    drag = [((k, 0, 0), (k + 4, 4, 2)) for k in range(8)]          # one cell further each redraw
    assert merge_boxes(drag) == [((0, 0, 0), (11, 4, 2))]
    apart = [((0, 0, 0), (2, 2, 2)), ((5, 5, 5), (6, 6, 6))]
    assert sorted(merge_boxes(apart)) == sorted(apart)
    assert merge_boxes([((0, 0, 0), (2, 2, 2)), ((2, 0, 0), (3, 2, 2))]) == \
        [((0, 0, 0), (3, 2, 2))]                                    # touching: one
    assert merge_boxes([]) == []


def test_merged_boxes_cover_every_cell_and_do_not_overlap():
    rng = np.random.default_rng(3)
    for _ in range(200):
        boxes = []
        for _ in range(rng.integers(1, 12)):
            a = rng.integers(0, 20, 3)
            boxes.append((tuple(a), tuple(a + rng.integers(1, 5, 3))))
        out = merge_boxes(boxes)
        grid = np.zeros((30, 30, 30), bool)
        for a, b in boxes:
            grid[a[0]:b[0], a[1]:b[1], a[2]:b[2]] = True
        cover = np.zeros_like(grid)
        for a, b in out:
            cover[a[0]:b[0], a[1]:b[1], a[2]:b[2]] = True
        assert not (grid & ~cover).any()
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                (a0, b0), (a1, b1) = out[i], out[j]
                assert not (np.all(np.array(a0) <= b1) and np.all(np.array(a1) <= b0))
