"""Geometry that used to fool the bake (issue 11), checked against exact answers: needle triangles
against brute-force distances, meshes far from their own origin against the same mesh at home
and the analytic SDF."""
import math

import numpy as np
import pytest

import shapes
from lumen_addon import sdf
from lumen_addon.cards import AXES, bake_mesh_cards
from lumen_addon.geometry import TrianglePairs, brute_force_distance

from test_sdf import stored_samples


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
