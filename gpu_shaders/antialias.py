"""Anti-aliasing of F12 renders: the image is the mean of `samples` G-buffers drawn with the
camera moved by a fraction of a pixel, as Cycles and EEVEE filter theirs (Blackman-Harris of the
scene's Film > Filter Size, 1.5 px by default, importance-sampled separably in x and y as Cycles
does, so every sample weighs the same). Cycles' Blackman-Harris spans twice the filter size
(intern/cycles/scene/film.cpp: filter_table doubles the width: 3 px across at 1.5), and so do
these jitters: over 1.5 px across the image was sharper than Cycles' (edges, texture detail:
bench/ssim_map.py on `textured`, local contrast 1.2-1.3x the reference's).

Why: with one G-buffer sample per pixel every edge is a staircase, and against a path tracer's
filtered image an edge pixel that is all floor where the reference is half floor and half
background costs more than all the noise of the bounce (relMSE and SSIM weigh it so). Why this
is cheap: the bounced light is smooth and is computed once, on the unjittered G-buffer; per
sample only the G-buffer, the direct light (sharp shadows and edges need it at the sample; each
sample evaluates its share of the lights' strata, so all samples together cost about one direct
pass) and two full-screen passes run:

    mesh_batches.draw     the sample's G-buffer (view_proj moved by the jitter)
    direct_light.shade    its direct light
    aa_resolve            its E_indirect: the frame's E from the unjittered pixels around it that
                          show the same surface, no wall between (glsl/aa_resolve.comp.glsl)
    composite             its Combined and Diffuse Indirect
    gi_accumulate         running means of Combined, Diffuse Direct, Diffuse Indirect, Diffuse Color

The Normal pass stays the unjittered one (a mean of normals is not a normal). Needs a GPU
context (jitters() and jittered() are numpy only). The viewport runs the same samples one per
redraw once its view has converged (Progressive).
"""
from __future__ import annotations

import functools
import math
import time

import numpy as np


def blackman_harris(x: np.ndarray, width: float) -> np.ndarray:
    """Blackman-Harris window over [-width/2, width/2] (Cycles' default pixel filter)."""
    t = np.clip(np.asarray(x, np.float64) / max(width, 1e-6) + 0.5, 0.0, 1.0)
    a = 2.0 * math.pi * t
    return 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)


def filter_span(filter_size: float) -> float:
    """The width in pixels, across, of the Blackman-Harris window of a Film > Filter Size: twice
    the size, as Cycles builds its filter table (film.cpp: `width *= 2.0f`)."""
    return 2.0 * float(filter_size)


def jitters(samples: int, filter_size: float = 1.5) -> np.ndarray:
    """float64 [samples, 2]: pixel offsets distributed as Cycles' Blackman-Harris pixel filter of
    Filter Size `filter_size` (filter_span: 3 px across at 1.5), separably (inverse CDF of a 1D
    table applied to stratified_set; cached: the viewport asks every redraw)."""
    return _jitters(max(int(samples), 1), float(filter_size)).copy()


@functools.lru_cache(maxsize=16)
def _jitters(samples: int, filter_size: float) -> np.ndarray:
    n = max(int(samples), 1)
    width = filter_span(filter_size)
    xs = np.linspace(-width / 2, width / 2, 1025)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (blackman_harris(xs[1:], width)
                                                  + blackman_harris(xs[:-1], width))
                                           * np.diff(xs))])
    cdf /= cdf[-1]
    return np.interp(stratified_set(n, lambda u: np.interp(u, cdf, xs)), cdf, xs)


def anisotropy(points: np.ndarray, directions: int = 24) -> float:
    """max / min over directions of the standard deviation of the points projected on them: 1
    for a set that filters edges of every orientation alike."""
    a = np.linspace(0.0, np.pi, directions, endpoint=False)
    std = (np.asarray(points, np.float64) @ np.stack([np.cos(a), np.sin(a)])).std(axis=0)
    return float(std.max() / max(std.min(), 1e-12))


def stratified_set(n: int, warp=None) -> np.ndarray:
    """float64 [n, 2] in (0, 1)^2: x and y each take every (i + 0.5) / n once (the filter's
    marginals exactly), paired by the permutation (every one up to 8 points, else the rank-1
    lattices y = k x mod n) whose set, mapped by `warp` (the filter's inverse CDF), is the most
    isotropic, then the widest spaced. Hammersley's pairing put half of 8 points on one diagonal
    (the bit reversal of 0, 2, 5, 7): an edge along the other diagonal was blurred over 2.3x the
    width of one along it (std 0.50 against 0.22 px at Filter Size 1.5)."""
    from itertools import permutations
    from math import gcd

    n = max(int(n), 1)
    if n == 1:
        return np.full((1, 2), 0.5)
    if n <= 8:
        perms = np.array(list(permutations(range(n))))
    else:
        perms = np.array([(k * np.arange(n)) % n for k in range(1, n) if gcd(k, n) == 1])
    x = (np.arange(n) + 0.5) / n
    y = (perms + 0.5) / n                                   # [candidates, n]
    wx = warp(x) if warp is not None else x - 0.5
    wy = warp(y) if warp is not None else y - 0.5
    a = np.linspace(0.0, np.pi, 24, endpoint=False)
    proj = wx[None, :, None] * np.cos(a) + wy[:, :, None] * np.sin(a)   # [candidates, n, dirs]
    std = proj.std(axis=1)
    aniso = np.round(std.max(axis=1) / np.maximum(std.min(axis=1), 1e-12), 6)
    dist = np.sqrt((wx[None, :, None] - wx[None, None, :]) ** 2
                   + (wy[:, :, None] - wy[:, None, :]) ** 2) + np.eye(n) * 1e9
    order = np.lexsort((-dist.min(axis=(1, 2)), aniso))
    return np.stack([x, y[order[0]]], axis=1)


def jittered(view_proj, dx: float, dy: float, width: int, height: int) -> np.ndarray:
    """view_proj with the image moved so that pixel (i, j) shows the scene at (i + 0.5 + dx,
    j + 0.5 + dy): clip x -= 2 dx / width * w (the same for y)."""
    m = np.array(view_proj, np.float64).reshape(4, 4)
    m[0] -= (2.0 * dx / width) * m[3]
    m[1] -= (2.0 * dy / height) * m[3]
    return m


def footprint(view_proj, height: int) -> tuple:
    """(a, b): a pixel's world size at distance d is about a d + b (perspective: a = 2 / (P11 h);
    orthographic: b = 2 / (P11 h))."""
    m = np.asarray(view_proj, np.float64).reshape(4, 4)
    scale = float(np.linalg.norm(m[1, :3]))           # P11 times the camera's up axis (unit)
    size = 2.0 / max(scale * height, 1e-12)
    perspective = float(np.linalg.norm(m[3, :3])) > 0.5   # row 3: -forward, or (0, 0, 0, 1)
    return (size, 0.0) if perspective else (0.0, size)


def sample_footprint(samples: int) -> float:
    """The share of a pixel's texture footprint one of `samples` jittered G-buffers filters:
    1 / sqrt(samples) (the samples together cover the pixel filter, each about its 1 / n of the
    area). With a whole pixel's mip footprint per sample the mean was the texture blurred by the
    pixel filter and again by a pixel (the `textured` benchmark's bricks, SSIM below EEVEE)."""
    return 1.0 / math.sqrt(max(int(samples), 1))


class Supersampler:
    """Running means of the sampled passes (textures), one frame's."""

    NAMES = ("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color")

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.means = {}
        self.count = 0

    def add(self, textures: dict):
        from .ssgi import accumulate     # mix(history, new, blend): the running mean

        self.count += 1
        for name in self.NAMES:
            new = textures.get(name)
            if new is not None:
                self.means[name], _ = accumulate(self.means.get(name), new, 1.0 / self.count,
                                                 self.width, self.height, 0,
                                                 mix_alpha=name == "Combined")   # coverage


def resolve_indirect(resources, gbuf: dict, base: dict, e_base, jitter, foot, cam_pos,
                     width: int, height: int):
    """glsl/aa_resolve.comp.glsl: E at a jittered sample's pixels from the frame's E."""
    from . import compute

    out = compute.texture((width, height))
    resolve = compute.Pass("aa_resolve", samplers=("gbuf_position", "gbuf_normal", "base_position",
                                                   "base_normal", "e_base"),
                           push=(('VEC3', 'cam_pos'), ('VEC2', 'jitter'), ('VEC2', 'footprint')))
    resolve.run((width, height), scene=resources, gbuf_position=gbuf["textures"]["position"],
                gbuf_normal=gbuf["textures"]["normal"], base_position=base["textures"]["position"],
                base_normal=base["textures"]["normal"], e_base=e_base, cam_pos=compute.vec(cam_pos),
                jitter=compute.vec(jitter, 2), footprint=compute.vec(foot, 2), out_image=out)
    return out


def light_part(index: int, samples: int, strata: int = 8) -> tuple:
    """(first, take): the direct-light strata sample `index` of `samples` evaluates (the largest
    power of two <= strata / samples of each light's points and of the sky cones, the next ones
    each sample): the samples' mean holds every stratum, as one full pass does, for the cost of
    about one pass (direct_light.shade's `part`, as its Progressive uses)."""
    n = max(int(strata), 1)
    take = 1 << max(int(math.log2(max(n // max(int(samples), 1), 1))), 0)
    return ((int(index) * take) % n, take)


def add_sample(acc: Supersampler, state, base: dict, e_indirect, lights, sky, cam_pos,
               view_proj, jitter, sky_cones: int, index: int, samples: int):
    """Sample `index` of `samples` (jitter in pixels) into `acc` (see the module docstring)."""
    from . import composite, direct_light

    part = light_part(index, samples, min(direct_light.LIGHT_SAMPLES, direct_light.SKY_CONES))
    width, height = acc.width, acc.height
    foot = footprint(view_proj, height)
    dx, dy = (float(v) for v in jitter)
    vp = jittered(view_proj, dx, dy, width, height)
    inv_vp = np.linalg.inv(vp)
    gbuf = state.mesh_batches.draw(vp, width, height, footprint_scale=sample_footprint(samples))
    out = direct_light.shade(state.resources, gbuf, lights, sky, cam_pos, inv_vp, width,
                             height, sky_cones=sky_cones, light_texture=state.light_texture,
                             part=part)
    sample = {"Combined": out["textures"]["combined"],
              "Diffuse Direct": out["textures"]["direct"],
              "Diffuse Color": gbuf["textures"]["albedo"]}
    if e_indirect is not None:
        e = resolve_indirect(state.resources, gbuf, base, e_indirect, (dx, dy), foot, cam_pos,
                             width, height)
        comp = composite.composite(gbuf, out["textures"]["direct"], e, sky, inv_vp, width,
                                   height)
        sample["Combined"] = comp["textures"]["combined"]
        sample["Diffuse Indirect"] = comp["textures"]["indirect"]
    acc.add(sample)


def supersample(state, base: dict, textures: dict, e_indirect, lights, sky, cam_pos, view_proj,
                width: int, height: int, samples: int, filter_size: float, sky_cones: int) -> dict:
    """F12: the anti-aliased passes ({name: texture} for Supersampler.NAMES) of a frame whose
    unjittered G-buffer is `base`, passes `textures` and indirect irradiance `e_indirect` (None:
    GI off). Returns {'textures', 'seconds', 'samples'}."""
    t0 = time.perf_counter()
    acc = Supersampler(width, height)
    for k, jitter in enumerate(jitters(samples, filter_size)):
        add_sample(acc, state, base, e_indirect, lights, sky, cam_pos, view_proj, jitter,
                   sky_cones, k, samples)
    result = dict(textures)
    result.update(acc.means)
    return {"textures": result, "seconds": time.perf_counter() - t0, "samples": acc.count}


class Progressive:
    """The viewport's anti-aliasing (held by the SceneState): once a still view has converged,
    jittered samples into a running mean, up to `samples` (the same jitters in the same order
    as F12, so a still viewport ends on the F12 image); a new view, scene or world starts
    again. A redraw takes one sample, and more while they fit in `seconds` (the engine passes
    the last refining redraw's time up to its composite, so an anti-aliasing redraw costs about
    what a refining one did plus that): the 32 samples end in a few redraws, not in 32 (the open yard at 128
    px: its GI done at ~180 redraws, its anti-aliasing past 200; now done at 182). Measured
    at 64 px in tests/gpu/test_view_draw.py: 8 samples in 6 redraws (2, 2, 1, 1, 1, 1); one a
    redraw since a tile's later updates keep its direct light (the refining redraws got cheaper).
    At most MAX_PER_REDRAW a redraw: the seconds are the host's, which on a GPU measure only
    the submission, so without a cap a GPU would get all 32 samples in one redraw (one stall
    of 32 samples' work where the viewport should stay responsive)."""

    MAX_PER_REDRAW = 4

    def __init__(self):
        self.key, self.acc = None, None

    @property
    def done(self) -> int:
        return self.acc.count if self.acc is not None else 0

    def step(self, key, state, base: dict, textures: dict, e_indirect, lights, sky, cam_pos,
             view_proj, width: int, height: int, samples: int, filter_size: float,
             sky_cones: int, seconds: float = 0.0) -> dict:
        """This redraw's passes: the running mean after one more sample, and more while the
        next (timed as the last) still ends within `seconds` of the first's start (none once
        `samples` are in)."""
        if key != self.key or self.acc is None:
            self.key, self.acc = key, Supersampler(width, height)
        marks = jitters(samples, filter_size)
        t0 = time.perf_counter()
        last = 0.0
        end = min(len(marks), self.acc.count + max(int(self.MAX_PER_REDRAW), 1))
        while self.acc.count < end:
            t = time.perf_counter()
            add_sample(self.acc, state, base, e_indirect, lights, sky, cam_pos, view_proj,
                       marks[self.acc.count], sky_cones, self.acc.count, samples)
            last = time.perf_counter() - t
            if time.perf_counter() - t0 + last > seconds:
                break
        result = dict(textures)
        result.update(self.acc.means)
        return result
