"""The world as a light, bpy-free (lumen_addon/sky.py) against closed forms."""
import numpy as np
import pytest

from lumen_addon import sky


def split_sky(above, below, height=64):
    env = np.zeros((height, 2 * height, 3))
    env[: height // 2] = above
    env[height // 2:] = below
    return env


def test_pixel_directions_follow_blenders_environment_texture():
    d = sky.directions(32, 64)
    np.testing.assert_allclose(d[0, 32], [0, 0, 1], atol=0.06)      # top row looks up
    np.testing.assert_allclose(d[16, 32], [1, 0, 0], atol=0.06)     # middle column: +X
    np.testing.assert_allclose(d[16, 16], [0, 1, 0], atol=0.06)     # a quarter across: +Y
    assert sky.solid_angles(32, 64).sum() * 64 == pytest.approx(4 * np.pi)


def test_split_sky_irradiance_is_the_closed_form():
    """A sky of radiance A above the horizon and B below: E(n) = pi (A (1 + nz) + B (1 - nz)) / 2."""
    A, B = np.array([1.0, 0.6, 0.3]), np.array([0.1, 0.2, 0.4])
    maps = sky.sky_maps(split_sky(A, B))
    n = sky.directions(*sky.IRR_SIZE[::-1])
    nz = n[..., 2:3]
    exact = np.pi * (A * (1 + nz) + B * (1 - nz)) / 2
    assert np.abs(maps.irradiance / exact - 1).max() < 0.01
    assert maps.sun is None
    np.testing.assert_allclose(maps.mean, (A + B) / 2, rtol=1e-3)


def test_prefilter_keeps_a_uniform_sky_and_the_mean():
    maps = sky.constant((0.3, 0.5, 0.7))
    np.testing.assert_allclose(maps.rays, np.broadcast_to((0.3, 0.5, 0.7), maps.rays.shape),
                               rtol=2e-3)
    np.testing.assert_allclose(maps.irradiance[..., 1], np.pi * 0.5, rtol=2e-3)
    env = split_sky((1, 1, 1), (0, 0, 0))
    rays = sky.prefilter(env)
    sa = sky.solid_angles(*rays.shape[:2])
    assert (rays[..., 0] * sa).sum() / (4 * np.pi) == pytest.approx(0.5, rel=0.01)


def test_a_bright_spot_becomes_a_sun_and_energy_is_conserved():
    """A disk of radiance 5000 (0.5 degrees wide) on a uniform sky of 0.2: the sun's irradiance
    is what the disk holds above the sky's clip level, toward its centre, and map + sun = the
    original map's irradiance on every normal."""
    h = 256
    env = np.full((h, 2 * h, 3), 0.2)
    d = sky.directions(h, 2 * h)
    toward = np.array([0.6, -0.3, 0.74])
    toward /= np.linalg.norm(toward)
    disk = d @ toward > np.cos(np.radians(1.5))
    env[disk] = (5000.0, 4000.0, 3000.0)
    sun, rest = sky.extract_sun(env)
    assert sun is not None
    assert np.degrees(np.arccos(np.clip(sun.toward @ toward, -1, 1))) < 0.5
    normals = np.array([[0, 0, 1], toward, [1, 0, 0], [0, 0, -1]], float)
    before = sky.irradiance(env, normals)
    after = sky.irradiance(rest, normals) + np.maximum(normals @ sun.toward, 0)[:, None] * sun.irradiance
    np.testing.assert_allclose(after, before, rtol=0.02)
    sa = sky.solid_angles(h, 2 * h)
    omega = (disk * sa).sum()
    assert sun.angle == pytest.approx(2 * np.arcsin(np.sqrt(omega / np.pi)), rel=0.05)
    row = sun.light_row()
    assert row[0] == 0 and np.allclose(row[4:7], -sun.toward)


def test_no_sun_in_a_smooth_sky_and_bad_maps_refused():
    assert sky.extract_sun(split_sky((1, 1, 1), (0.5, 0.5, 0.5)))[0] is None
    assert sky.extract_sun(np.zeros((8, 16, 3)))[0] is None
    with pytest.raises(ValueError):
        sky.sky_maps(np.zeros((10, 10, 3)))
    nan = split_sky((1, 1, 1), (0, 0, 0))
    nan[3, 4] = np.nan
    assert np.isfinite(sky.sky_maps(nan).atlas()).all()
