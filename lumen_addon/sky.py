"""The world as a light, from an equirectangular radiance map (numpy only, no bpy).

A world of any node tree arrives here as one equirectangular map of linear RGB radiance
(operators/world_capture.py renders it with Cycles, so every node evaluates as Cycles has it).
Rows are top first (row 0 looks up, +Z), as OpenImageIO reads an image; columns follow Blender's
Environment Texture: u = (pi - atan2(y, x)) / 2 pi, so +X is the middle column and +Y a quarter
across. This module turns the map into what the engine samples:

- `extract_sun`: the brightest compact spot (an HDRI's sun) becomes a sun light of the same
  irradiance, direction and angular size, so the SDF casts its shadows; the map keeps the rest
  (the spot's pixels are clipped to the threshold, so map + sun = the original, exactly).
- `prefilter`: the map blurred with a von Mises-Fisher kernel of about a GI ray's cone (a ray of
  64 per probe hemisphere covers ~0.1 sr), so a miss reads the mean over its cone, not one texel.
- `irradiance_map`: E(n) = integral of L(w) max(n.w, 0) dw for every normal n (brute force over
  the map's pixels, exact for the map): the unoccluded sky irradiance of the direct pass.
- `SkyMaps.atlas`: the three packed into one RGBA32F image (one sampler for the shaders,
  glsl/sky_lib.glsl reads it).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

RAY_SIZE = (64, 32)          # prefiltered map for ray misses (width, height)
IRR_SIZE = (32, 16)          # irradiance map for the direct pass
RAY_KAPPA = 30.0             # vMF concentration: angular spread ~ 1/sqrt(kappa) = 10 degrees
SUN_MIN_SHARE = 0.05         # a spot is a sun when it brings at least 5% of the map's irradiance
SUN_RADIUS = np.radians(6.0)  # and lies within 6 degrees of the brightest pixel
SUN_CONTRAST = 20.0          # its pixels are brighter than 20 x the map's median (and 5% of peak)
LUMA = np.array([0.2126, 0.7152, 0.0722])


def directions(height: int, width: int) -> np.ndarray:
    """float64 [h, w, 3]: the unit direction of every pixel centre (see the module doc)."""
    theta = (np.arange(height) + 0.5) / height * np.pi
    u = (np.arange(width) + 0.5) / width
    phi = np.pi - 2.0 * np.pi * u
    st = np.sin(theta)[:, None]
    return np.stack([st * np.cos(phi)[None, :], st * np.sin(phi)[None, :],
                     np.broadcast_to(np.cos(theta)[:, None], (height, width))], axis=-1)


def solid_angles(height: int, width: int) -> np.ndarray:
    """float64 [h, 1]: each pixel's exact solid angle (they sum to 4 pi)."""
    edges = np.cos(np.arange(height + 1) / height * np.pi)
    return ((edges[:-1] - edges[1:]) * (2.0 * np.pi / width))[:, None]


def downsample(env: np.ndarray, max_width: int) -> np.ndarray:
    """Box-average by powers of two until the width is at most max_width (keeps 2:1 maps 2:1)."""
    env = np.asarray(env, np.float64)
    while env.shape[1] > max_width and env.shape[0] % 2 == 0 and env.shape[1] % 2 == 0:
        h, w = env.shape[:2]
        env = env.reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3))
    return env


@dataclass
class Sun:
    """A directional light taken out of the map: irradiance (linear RGB, W/m^2 facing it),
    `toward` (unit vector to the sun), `angle` (angular diameter, radians)."""
    irradiance: np.ndarray
    toward: np.ndarray
    angle: float

    def light_row(self) -> np.ndarray:
        """The 16 float32 of operators/lights.py's row for a sun."""
        row = np.zeros(16, np.float32)
        row[0] = 0.0
        row[4:7] = -self.toward
        row[7] = self.angle
        row[8:11] = self.irradiance
        return row


def extract_sun(env: np.ndarray):
    """(Sun or None, the map without it). A sun: the pixels within SUN_RADIUS of the brightest
    one that are brighter than max(SUN_CONTRAST x median, 5% of the peak); taken out only when
    what they hold above that threshold is at least SUN_MIN_SHARE of the map's irradiance."""
    env = np.asarray(env, np.float64)[..., :3]
    h, w = env.shape[:2]
    lum = env @ LUMA
    sa = solid_angles(h, w)
    total = float((lum * sa).sum())
    if not np.isfinite(total) or total <= 0.0:
        return None, env
    peak = np.unravel_index(int(np.argmax(lum)), lum.shape)
    dirs = directions(h, w)
    near = dirs @ dirs[peak] > np.cos(SUN_RADIUS)
    threshold = max(SUN_CONTRAST * float(np.median(lum)), 0.05 * float(lum[peak]))
    spot = near & (lum > threshold)
    if not spot.any():
        return None, env
    scale = np.where(spot, np.minimum(threshold / np.maximum(lum, 1e-30), 1.0), 1.0)
    rest = env * scale[..., None]
    excess = (env - rest) * sa[..., None]
    excess_lum = float((excess @ LUMA).sum())
    if excess_lum < SUN_MIN_SHARE * total:
        return None, env
    weights = excess @ LUMA
    toward = (dirs * weights[..., None]).sum(axis=(0, 1))
    toward /= max(np.linalg.norm(toward), 1e-30)
    omega = float(sa[:, 0][np.nonzero(spot)[0]].sum())
    angle = 2.0 * np.arcsin(min(np.sqrt(omega / np.pi), 1.0))
    return Sun(excess.sum(axis=(0, 1)).astype(np.float32), toward, angle), rest


def _convolve(env: np.ndarray, out_size, kernel, normalise=False, chunk: int = 512) -> np.ndarray:
    """[oh, ow, 3]: for each output pixel direction d, sum_w k(d . w) L(w) dw (with `normalise`,
    divided by sum_w k(d . w) dw: a weighted mean, exact for a uniform map)."""
    h, w = env.shape[:2]
    src_dirs = directions(h, w).reshape(-1, 3)
    sa = np.broadcast_to(solid_angles(h, w), (h, w)).reshape(-1, 1)
    src = np.concatenate([env[..., :3].reshape(-1, 3) * sa, sa], axis=1)
    ow, oh = out_size
    dst = directions(oh, ow).reshape(-1, 3)
    out = np.empty((len(dst), 4))
    for s in range(0, len(dst), chunk):
        out[s:s + chunk] = kernel(dst[s:s + chunk] @ src_dirs.T) @ src
    rgb = out[:, :3] / np.maximum(out[:, 3:], 1e-30) if normalise else out[:, :3]
    return rgb.reshape(oh, ow, 3)


def prefilter(env: np.ndarray, size=RAY_SIZE, kappa: float = RAY_KAPPA) -> np.ndarray:
    """The map convolved with a vMF kernel (mean radiance over a ~ray cone)."""
    small = downsample(env, 2 * size[0])
    return _convolve(small, size, lambda c: np.exp(kappa * (c - 1.0)), normalise=True)


def irradiance_map(env: np.ndarray, size=IRR_SIZE) -> np.ndarray:
    """E(n) for the direction n of every output pixel: integral of L max(n.w, 0) dw."""
    small = downsample(env, 2 * size[0])
    return _convolve(small, size, lambda c: np.maximum(c, 0.0))


def irradiance(env: np.ndarray, normals) -> np.ndarray:
    """float64 [n, 3]: E(n) of the full map at the given unit normals (a test reference)."""
    env = np.asarray(env, np.float64)
    h, w = env.shape[:2]
    src_dirs = directions(h, w).reshape(-1, 3)
    src = (env[..., :3] * solid_angles(h, w)[..., None]).reshape(-1, 3)
    return np.maximum(np.asarray(normals, np.float64) @ src_dirs.T, 0.0) @ src


@dataclass
class SkyMaps:
    """What the engine uploads for one world: `background` (the map as the camera sees it),
    `rays` (prefiltered, without the sun), `irradiance` (E(n), without the sun), `sun` (or None),
    `key` (content hash: the GPU re-uploads only when it changes), `mean` (mean radiance)."""
    background: np.ndarray
    rays: np.ndarray
    irradiance: np.ndarray
    sun: Sun = None
    key: str = ""
    mean: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def atlas(self) -> np.ndarray:
        """float32 [H + 48, W, 4]: background rows on top, the ray map below it (64 x 32, at
        x = 0), the irradiance map below that (32 x 16). W = max(background width, 64)."""
        bh, bw = self.background.shape[:2]
        width = max(bw, RAY_SIZE[0])
        out = np.zeros((bh + RAY_SIZE[1] + IRR_SIZE[1], width, 4), np.float32)
        out[..., 3] = 1.0
        out[:bh, :bw, :3] = self.background[..., :3]
        out[bh:bh + RAY_SIZE[1], :RAY_SIZE[0], :3] = self.rays
        out[bh + RAY_SIZE[1]:, :IRR_SIZE[0], :3] = self.irradiance
        return out

    def sun_rows(self) -> np.ndarray:
        return (self.sun.light_row()[None] if self.sun is not None
                else np.zeros((0, 16), np.float32))


def sky_maps(env: np.ndarray, background_width: int = 1024) -> SkyMaps:
    """All of it from one equirectangular radiance map [h, w, >=3] (h = w / 2)."""
    env = np.asarray(env, np.float64)[..., :3]
    if env.ndim != 3 or env.shape[1] != 2 * env.shape[0] or env.shape[0] < 2:
        raise ValueError(f"an equirectangular map is twice as wide as high, not {env.shape}")
    env = np.where(np.isfinite(env), np.maximum(env, 0.0), 0.0)
    background = downsample(env, background_width)
    sun, rest = extract_sun(downsample(env, 512))
    rays = prefilter(rest)
    irr = irradiance_map(rest)
    h, w = background.shape[:2]
    mean = (background * solid_angles(h, w)[..., None]).sum(axis=(0, 1)) / (4.0 * np.pi)
    digest = hashlib.sha1(np.ascontiguousarray(background, np.float32).tobytes()).hexdigest()[:16]
    return SkyMaps(background.astype(np.float32), rays.astype(np.float32),
                   irr.astype(np.float32), sun, digest, mean)


def constant(colour, width: int = 64) -> SkyMaps:
    """A uniform world of radiance `colour` (E(n) = pi colour everywhere)."""
    c = np.asarray(colour, np.float64)[:3]
    return sky_maps(np.broadcast_to(c, (width // 2, width, 3)).copy(), background_width=width)
