"""Geometry that used to fool the bake (issue 11), checked against exact answers: needle triangles
against brute-force distances."""
import numpy as np
import pytest

import shapes
from lumen_addon import sdf
from lumen_addon.geometry import TrianglePairs, brute_force_distance

from test_sdf import stored_samples


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
