"""Geometry that used to fool the bake (issue 11): inside-out and half-flipped closed meshes, needle
triangles, meshes far from their own origin. Each is checked against an exact answer: the
analytic SDF, the same mesh baked the right way round or at home, or brute-force distances."""
import math

import numpy as np
import pytest

import shapes
from lumen_addon import sdf
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_addon.cards import AXES, bake_mesh_cards
from lumen_addon.geometry import (CLOSED, NON_ORIENTABLE, OPEN, TrianglePairs, brute_force_distance,
                                  orient_triangles)

from test_sdf import stored_samples

FLIPPED = "faces were inside-out and were flipped (a room meant to be seen from inside bakes as Two Sided)"


def assert_same_bake(a, b, p, shift=0.0):
    """b baked from the same surface as a (turned, or moved by `shift`): the same bricks, and
    samples within a quarter voxel of each mip. Not bit-identical: beyond the exact shell of one
    voxel, distances come from closest-triangle propagation, and float32 ties between triangles
    (rounded differently once corners are reordered or moved) can carry another triangle out;
    both stay within check_mesh's half voxel of the exact distance."""
    for k, (ma, mb) in enumerate(zip(a.mips, b.mips, strict=True)):
        assert np.array_equal(ma.indirection, mb.indirection), f"mip {k}: other bricks"
        diff = np.abs(a.sample(p, k) - b.sample(p + shift, k)).max() / ma.voxel_size
        assert diff <= 0.25, f"mip {k}: {diff:.3f} voxels apart"


def sphere_points(n, r_lo, r_hi, seed=1):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True) * rng.uniform(r_lo, r_hi, (n, 1))


def half_flipped(f, seed):
    sel = np.random.default_rng(seed).random(len(f)) < 0.5
    out = f.copy()
    out[sel] = out[sel, ::-1]
    return out, sel


# --- Orientation ---------------------------------------------------------------------------------

def test_inside_out_sphere_bakes_as_the_right_way_round():
    """Every face flipped: the centre was +0.13 m (outside) and every inside point positive."""
    v, f = shapes.icosphere(0.5, 4)
    good = sdf.bake_mesh_sdf(v, f, voxel_density=30)
    bad = sdf.bake_mesh_sdf(v, f[:, ::-1], voxel_density=30)
    assert bad.orientation_notes == [f"5120 {FLIPPED}"]
    assert bad.sample([[0, 0, 0]])[0] == pytest.approx(-bad.mips[0].band)
    assert_same_bake(good, bad, sphere_points(4000, 0.0, 0.7))
    # And it is the analytic sphere (test_sdf.test_sphere's tolerance).
    near = sphere_points(2000, 0.45, 0.55, seed=2)
    exact = np.linalg.norm(near, axis=1) - 0.5
    assert np.abs(bad.sample(near) - exact).max() <= 0.5 * bad.voxel_size + 2e-3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_half_flipped_sphere_is_negative_inside(seed):
    """50% of faces flipped at random: a third to two thirds of inside points were positive."""
    v, f = shapes.icosphere(0.5, 4)
    ff, sel = half_flipped(f, seed)
    m = sdf.bake_mesh_sdf(v, ff, voxel_density=30)
    assert m.orientation_notes == [f"{int(sel.sum())} {FLIPPED}"]
    h = m.voxel_size
    assert (m.sample(sphere_points(4000, 0.0, 0.5 - h)) < 0).all()
    assert (m.sample(sphere_points(4000, 0.5 + h, 0.9)) > 0).all()
    near = sphere_points(2000, 0.45, 0.55, seed=2)
    assert np.abs(m.sample(near) - (np.linalg.norm(near, axis=1) - 0.5)).max() <= 0.5 * h + 2e-3


def test_orientation_of_parts():
    """Which parts turn: inside-out shells do; a hollow object's inner wall and a room seen from
    inside with something in it face inwards on purpose and stay; a triangle soup (STL) is
    welded by position; open parts follow their larger area; a Moebius strip is left alone."""
    v, f = shapes.icosphere(0.5, 3)
    iv, i_f = shapes.icosphere(0.3, 2)
    hv = np.concatenate([v, iv])
    inner = i_f + len(v)

    def flips(vv, ff):
        return orient_triangles(vv, ff).flip

    assert not flips(v, f).any()
    assert flips(v, f[:, ::-1]).all()
    ff, sel = half_flipped(f, 3)
    assert np.array_equal(flips(v, ff), sel)
    # Hollow sphere: the inner wall faces inwards (a cavity) and stays so ...
    assert not flips(hv, np.concatenate([f, inner[:, ::-1]])).any()
    # ... and when only the outer wall is inside-out, only the outer wall turns.
    got = flips(hv, np.concatenate([f[:, ::-1], inner[:, ::-1]]))
    assert got[:len(f)].all() and not got[len(f):].any()
    # A room seen from inside holding a pillar: as modelled. An empty inside-out box turns.
    rv, rf = shapes.room_with_pillar()
    assert not flips(rv, rf).any()
    bv, bf = shapes.box()
    assert flips(bv, bf[:, ::-1]).all()
    # Two spheres, one inside-out: that one turns.
    two = flips(np.concatenate([v, v + [2.0, 0, 0]]), np.concatenate([f, f[:, ::-1] + len(v)]))
    assert not two[:len(f)].any() and two[len(f):].all()
    # Triangle soup: every triangle with its own corners.
    soup = v[f[:, ::-1]].reshape(-1, 3)
    assert flips(soup, np.arange(len(soup)).reshape(-1, 3)).all()
    # Open tube with 100 faces flipped: those turn back, the part is reported as open.
    cv, cf = shapes.open_cylinder()
    cf2 = cf.copy()
    cf2[:100] = cf2[:100, ::-1]
    o = orient_triangles(cv, cf2)
    assert np.array_equal(np.flatnonzero(o.flip), np.arange(100)) and (o.part == OPEN).all()
    assert o.notes() == ["100 faces of an open part faced against the rest of it and were flipped"]
    # Moebius strip: no winding works; nothing flipped, said so.
    n = 48
    u = np.arange(n) / n * 2 * np.pi
    side = [np.stack([(1 + s * 0.3 * np.cos(u / 2)) * np.cos(u), (1 + s * 0.3 * np.cos(u / 2)) * np.sin(u),
                      s * 0.3 * np.sin(u / 2)], 1) for s in (-1, 1)]
    mv = np.concatenate(side)
    i = np.arange(n)
    j = (i + 1) % n
    # After a full turn the strip's -1 side meets its +1 side: the last quad joins them crosswise.
    j_lo, j_hi = np.where(j == 0, n, 0) + j, np.where(j == 0, 0, n) + j
    mf = np.concatenate([np.stack([i, j_lo, i + n], 1), np.stack([j_lo, j_hi, i + n], 1)])
    o = orient_triangles(mv, mf)
    assert (o.part == NON_ORIENTABLE).all() and not o.flip.any() and "non-orientable" in o.notes()[0]
    assert (orient_triangles(v, f).part == CLOSED).all()


def test_scene_bake_names_the_inside_out_object_and_its_cards_face_out():
    """Through bake_scene: the warning names the object, the SDF equals the right way round's,
    and the cards capture the outside (they were placed inside it), with the corner normals
    Blender derives from the flipped winding (pointing in) turned out with the faces."""
    v, f = shapes.icosphere(0.5, 3)
    bv, bf = shapes.box((0.5, 0.5, 0.5))
    tri = bv[bf]
    inward = -np.repeat(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, None], 3, axis=1)
    inward /= np.linalg.norm(inward, axis=2, keepdims=True)
    settings = BakeSettings(voxel_density=20)
    bad = bake_scene([ObjectInput("Inside Out", v, f[:, ::-1]),
                      ObjectInput("Crate", bv, bf[:, ::-1], matrix_world=shapes.matrix((3, 0, 0)),
                                  normals=inward[:, ::-1])], settings)
    good = bake_scene([ObjectInput("Ball", v, f)], settings)
    assert ("Inside Out", f"1280 {FLIPPED}") in bad.warnings
    assert ("Crate", f"12 {FLIPPED}") in bad.warnings
    assert_same_bake(next(iter(good.meshes.values())), bad.meshes[bad.instances[0].mesh],
                     sphere_points(3000, 0.0, 0.7))
    crate = bad.cards[bad.instances[1].cards]
    assert len(crate.cards) == 6 and crate.coverage == 1.0
    for c in crate.cards:
        assert c.opacity.all()
        assert np.allclose(c.normal.reshape(-1, 3), -AXES[c.axis], atol=1e-6)
        assert np.abs(c.depth - (-0.5 - c.near)).max() <= c.texel_size().max()


def test_rooms_and_cavities_are_not_reported():
    """Inward faces on purpose (a furnished room seen from inside, a hollow ball's inner wall, a
    bare room marked two-sided as the warning advises) bake as modelled, without a warning; an
    open tube with flipped faces is reported."""
    rv, rf = shapes.room_with_pillar()
    v, f = shapes.icosphere(0.5, 3)
    iv, i_f = shapes.icosphere(0.3, 2)
    cv, cf = shapes.open_cylinder()
    cf2 = cf.copy()
    cf2[:10] = cf2[:10, ::-1]
    bv, bf = shapes.box((3.0, 2.0, 1.5))
    bake = bake_scene([ObjectInput("Room", rv, rf),
                       ObjectInput("Hollow", np.concatenate([v, iv]), np.concatenate([f, i_f[:, ::-1] + len(v)])),
                       ObjectInput("Tube", cv, cf2),
                       ObjectInput("Bare Room", bv, bf[:, ::-1], two_sided=True)], BakeSettings(voxel_density=8))
    assert bake.warnings == [("Tube", "10 faces of an open part faced against the rest of it and were flipped")]
    bare = bake.meshes[bake.instances[3].mesh]
    assert bare.sample([[0.0, 0.0, 0.0]])[0] > 0          # free space inside
    assert bake.cards[bake.instances[3].cards].coverage >= 0.99
    room = bake.meshes[bake.instances[0].mesh]
    assert room.sample([[-1.0, -1.0, 0.0]])[0] > 0        # in the room: free space
    assert room.sample([[0.8, 0.4, 0.0]])[0] < 0          # in the pillar: solid
    hollow = bake.meshes[bake.instances[1].mesh]
    assert hollow.sample([[0.0, 0.0, 0.0]])[0] > 0        # the cavity is empty
    assert hollow.sample([[0.4, 0.0, 0.0]])[0] < 0        # the wall is solid


# --- Needle and sliver triangles ---------------------------------------------------------------

NEEDLES = {
    # name: corners; 1 m long, 0.1 mm (the case) or 1 um wide, along an oblique axis
    "0.1mm": np.array([[-0.5, -0.3, 0.1], [0.5, 0.3, -0.1], [0.5, 0.3 + 1e-4, -0.1]]),
    "1um": np.array([[-0.5, -0.3, 0.1], [0.5, 0.3, -0.1], [0.5, 0.3, -0.1 + 1e-6]]),
    "axis": np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 1e-4, 0.0]]),
}


@pytest.mark.parametrize("name", NEEDLES)
def test_needle_kernel_is_exact_in_float32(name):
    """The point-triangle kernel in float32 against float64 brute force: the Gram-determinant
    barycentrics it used cancelled to 0 (errors of 6 cm at 1 m); frame coordinates do not."""
    v, f = NEEDLES[name], np.array([[0, 1, 2]])
    p = np.random.default_rng(0).uniform(-1, 1, (20000, 3))
    exact = brute_force_distance(v, f, p)
    got = np.sqrt(TrianglePairs(v, f, np.zeros(3)).distance_sq(p.astype(np.float32), np.zeros(len(p), np.int64)))
    assert np.isfinite(got).all()
    assert np.abs(got - exact).max() <= 1e-6


@pytest.mark.parametrize("name", NEEDLES)
def test_needle_makes_no_phantom_plane(name):
    """A needle alone (two-sided) and on a closed box (one-sided): every stored band sample within
    half a voxel of brute force, the tolerance test_sdf.check_mesh holds every mesh to (it had
    5-16 voxel errors: a plane through the needle)."""
    nv = NEEDLES[name]
    bv, bf = shapes.box((0.5, 0.4, 0.3))
    cases = [(nv, np.array([[0, 1, 2]]), True),
             (np.concatenate([bv, nv + [0.0, 0.0, 0.6]]), np.concatenate([bf, [[8, 9, 10]]]), False)]
    for v, f, two_sided in cases:
        m = sdf.bake_mesh_sdf(v, f, voxel_density=20, two_sided=two_sided)
        for mip in range(len(m.mips)):
            h = m.mips[mip].voxel_size
            pts, dist = stored_samples(m, mip)
            band = np.abs(dist) < 0.99 * m.mips[mip].band
            exact = brute_force_distance(v, f, pts[band])
            got = dist[band] + 0.5 * h if two_sided else np.abs(dist[band])   # two-sided: d - h/2
            err = np.abs(got - exact) / h
            assert err.max() <= 0.5, f"{name} two_sided={two_sided} mip {mip}: {err.max():.2f} voxels"
        if not two_sided:     # the box's inside is still inside
            assert m.sample([[0.0, 0.0, 0.0]])[0] < 0


# --- Far from the origin ---------------------------------------------------------------------

@pytest.mark.parametrize("offset", [1e4, 1e7])
def test_far_from_origin_bakes_as_at_home(offset):
    """A box whose vertices sit 1e7 m from the object's origin lost its signs (15.7% of points
    wrong, 4.3 voxel errors) and its cards (1 card, coverage 0): Embree is float32, 1 m per step
    there. Baked in a frame centred on the mesh, it equals the box at home, moved."""
    half = (0.5, 0.4, 0.3)
    v, f = shapes.box(half)
    shift = np.array([1.0, -0.3, 0.6]) * offset
    home = sdf.bake_mesh_sdf(v, f, voxel_density=20)
    far = sdf.bake_mesh_sdf(v + shift, f, voxel_density=20)
    p = np.random.default_rng(3).uniform(-0.7, 0.7, (20000, 3))
    assert np.allclose(far.origin - shift, home.origin, rtol=0, atol=1e-9 * offset)
    assert_same_bake(home, far, p, shift)
    exact = shapes.box_sdf(p, half)
    ok = np.abs(exact) < far.mips[0].band - math.sqrt(3) * far.voxel_size
    assert np.abs(far.sample(p + shift) - exact)[ok].max() <= 0.5 * far.voxel_size

    a = bake_mesh_cards(v, f, texel_density=20)
    b = bake_mesh_cards(v + shift, f, texel_density=20)
    assert len(b.cards) == len(a.cards) == 6 and b.coverage == a.coverage == 1.0
    for ca, cb in zip(a.cards, b.cards):
        iu, iv = (1, 2) if ca.axis < 2 else (0, 2) if ca.axis < 4 else (0, 1)
        assert ca.axis == cb.axis and ca.resolution == cb.resolution
        assert np.allclose(cb.rect_min - shift[[iu, iv]], ca.rect_min, atol=1e-9 * offset)
        assert np.allclose(cb.rect_max - shift[[iu, iv]], ca.rect_max, atol=1e-9 * offset)
        assert cb.near - AXES[cb.axis] @ shift == pytest.approx(ca.near, abs=1e-9 * offset)
        assert np.array_equal(cb.opacity, ca.opacity)
        assert np.allclose(cb.depth, ca.depth, atol=1e-6) and np.allclose(cb.normal, ca.normal)
