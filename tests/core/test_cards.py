"""Mesh cards, capture and atlas against exact answers."""
import numpy as np
import pytest

import shapes
from shapes import shared_mesh_names
from lumen_addon.atlas import LAYERS, PADDING, build_atlas, pack, split_atlas
from lumen_addon.cards import AXES, PLANE, bake_mesh_cards
from lumen_addon.geometry import MeshError
from lumen_addon.materials import Material, sample_texture


def test_cube_six_cards_exact():
    v, f = shapes.box((0.5, 0.5, 0.5))
    mc = bake_mesh_cards(v, f, texel_density=20)
    assert len(mc.cards) == 6 and mc.coverage == 1.0
    for c in mc.cards:
        assert c.opacity.all()                               # every texel sees the cube
        expected = -AXES[c.axis]                              # the face looking back at the card
        assert np.array_equal(c.normal.reshape(-1, 3), np.tile(expected, (c.opacity.size, 1)))
        exact = -0.5 - c.near                                 # depth of the face from the near plane
        assert np.abs(c.depth - exact).max() <= c.texel_size().max()
        assert np.allclose(c.albedo, 0.8)                     # plain grey without materials


def checker(n=8, texels=64):
    """A texture of n x n squares, alternating two colours (exact in 8 bits)."""
    i = np.arange(texels) * n // texels
    mask = (i[:, None] + i[None, :]) % 2 == 0
    a, b = np.array([200, 30, 90]) / 255, np.array([10, 220, 160]) / 255
    return np.where(mask[:, :, None], a, b).astype(np.float32), a, b


def plane(size=1.0):
    s = size / 2
    v = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = (v[:, :2] / size + 0.5)[f]                           # UV (0,0) at (-s,-s), (1,1) at (s,s)
    return v, f, uv


def test_textured_plane_round_trip():
    tex, a, b = checker()
    v, f, uv = plane()
    mc = bake_mesh_cards(v, f, texel_density=100, uvs=uv, materials=[Material(base_color_texture=tex)])
    card = next(c for c in mc.cards if c.axis == 5)           # looking down (-Z) at the top face
    w, h = card.resolution
    iu, iv = PLANE[card.axis]
    ts = card.texel_size()
    x = card.rect_min[0] + (np.arange(w) + 0.5) * ts[0]
    y = card.rect_min[1] + (np.arange(h) + 0.5) * ts[1]
    Y, X = np.meshgrid(y, x, indexing="ij")
    tu, tv = X + 0.5, Y + 0.5                                 # the UVs at the texel centres
    # Away from checker edges (one texture texel plus one card texel), the colour is exact.
    edge = 1 / 64 + ts.max()
    cell = 1 / 8
    far_u = np.abs(((tu + cell / 2) % cell) - cell / 2) > edge
    far_v = np.abs(((tv + cell / 2) % cell) - cell / 2) > edge
    inside = (tu > edge) & (tu < 1 - edge) & (tv > edge) & (tv < 1 - edge)
    sel = far_u & far_v & inside
    assert sel.sum() > 0.3 * sel.size
    want = sample_texture(tex, np.stack([tu[sel], tv[sel]], 1))
    assert np.abs(card.albedo[sel] - want).max() <= 1 / 255
    colours = card.albedo[sel]
    is_a = np.all(np.abs(colours - a) <= 1 / 255, axis=1)
    is_b = np.all(np.abs(colours - b) <= 1 / 255, axis=1)
    assert (is_a | is_b).all() and is_a.any() and is_b.any()


def test_emission_strength_comes_through():
    v, f = shapes.box()
    mat = Material(base_color=(0.2, 0.3, 0.4), emission_color=(1.0, 0.5, 0.25), emission_strength=7.5)
    mc = bake_mesh_cards(v, f, texel_density=10, materials=[mat])
    for c in mc.cards:
        lit = c.opacity > 0
        assert np.allclose(c.emissive[lit], [7.5, 3.75, 1.875])
        assert np.allclose(c.albedo[lit], [0.2, 0.3, 0.4])


def test_material_ids_select_materials():
    v, f = shapes.box()
    ids = np.where(np.arange(len(f)) < 6, 0, 1)
    red, blue = Material(base_color=(1, 0, 0)), Material(base_color=(0, 0, 1))
    mc = bake_mesh_cards(v, f, texel_density=10, material_ids=ids, materials=[red, blue])
    colours = np.concatenate([c.albedo[c.opacity > 0] for c in mc.cards])
    assert {tuple(x) for x in np.unique(colours, axis=0)} == {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)}


def test_colour_attribute_is_interpolated_across_each_triangle():
    """A vertex_colors material's albedo is the per-corner colours, interpolated with the
    texel's barycentric coordinates (exact: a plane whose colour is linear in x and y); another
    material on the same mesh keeps its base colour."""
    v, f, _ = plane()
    colour = lambda p: np.stack([0.5 + 0.4 * p[..., 0], 0.5 + 0.4 * p[..., 1],   # noqa: E731
                                 np.full(p.shape[:-1], 0.25)], -1)
    colors = colour(v[f]).astype(np.float32)                  # (T, 3, 3), linear in x, y
    painted = Material(base_color=(0.0, 1.0, 0.0), vertex_colors=True)
    mc = bake_mesh_cards(v, f, texel_density=64, colors=colors, materials=[painted],
                         material_ids=np.zeros(len(f), np.int64))
    card = next(c for c in mc.cards if c.axis == 5)           # looking down at the top face
    w, h = card.resolution
    ts = card.texel_size()
    x = card.rect_min[0] + (np.arange(w) + 0.5) * ts[0]
    y = card.rect_min[1] + (np.arange(h) + 0.5) * ts[1]
    Y, X = np.meshgrid(y, x, indexing="ij")
    lit = card.opacity > 0
    want = colour(np.stack([X, Y], -1))
    assert lit.sum() > 0.9 * lit.size
    assert np.abs(card.albedo[lit] - want[lit]).max() < 1e-5
    # a second material without the flag: its base colour, the colours ignored
    ids = np.array([0, 1])
    mc = bake_mesh_cards(v, f, texel_density=64, colors=colors, material_ids=ids,
                         materials=[painted, Material(base_color=(0.1, 0.2, 0.3))])
    card = next(c for c in mc.cards if c.axis == 5)
    got = card.albedo[card.opacity > 0]
    plain = np.all(np.abs(got - (0.1, 0.2, 0.3)) < 1e-6, axis=1)
    assert 0.3 < plain.mean() < 0.7


def test_a_cut_out_reflects_only_where_its_alpha_is():
    """A cut-out's cards (Material.alpha_clip) keep the whole faces but weigh the albedo by the
    texture's alpha: away from the holes' edges a texel is the colour or black; the same
    texture without the flag is the colour everywhere (alpha ignored)."""
    colour = np.array([0.2, 0.6, 0.3], np.float32)
    i = np.arange(8) // 2
    tex = np.ones((8, 8, 4), np.float32)
    tex[..., :3] = colour
    tex[..., 3] = ((i[:, None] + i[None, :]) % 2).astype(np.float32)
    v, f, uv = plane()
    for clip in (True, False):
        mc = bake_mesh_cards(v, f, texel_density=64, uvs=uv,
                             materials=[Material(base_color_texture=tex, alpha_clip=clip)])
        card = next(c for c in mc.cards if c.axis == 5)
        got = card.albedo[card.opacity > 0]
        if not clip:
            assert np.allclose(got, colour, atol=1e-6)
            continue
        solid = np.all(np.abs(got - colour) < 1e-5, axis=1)
        hole = np.all(np.abs(got) < 1e-5, axis=1)
        assert solid.mean() > 0.1 and hole.mean() > 0.1        # bilinear: edges blend a texel
        assert abs(got.mean(0)[1] / colour[1] - 0.5) < 0.05    # half of the light reflected


def test_room_with_pillar_seen_from_inside():
    v, f = shapes.room_with_pillar()
    mc = bake_mesh_cards(v, f, texel_density=20)
    assert mc.coverage >= 0.99
    # From outside a room shows only back faces: the bounds cards of the four walls' axes see
    # nothing and are dropped, so cost no texels.
    from lumen_addon.cards import _Surface, place_cards
    placed = place_cards(_Surface(v, f, 4096))
    assert len(mc.cards) <= len(placed) - 4


@pytest.mark.parametrize("name", shared_mesh_names() or ["<none>"])
def test_shared_mesh_coverage(shared_mesh, name):
    v, f = shared_mesh(name)
    extent = float((v.max(0) - v.min(0)).max())
    mc = bake_mesh_cards(v, f, texel_density=64 / extent)
    assert mc.coverage >= 0.99, f"{name}: coverage {mc.coverage:.4f}"
    assert len(mc.cards) <= 32


def test_resolution_clamped():
    v, f = shapes.box((50.0, 0.001, 0.5))
    mc = bake_mesh_cards(v, f, texel_density=20)
    for c in mc.cards:
        assert all(4 <= r <= 512 for r in c.resolution)


def test_atlas_packing_no_overlap_and_padding():
    rng = np.random.default_rng(1)
    sizes = rng.integers(4, 180, (400, 2))
    pos, (w, h) = pack(sizes, PADDING)
    r = np.concatenate([pos - PADDING, pos + sizes + PADDING], axis=1)
    assert (r[:, :2] >= 0).all() and (r[:, 2] <= w).all() and (r[:, 3] <= h).all()
    overlap = ((r[:, None, 0] < r[None, :, 2]) & (r[None, :, 0] < r[:, None, 2])
               & (r[:, None, 1] < r[None, :, 3]) & (r[None, :, 1] < r[:, None, 3]))
    np.fill_diagonal(overlap, False)
    assert not overlap.any()


def test_atlas_border_repeats_card_edges_and_splits_back():
    v, f = shapes.icosphere(0.5, 2)
    mc = bake_mesh_cards(v, f, texel_density=16)
    atlas = build_atlas({"m": mc})
    for e, c in zip(atlas.table, mc.cards):
        x, y, w, h = e["rect"]
        alb = atlas.layers["albedo"]
        assert np.array_equal(alb[y:y + h, x:x + w], c.albedo)
        # Padding: bilinear lookups one texel outside the card read the card's own edge.
        assert np.array_equal(alb[y - 1, x:x + w], c.albedo[0])
        assert np.array_equal(alb[y:y + h, x + w], c.albedo[:, -1])
    back = split_atlas(atlas, {"m": mc.coverage})["m"]
    for a, b in zip(mc.cards, back.cards, strict=True):
        for name in LAYERS:
            assert np.array_equal(getattr(a, name), getattr(b, name))


def test_bad_attributes_fall_back_with_warnings():
    v, f = shapes.box()
    tex, _, _ = checker()
    mc = bake_mesh_cards(v, f, texel_density=10,
                         materials=[Material(base_color=(0.1, 0.2, 0.3), base_color_texture=tex)])
    assert any("no UVs" in w for w in mc.warnings)
    assert np.allclose(mc.cards[0].albedo[mc.cards[0].opacity > 0], [0.1, 0.2, 0.3])
    mc = bake_mesh_cards(v, f, texel_density=10, normals=np.zeros((3, 3)), uvs=np.full((len(f), 3, 2), np.nan))
    assert any("normals ignored" in w for w in mc.warnings) and any("UVs ignored" in w for w in mc.warnings)
    with pytest.raises(MeshError, match="degenerate"):
        bake_mesh_cards(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), np.array([[0, 1, 2]]))


def test_sheet_is_captured_from_both_sides():
    """An open sheet's back is surface, two-sided or not (Cycles and EEVEE shade and emit on both
    sides of a face; only a closed part hides its backs, its inside)."""
    v, f, _ = plane()
    for mc in (bake_mesh_cards(v, f, texel_density=20),
               bake_mesh_cards(v, f, texel_density=20, two_sided=True)):
        assert sorted(AXES[c.axis][2] for c in mc.cards) == [-1.0, 1.0]
        assert mc.coverage == 1.0
        for c in mc.cards:                                           # normals face each card
            assert np.allclose(c.normal[c.opacity > 0], -AXES[c.axis])


def test_closed_mesh_hides_its_backs():
    v, f = shapes.box()
    mc = bake_mesh_cards(v, f, texel_density=10)
    assert sorted(c.axis for c in mc.cards) == list(range(6))
    for c in mc.cards:                                               # outside faces only
        assert np.allclose(c.normal[c.opacity > 0], -AXES[c.axis])
