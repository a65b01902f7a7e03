"""The bake measures how far the trilinear field reads a mesh's convex edges off its surface
(lumen_addon.sdf.edge_rounding), what the shadow cones add to a thick mesh's occluders up to a
quarter voxel (gpu_shaders/packing.edge_voxels), instead of a fixed quarter voxel.

Closed forms, for a box's right-angled edges: on samples the field is exact there (0); midway
between samples in both axes it reads (sqrt(2)/2 + 1/2 + 1/2 - 1/2) / 4 = 0.302 voxel (the four
samples around the edge: one outside diagonally, two outside beside it, one inside).
"""
import numpy as np
import pytest

import shapes
from gpu_shaders import packing
from lumen_addon.sdf import bake_mesh_sdf, edge_rounding

MIDWAY = (np.sqrt(0.5) + 0.5) / 4


def baked(half):
    v, f = shapes.box(half)
    sdf = bake_mesh_sdf(v, f, voxel_density=20.0)
    offset = ((np.asarray(half) - sdf.origin) / sdf.voxel_size) % 1.0   # faces off the samples
    return sdf, offset, (v, f)


@pytest.mark.parametrize("half", [(0.25, 0.25, 0.25), (0.1, 0.5, 0.5)])
def test_edges_on_samples_read_no_rounding(half):
    sdf, offset, _ = baked(half)
    assert np.allclose(np.minimum(offset, 1 - offset), 0.0, atol=1e-6)
    print(half, sdf.edge_voxels)
    assert sdf.edge_voxels[0] < 0.03                    # uint8 quantisation: 8 / 255 voxel
    assert packing.edge_voxels(sdf) == pytest.approx(sdf.edge_voxels[0])


def test_edges_midway_read_the_closed_form():
    sdf, offset, _ = baked((0.3, 0.3, 0.3))
    assert np.allclose(offset, 0.5, atol=1e-6)
    print(sdf.edge_voxels, MIDWAY)
    assert sdf.edge_voxels[0] == pytest.approx(MIDWAY, abs=0.03)
    # the shadow cones add at most the quarter voxel (their penumbra already darkens the edge)
    assert packing.edge_voxels(sdf) == packing.EDGE_VOXELS


def test_no_sharp_edge_and_old_bakes_fall_back():
    sdf, _, _ = baked((0.3, 0.3, 0.3))
    v, f = shapes.icosphere(0.5, 3)                     # 5 degrees between faces: no sharp edge
    assert edge_rounding(sdf, v, f) is None
    sdf.edge_voxels = []                                # a bake from before the measurement
    assert packing.edge_voxels(sdf) == packing.EDGE_VOXELS
    sdf.edge_voxels = [None, None, None]
    assert packing.edge_voxels(sdf) == packing.EDGE_VOXELS
