"""How noisy an F12 render's gathered indirect light still is (numpy only, no gpu): the adaptive
end of its temporal accumulation, as Cycles' adaptive sampling ends a pixel's samples at a noise
threshold.

An F12 render averages GISettings.render_frames frames of jittered screen probes (and a surface
cache relit each frame). Each frame's per-pixel indirect irradiance is an independent estimate,
so the noise of their mean is the frames' standard deviation over sqrt(frames). `FrameNoise`
keeps per-pixel running means and squared deviations of the frames' luminance (Welford's
update: sums of squares cancel) and gives the RMS, over the pixels
that show a surface, of that standard error relative to what the pixel shows: its direct light
plus its mean indirect light (Diffuse Direct + Diffuse Indirect, both E / pi: the albedo scales
signal and noise alike), plus a floor of RELATIVE_FLOOR x the image's mean, so that dark pixels,
whose noise nobody sees, do not decide. Why: an open sky-lit scene's frames agree after a few
frames, a room lit by bounces needs all of them; a fixed count spent the room's frames on the
open ground (bench/quality.py: thin and yard were the scenes above EEVEE's time). A surface
cache still converging adds its trend to the variance: such a render runs longer, never shorter.
"""
from __future__ import annotations

import numpy as np

RELATIVE_FLOOR = 0.1
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


class FrameNoise:
    """Per-pixel running mean and sum of squared deviations of the frames' luminance (float64)."""

    def __init__(self, direct: np.ndarray, surface: np.ndarray):
        """direct: float [h, w, >=3] Diffuse Direct (E / pi); surface: bool [h, w], the pixels
        that show a surface."""
        self.base = np.asarray(direct, np.float64)[..., :3] @ LUMINANCE
        self.surface = np.asarray(surface, bool)
        self.frames = 0
        self.mean = np.zeros_like(self.base)
        self.m2 = np.zeros_like(self.base)

    def add(self, indirect: np.ndarray):
        """One frame's indirect irradiance E, float [h, w, >=3]."""
        lum = (np.asarray(indirect, np.float64)[..., :3] @ LUMINANCE) / np.pi
        self.frames += 1
        delta = lum - self.mean
        self.mean += delta / self.frames
        self.m2 += delta * (lum - self.mean)

    def relative_noise(self) -> float:
        """RMS over the surface pixels of the mean's standard error / (direct + |mean| +
        floor); inf with fewer than 2 frames, 0 with no surface pixel."""
        n = self.frames
        if n < 2:
            return float("inf")
        if not self.surface.any():
            return 0.0
        mean = self.mean[self.surface]
        var = self.m2[self.surface] / (n - 1)
        shown = self.base[self.surface] + np.abs(mean)
        floor = RELATIVE_FLOOR * float(shown.mean()) + 1e-12
        rel = np.sqrt(var / n) / (shown + floor)
        return float(np.sqrt(np.mean(rel * rel)))
