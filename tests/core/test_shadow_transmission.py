"""lumen_addon.materials.shadow_transmission: the share of light a mesh's cut-out holes let
through one layer of its surface (the shadow cones' share, light_lib.glsl), against exact areas."""
import numpy as np

from lumen_addon.materials import Material, shadow_transmission

QUAD_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
QUAD_T = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)


def holes(n: int = 4, texels: int = 8, open_every: int = 2) -> np.ndarray:
    """RGBA texels of an n x n grid of squares, every open_every-th one alpha 0."""
    i = np.arange(texels) * n // texels
    tex = np.ones((texels, texels, 4), np.float32)
    tex[..., 3] = ((i[:, None] + i[None, :]) % open_every != 0).astype(np.float32)
    return tex


def cut(tex) -> Material:
    return Material(base_color_texture=tex, alpha_clip=True)


def test_a_checker_of_holes_lets_half_through():
    assert abs(shadow_transmission(QUAD_V, QUAD_T, QUAD_UV, np.zeros(2, int),
                                   [cut(holes())]) - 0.5) < 0.01


def test_area_weighted_over_materials_and_triangle_sizes():
    # triangle 0 (half the quad) opaque, triangle 1 a checker: a quarter of the area is holes
    got = shadow_transmission(QUAD_V, QUAD_T, QUAD_UV, np.array([1, 0]),
                              [cut(holes()), Material()])
    assert abs(got - 0.25) < 0.01
    # a fine grid of 16 x 16 squares, one in three open, on a quad scaled 3 x 1
    v = QUAD_V * [3.0, 1.0, 1.0]
    got = shadow_transmission(v, QUAD_T, QUAD_UV, np.zeros(2, int),
                              [cut(holes(16, 64, 3))])
    i = np.arange(16)
    exact = float(((i[:, None] + i[None, :]) % 3 == 0).mean())
    assert abs(got - exact) < 0.02


def test_opaque_without_uvs_and_bad_input_pass_nothing():
    ids = np.zeros(2, int)
    assert shadow_transmission(QUAD_V, QUAD_T, QUAD_UV, ids, [Material()]) == 0.0
    assert shadow_transmission(QUAD_V, QUAD_T, None, ids, [cut(holes())]) == 0.0
    # a texture but no alpha test (alpha_clip off): opaque
    assert shadow_transmission(QUAD_V, QUAD_T, QUAD_UV, ids,
                               [Material(base_color_texture=holes())]) == 0.0
    # a NaN vertex: its triangles weigh nothing, the result is finite
    v = QUAD_V.copy()
    v[1] = np.nan
    got = shadow_transmission(v, QUAD_T, QUAD_UV, ids, [cut(holes())])
    assert np.isfinite(got) and 0.0 <= got <= 1.0
    # degenerate: every triangle of zero area
    assert shadow_transmission(np.zeros((4, 3)), QUAD_T, QUAD_UV, ids, [cut(holes())]) == 0.0
    # a texture of one channel (no alpha): opaque
    assert shadow_transmission(QUAD_V, QUAD_T, QUAD_UV, ids,
                               [cut(np.ones((4, 4), np.float32))]) == 0.0
