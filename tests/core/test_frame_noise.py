"""frame_noise.FrameNoise without Blender: the relative noise of the mean of an F12 render's frames
against closed forms (the standard error of a mean of independent frames)."""
import numpy as np

from gpu_shaders.frame_noise import LUMINANCE, RELATIVE_FLOOR, FrameNoise


def grey(values):
    """[h, w, 3] frames of the given luminance (LUMINANCE sums to 1)."""
    return np.repeat(np.asarray(values, np.float64)[..., None], 3, axis=-1)


def test_identical_frames_have_no_noise():
    n = FrameNoise(grey(np.ones((4, 4))), np.ones((4, 4), bool))
    assert n.relative_noise() == float("inf")          # one frame: no estimate yet
    for _ in range(3):
        n.add(grey(np.full((4, 4), 2.0)))
    assert n.relative_noise() < 1e-9


def test_two_level_frames_against_the_standard_error():
    # every surface pixel alternates between pi * (m - d) and pi * (m + d): E / pi has mean m,
    # sample standard deviation d sqrt(k / (k - 1)) over k frames, standard error of the mean
    # that over sqrt(k); relative to direct b + m plus the floor
    b, m, d, k = 0.5, 1.0, 0.2, 8
    surface = np.zeros((6, 6), bool)
    surface[1:5, 1:5] = True
    n = FrameNoise(grey(np.full((6, 6), b)), surface)
    for i in range(k):
        n.add(grey(np.full((6, 6), np.pi * (m + (d if i % 2 else -d)))))
    se = d * np.sqrt(k / (k - 1)) / np.sqrt(k)
    shown = b + m
    expected = se / (shown + RELATIVE_FLOOR * shown)
    assert abs(n.relative_noise() - expected) <= 1e-9 * expected
    assert abs(LUMINANCE.sum() - 1.0) < 1e-12


def test_noise_falls_as_one_over_sqrt_frames_and_ignores_the_background():
    rng = np.random.default_rng(1)
    surface = np.zeros((32, 32), bool)
    surface[:, :16] = True
    n = FrameNoise(grey(np.zeros((32, 32))), surface)
    seen = {}
    for i in range(64):
        frame = np.where(surface, np.pi * (1.0 + 0.3 * rng.standard_normal((32, 32))), 50.0 * i)
        n.add(grey(frame))
        seen[i + 1] = n.relative_noise()
    # the background changes wildly and does not count; the surface's se is 0.3 / sqrt(k)
    for k in (16, 64):
        assert abs(seen[k] - 0.3 / np.sqrt(k) / 1.1) <= 0.15 * 0.3 / np.sqrt(k)
    assert FrameNoise(grey(np.ones((2, 2))), np.zeros((2, 2), bool)).relative_noise() == float("inf")
