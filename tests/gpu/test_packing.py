"""The texture arrays of gpu_shaders.packing, exactly, for a hand-made two-mesh scene (no bpy)."""
from types import SimpleNamespace

import numpy as np
import pytest

from gpu_shaders.packing import OBJECT_TEXELS, atlas_grid, brick_cell, pack_scene
from lumen_addon.sdf import MeshSDF, SDFMip


def mesh(indirection, n_bricks, seed, origin, h):
    rng = np.random.default_rng(seed)
    ind = np.array(indirection, np.int32)
    res = tuple(int(n) * 7 for n in ind.shape)
    bricks = rng.integers(0, 256, (n_bricks, 8, 8, 8)).astype(np.uint8)
    return MeshSDF(origin=np.array(origin, float), bounds_min=np.array(origin, float) + h,
                   bounds_max=np.array(origin, float) + np.array(res) * h - h, two_sided=False,
                   mips=[SDFMip(h, res, ind, bricks)])


@pytest.fixture
def scene():
    a = mesh([[[0]], [[-2]]], 1, 1, (-1.0, -0.5, -0.25), 0.1)             # grid 2x1x1
    b = mesh([[[-1, 0], [1, -2]]], 2, 2, (0.0, 0.0, 0.0), 0.05)            # grid 1x2x2
    m2 = np.eye(4)
    m2[:3, :3] *= 2.0
    m2[:3, 3] = (3.0, 0.0, 1.0)
    m3 = np.eye(4)
    m3[:3, 3] = (0.0, 5.0, 0.0)
    instances = [SimpleNamespace(name="A1", mesh="a", matrix_world=np.eye(4)),
                 SimpleNamespace(name="B", mesh="b", matrix_world=m2),
                 SimpleNamespace(name="A2", mesh="a", matrix_world=m3)]
    return {"a": a, "b": b, "unused": mesh([[[0]]], 1, 3, (0, 0, 0), 1.0)}, instances


def test_indirection_table_and_offsets(scene):
    meshes, instances = scene
    p = pack_scene(meshes, instances)
    assert p.mesh_keys == ["a", "b"]                 # the unused mesh is not packed
    assert p.brick_offset == {"a": 0, "b": 1} and p.indirection_offset == {"a": 0, "b": 2}
    assert p.bricks == 3
    # a: x fastest [0, -2]; b (1x2x2): (0,0,0) -1, (0,1,0) 1+1, (0,0,1) 0+1, (0,1,1) -2
    assert p.indirection.dtype == np.int32
    assert p.indirection.tolist() == [[0, -2, -1, 2, 1, -2]]
    narrow = pack_scene(meshes, instances, indirection_width=4)
    assert narrow.indirection.tolist() == [[0, -2, -1, 2], [1, -2, -1, -1]]


def test_atlas_holds_every_brick_at_its_cell(scene):
    meshes, instances = scene
    p = pack_scene(meshes, instances)
    assert p.atlas_bricks == (2, 2, 1) and p.atlas_size == (16, 16, 8)
    assert p.atlas.shape == (8, 16, 16) and p.atlas.dtype == np.uint8    # [z, y, x]
    bricks = np.concatenate([meshes["a"].mips[0].bricks, meshes["b"].mips[0].bricks])
    x, y, z = np.meshgrid(*(np.arange(8),) * 3, indexing="ij")
    for s, brick in enumerate(bricks):
        cx, cy, cz = brick_cell(s, p.atlas_bricks)
        np.testing.assert_array_equal(p.atlas[8 * cz + z, 8 * cy + y, 8 * cx + x], brick)
    assert not p.atlas[0:8, 8:16, 8:16].any()       # the fourth cell is empty
    # Flattened as uploaded (x fastest), texel (x, y, z) is at x + W*(y + H*z).
    flat = p.atlas.reshape(-1)
    assert flat[3 + 16 * (5 + 16 * 7) + 8] == bricks[1][3 + 8 - 8, 5, 7]


def test_object_table_rows(scene):
    meshes, instances = scene
    p = pack_scene(meshes, instances)
    assert p.objects.shape == (3, OBJECT_TEXELS, 4) and p.objects.dtype == np.float32
    assert p.instance_names == ["A1", "B", "A2"]
    b = p.objects[1]
    expect_inv = np.eye(4)
    expect_inv[:3, :3] *= 0.5
    expect_inv[:3, 3] = (-1.5, 0.0, -0.5)
    np.testing.assert_array_equal(b[0:4], expect_inv.astype(np.float32))
    np.testing.assert_array_equal(b[4], np.float32([0, 0, 0, 0.05]))
    np.testing.assert_array_equal(b[5], np.float32([1, 2, 2, 0.2]))          # grid, band = 4 voxels
    np.testing.assert_array_equal(b[6], np.float32([0.05, 0.05, 0.05, 2]))   # bounds_min, offset
    np.testing.assert_array_equal(b[7], np.float32([0.3, 0.65, 0.65, 2.0]))  # bounds_max, scale
    a2 = p.objects[2]
    np.testing.assert_array_equal(a2[0:4, 3], np.float32([0, -5, 0, 1]))
    np.testing.assert_array_equal(a2[6], np.float32([-0.9, -0.4, -0.15, 0]))
    np.testing.assert_array_equal(a2[7, 3], np.float32(1.0))
    np.testing.assert_array_equal(p.objects[0, 4:8], p.objects[2, 4:8][[0, 1, 2, 3]])
    # world bounding sphere of the mesh bounds grown by half a voxel (0.025 .. 0.325 x 0.675 x
    # 0.675, scale 2): centre of the scaled, moved box, radius half its diagonal
    np.testing.assert_allclose(b[8, :3], [3.35, 0.7, 1.7], atol=1e-6)
    np.testing.assert_allclose(b[8, 3], np.linalg.norm([0.3, 0.65, 0.65]), rtol=1e-4)


def test_atlas_grid_limits():
    assert atlas_grid(0) == (1, 1, 1) and atlas_grid(1) == (1, 1, 1)
    assert atlas_grid(8) == (2, 2, 2) and atlas_grid(9) == (3, 3, 1)
    assert atlas_grid(27) == (3, 3, 3) and atlas_grid(28) == (4, 4, 2)
    ax, ay, az = atlas_grid(20_000_000 // 2)
    assert max(ax, ay, az) <= 256 and ax * ay * az >= 10_000_000
    with pytest.raises(ValueError):
        atlas_grid(256 ** 3 + 1)


def test_missing_mesh_is_an_error(scene):
    meshes, instances = scene
    with pytest.raises(KeyError):
        pack_scene({"a": meshes["a"]}, instances)
