"""Mesh SDF bake against exact answers: brute-force distances, winding-number signs, analytic shapes."""
import math

import numpy as np
import pytest

from lumen_addon import sdf
from lumen_addon.geometry import boundary_loops, brute_force_distance, clean_mesh, winding_number

import shapes
from shapes import shared_mesh_names

RNG_SEED = 7


def band_points(v, f, m, n, rng):
    """Random points whose whole trilinear stencil lies inside the band (so 'within the band')."""
    h = m.voxel_size
    p = shapes.surface_samples(v, f, n, rng)
    return p + rng.uniform(-1, 1, p.shape) * 2.2 * h


def stored_samples(m, mip=0):
    """Unique sample positions of the kept bricks with their stored distances."""
    lvl = m.mips[mip]
    kept = np.argwhere(lvl.indirection >= 0)
    slots = lvl.indirection[tuple(kept.T)]
    off = np.stack(np.meshgrid(*(np.arange(sdf.BRICK),) * 3, indexing="ij"), -1).reshape(-1, 3)
    idx = (kept[:, None, :] * sdf.BRICK_CELLS + off[None]).reshape(-1, 3)
    idx, first = np.unique(idx, axis=0, return_index=True)
    dist = (lvl.bricks[slots].reshape(-1)[first].astype(float) - 127.5) / 127.5 * lvl.band
    return m.origin + idx * lvl.voxel_size, dist


def away_from_holes(mesh, p, margin):
    """False for points near a hole. Across a hole the sign flips where no surface is (the cap
    that keeps rays out of open scans, test_holes_are_capped), and each mip puts that flip a little
    differently: distances there are not the mesh's, so distance checks leave them out."""
    centres, radii = boundary_loops(mesh.vertices, mesh.triangles)
    if not len(radii):
        return np.ones(len(p), bool)
    gap = np.linalg.norm(p[:, None] - centres[None], axis=2) - radii[None] - 2 * margin
    return (gap > 0).all(axis=1)


def check_mesh(v, f, density, closed, n_dist=600, n_sign=1500, two_sided=False):
    """The issue's acceptance checks for one mesh; returns measured numbers for messages."""
    rng = np.random.default_rng(RNG_SEED)
    m = sdf.bake_mesh_sdf(v, f, voxel_density=density, two_sided=two_sided)
    h = m.voxel_size
    c = clean_mesh(v, f)

    # 1. Distance within the band: |sampled - exact| <= 0.5 voxel (exact = brute force).
    p = band_points(v, f, m, n_dist, rng)
    udf = brute_force_distance(c.vertices, c.triangles, p)
    got = m.sample(p)
    if two_sided:
        err = np.abs(got - (udf - 0.5 * h))
    elif closed:
        sign = np.where(winding_number(c.vertices, c.triangles, p) > 0.5, -1.0, 1.0)
        err = np.abs(got - sign * udf)
    else:
        err = np.abs(np.abs(got) - udf)   # open meshes: the sign is a convention near holes
    in_band = (udf < m.mips[0].band - math.sqrt(3) * h) & away_from_holes(c, p, h)
    assert in_band.sum() > n_dist // 2
    max_err = err[in_band].max() / h
    assert max_err <= 0.5, f"max distance error {max_err:.3f} voxels"

    # 2. Sign of stored band samples vs the generalised winding number. A sample within one
    #    quantisation step of the surface has no meaningful sign (its code is +-half a step).
    pts, dist = stored_samples(m)
    step = m.mips[0].band / 127.5
    band = (np.abs(dist) < 0.99 * m.mips[0].band) & (np.abs(dist) > step)
    sel = rng.choice(np.flatnonzero(band), min(n_sign, int(band.sum())), replace=False)
    w = winding_number(c.vertices, c.triangles, pts[sel])
    # Likewise a sample on the winding number's own membrane across a hole (w ~ 0.5).
    defined = np.abs(w - 0.5) > 0.02
    wrong = float(np.mean((dist[sel] < 0)[defined] != (w > 0.5)[defined]))
    if closed and not two_sided:
        assert wrong <= 0.001, f"sign wrong on {100 * wrong:.3f}% of band samples"

    # 3. Mips agree with mip 0 within their own voxel size (where both are inside their bands).
    q = band_points(v, f, m, n_dist, rng)
    d0 = m.sample(q, 0)
    for k in range(1, len(m.mips)):
        dk = m.sample(q, k)
        hk = m.mips[k].voxel_size
        ok = (np.abs(d0) < m.mips[0].band - math.sqrt(3) * h) & away_from_holes(c, q, hk)
        assert np.abs(dk - d0)[ok].max() <= hk, f"mip {k} differs by more than its voxel"
    return m, max_err, wrong


def test_box_matches_analytic_sdf():
    half = (0.5, 0.4, 0.3)
    v, f = shapes.box(half)
    m = sdf.bake_mesh_sdf(v, f, voxel_density=20)
    rng = np.random.default_rng(RNG_SEED)
    p = rng.uniform(-0.7, 0.7, (20000, 3))
    exact = shapes.box_sdf(p, half)
    inside_band = np.abs(exact) < m.mips[0].band - math.sqrt(3) * m.voxel_size
    err = np.abs(m.sample(p) - exact)[inside_band] / m.voxel_size
    assert err.max() <= 0.5
    # Deep inside and far outside: clamped to the band with the right sign.
    assert m.sample([[0, 0, 0]])[0] == pytest.approx(-m.mips[0].band, rel=1e-6)
    assert m.sample([[5, 0, 0]])[0] >= 4.0   # outside the volume: a lower bound of the distance


def test_sphere():
    v, f = shapes.icosphere(0.5, 4)
    m, err, wrong = check_mesh(v, f, 30, closed=True)
    # Also close to the analytic sphere (tessellation error of a 5120-face icosphere < 1 mm).
    p = np.random.default_rng(1).normal(size=(2000, 3))
    p = p / np.linalg.norm(p, axis=1, keepdims=True) * np.random.default_rng(2).uniform(0.45, 0.55, (2000, 1))
    assert np.abs(m.sample(p) - (np.linalg.norm(p, axis=1) - 0.5)).max() <= 0.5 * m.voxel_size + 2e-3


def test_box():
    v, f = shapes.box()
    check_mesh(v, f, 20, closed=True)


def test_torus():
    v, f = shapes.torus()
    check_mesh(v, f, 30, closed=True)


def test_open_cylinder():
    v, f = shapes.open_cylinder()
    m, err, wrong = check_mesh(v, f, 30, closed=False)
    assert wrong <= 0.001, f"open cylinder: sign differs from winding number on {100 * wrong:.3f}%"
    # Deep inside the tube is inside; far outside is outside.
    assert m.sample([[0, 0, 0]])[0] < 0
    assert m.sample([[0.6, 0, 0]])[0] > 0


def test_holes_are_capped():
    """Rays into an open tube stop at a membrane across its opening instead of leaking inside;
    the same tube baked two-sided lets them through to the far side's wall."""
    v, f = shapes.open_cylinder(radius=0.3, height=1.6)
    o = np.array([[0.0, 0.0, 1.5]])
    down = np.array([[0.0, 0.0, -1.0]])
    capped = sdf.bake_mesh_sdf(v, f, voxel_density=30).sphere_trace(o, down, t_max=4.0)[0]
    assert 0.6 < capped < 0.8 + 0.2, capped          # stops near the opening at z = 0.8
    sheet = sdf.bake_mesh_sdf(v, f, voxel_density=30, two_sided=True).sphere_trace(o, down, 4.0)[0]
    assert not np.isfinite(sheet)                     # straight through the open tube


def test_thin_wall_two_sided_does_not_leak():
    """A 1 cm wall at 5 cm voxels: half-voxel expansion makes it solid for every ray."""
    v, f = shapes.thin_wall(1.0, 0.01)
    m, err, _ = check_mesh(v, f, 20, closed=True, two_sided=True)
    h = m.voxel_size
    assert h > 0.01 * 4
    rng = np.random.default_rng(3)
    target = np.concatenate([rng.uniform(-0.4, 0.4, (2000, 2)), np.zeros((2000, 1))], axis=1)
    d = np.concatenate([rng.normal(scale=0.3, size=(2000, 2)), np.ones((2000, 1))], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = target - d * (0.5 / d[:, 2:3])          # start 0.5 m below the wall's plane, aimed at it
    hit = m.sphere_trace(o, d, t_max=2.0)
    t_wall = 0.5 / d[:, 2]
    assert np.isfinite(hit).all(), f"{int((~np.isfinite(hit)).sum())} rays leaked through the wall"
    assert np.all(np.abs(hit - t_wall) <= (0.5 + 0.5) * h / d[:, 2])


@pytest.mark.parametrize("name", shared_mesh_names() or ["<none>"])
def test_shared_mesh(shared_mesh, name):
    v, f = shared_mesh(name)
    extent = float((v.max(0) - v.min(0)).max())
    closed = name in {"spot", "fandisk", "armadillo"}
    big = len(f) > 30000
    check_mesh(v, f, 40 / extent, closed=closed, n_dist=250 if big else 500, n_sign=400 if big else 1000)


def test_sign_agrees_with_winding_number_on_open_scan(shared_mesh):
    """The bunny has holes in its base: compare every band sample near them to the winding number."""
    v, f = shared_mesh("stanford-bunny")
    m = sdf.bake_mesh_sdf(v, f, voxel_density=24 / float((v.max(0) - v.min(0)).max()))
    c = clean_mesh(v, f)
    pts, dist = stored_samples(m)
    band = (np.abs(dist) < 0.99 * m.mips[0].band) & (np.abs(dist) > m.mips[0].band / 127.5)
    low = pts[:, 1] < np.percentile(pts[band, 1], 15)        # the base, where the holes are
    sel = np.flatnonzero(band & low)
    w = winding_number(c.vertices, c.triangles, pts[sel])
    assert np.mean((dist[sel] < 0) != (w > 0.5)) <= 0.001


def test_stats_and_layout():
    v, f = shapes.icosphere(0.5, 3)
    m = sdf.bake_mesh_sdf(v, f, voxel_density=40)
    st = m.stats()
    assert len(st) == 3
    for k, s in enumerate(st):
        assert all(r % sdf.BRICK_CELLS == 0 for r in s["resolution"])
        assert 0 < s["bricks_kept"] <= s["bricks_total"]
        assert s["bytes"] == s["bricks_kept"] * 512 + s["bricks_total"] * 4
        if k:
            assert s["voxel_size"] == pytest.approx(2 * st[k - 1]["voxel_size"])
    # Voxel density: 40 voxels per metre over a 1 m sphere plus the margin, in whole bricks.
    assert m.voxel_size == pytest.approx(1 / 40)
    assert st[0]["resolution"][0] == 7 * math.ceil((40 + 2 * sdf.MARGIN_VOXELS) / 7)
    # Bricks far from the surface are dropped; inside ones are marked inside.
    assert (m.mips[0].indirection == sdf.INVALID_INSIDE).any()
    assert (m.mips[0].indirection == sdf.INVALID_OUTSIDE).any()


def test_resolution_clamp_and_scale():
    v, f = shapes.box((1.0, 0.25, 0.25))
    m = sdf.bake_mesh_sdf(v, f, voxel_density=1000, max_resolution=56)
    assert m.clamped and max(m.mips[0].resolution) <= 56
    m2 = sdf.bake_mesh_sdf(v, f, voxel_density=10, resolution_scale=2.0)
    assert m2.voxel_size == pytest.approx(1 / 20)
