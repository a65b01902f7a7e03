"""The direct light pass (glsl/direct_light.comp.glsl): per G-buffer pixel, Lambert diffuse
direct light of every light (operators/lights.py rows) with SDF cone-traced soft shadows, sky
light from the world's maps (sky_light.SkyLight) occluded by SDF cones, and emission.

Outputs follow Cycles' pass conventions so they compare directly:
    direct   = E / pi          (Cycles "Diffuse Direct", DiffDir: albedo excluded)
    combined = albedo * direct + emission  (the world on the background)
Needs a GPU context.
"""
from __future__ import annotations

import time

import gpu
import numpy as np

from . import compute
from .gbuffer import ATTACHMENTS
from .resources import SceneResources, float_buffer
from .sky_light import SkyLight

GROUP = 8
SKY_CONES = 8
LIGHT_SAMPLES = 8          # points per light with a radius (light_lib.glsl: soft shadows)
DIRECT = compute.Pass("direct_light",
                      samplers=tuple("gbuf_" + n for n in ATTACHMENTS) + ("lights", "single_in"),
                      images=("direct_out", "combined_out", "single_out"),
                      push=(('VEC3', 'cam_pos'), ('INT', 'light_count'),
                            ('INT', 'sample_plan'),   # samples + 256 first + 65536 take + 2^24 mode
                                                      # + 2^28 transparent film
                            ('INT', 'sky_cones'), ('MAT4', 'inv_view_proj')))
ACCUMULATE = compute.Pass("direct_accumulate", samplers=("new_direct", "new_combined"),
                          images=(("direct_mean", 'RGBA32F', {'READ', 'WRITE'}),
                                  ("combined_mean", 'RGBA32F', {'READ', 'WRITE'})),
                          push=(('FLOAT', 'blend'),))


def shade(resources: SceneResources, gbuf: dict, lights: np.ndarray, sky: SkyLight, cam_pos,
          inv_view_proj, width: int, height: int, sky_cones: int = SKY_CONES, light_texture=None,
          light_samples: int = LIGHT_SAMPLES, part=None, single=None) -> dict:
    """Run the pass; returns {'textures': {'direct', 'combined'} (GPUTextures, not read back),
    timings}.
    `light_texture`: the rows already on the GPU (SceneState.light_texture), else made here.
    sky_cones = 0 leaves the sky light out (the GI passes bring it). part = (first, take): only
    those of each light's samples and of the sky cones (None: all; see Progressive).
    single = (texture, store): the one-sample lights' E stored into the texture (store True) or
    read from it instead of evaluated (False); None: evaluated as the others."""
    t0 = time.perf_counter()
    DIRECT.shader                        # compiled on first use
    t1 = time.perf_counter()
    rows = np.asarray(lights, np.float32).reshape(-1, 16)
    count = len(rows)
    if not count:
        rows = np.zeros((1, 16), np.float32)
    light_tex = light_texture if light_texture is not None else gpu.types.GPUTexture(
        (4, len(rows)), format='RGBA32F', data=float_buffer(rows))
    direct = gpu.types.GPUTexture((width, height), format='RGBA32F')
    combined = gpu.types.GPUTexture((width, height), format='RGBA32F')
    first, take = part if part is not None else (0, max(light_samples, sky_cones, 1))
    if single is None:
        single_tex, mode = _dummy(), 0
    else:
        single_tex, mode = single[0], (1 if single[1] else 2)
    DIRECT.run((width, height), scene=resources, sky=sky,
               **{"gbuf_" + n: gbuf["textures"][n] for n in ATTACHMENTS}, lights=light_tex,
               direct_out=direct, combined_out=combined, inv_view_proj=inv_view_proj,
               single_in=single_tex if mode == 2 else _dummy(),
               single_out=single_tex if mode == 1 else _dummy(),
               cam_pos=compute.vec(cam_pos), light_count=count, sky_cones=int(sky_cones),
               sample_plan=int(light_samples) + 256 * int(first) + 65536 * int(take)
               + 16777216 * mode
               + 268435456 * int(getattr(sky, "film_alpha", 1.0) == 0.0))   # Film > Transparent
    out = {"textures": {"direct": direct, "combined": combined}}
    out["compile_seconds"] = t1 - t0
    out["shade_seconds"] = time.perf_counter() - t1
    return out


def _dummy():
    """A 1x1 texture for the single-light input or output a dispatch does not use."""
    return gpu.types.GPUTexture((1, 1), format='RGBA32F')


class Progressive:
    """The viewport's direct light, spread over redraws and then kept (one per engine instance,
    on SceneState.direct).

    Why: the direct pass was a fifth of a 640x360 viewport frame (bench/pass_profile.py), and
    a still view computed the same shadows every redraw. Here redraw j evaluates TAKE of each
    light's LIGHT_SAMPLES strata and of the SKY_CONES sky cones (those from j * TAKE on), and the
    running mean of FRAMES such parts is exactly F12's full pass (light_lib.glsl:
    light_irradiance_part); after that the pass does not run again until the view, the scene or
    the world changes (`key`: camera, size, sky cones, the engine instance's depsgraph epoch).
    TAKE = 1: the first redraw after a change costs an eighth of the full pass, as the GI's
    GISettings.split spreads its own work. A light with one sample (a sun, a light without
    radius) is the same in every part: the first part stores its E (`single`) and the later
    parts read it instead of tracing its shadow again (bench/pass_profile.py: a sun's shadow
    cone made every part cost as much as the whole pass)."""

    TAKE = 1
    FRAMES = max(LIGHT_SAMPLES, SKY_CONES) // TAKE

    def __init__(self):
        self.key = None
        self.done = 0            # parts in the mean (FRAMES: converged)
        self.direct = None       # RGBA32F running means (the pass's 'direct', 'combined')
        self.combined = None
        self.single = None       # RGBA32F: the one-sample lights' E, from the first part
        self.dispatches = 0      # direct passes run (tests: none once converged)

    @property
    def converged(self) -> bool:
        return self.done >= self.FRAMES

    def shade(self, key, resources, gbuf: dict, lights, sky, cam_pos, inv_view_proj,
              width: int, height: int, sky_cones: int, light_texture) -> dict:
        """shade() for this redraw: a new part blended into the mean, or the mean as it is."""
        assert LIGHT_SAMPLES % self.TAKE == 0 and SKY_CONES % self.TAKE == 0
        t0 = time.perf_counter()
        if key != self.key:
            self.key, self.done = key, 0
        if self.converged:
            return {"textures": {"direct": self.direct, "combined": self.combined},
                    "compile_seconds": 0.0, "shade_seconds": 0.0, "part": None}
        part = ((self.done * self.TAKE) % LIGHT_SAMPLES, self.TAKE)
        if self.done == 0:
            self.single = gpu.types.GPUTexture((width, height), format='RGBA32F')
        out = shade(resources, gbuf, lights, sky, cam_pos, inv_view_proj, width, height,
                    sky_cones=sky_cones, light_texture=light_texture, part=part,
                    single=(self.single, self.done == 0))
        self.dispatches += 1
        new = out["textures"]
        if self.done == 0:
            self.direct, self.combined = new["direct"], new["combined"]
        else:
            ACCUMULATE.run((width, height), new_direct=new["direct"],
                           new_combined=new["combined"], direct_mean=self.direct,
                           combined_mean=self.combined, blend=1.0 / (self.done + 1))
        self.done += 1
        out["textures"] = {"direct": self.direct, "combined": self.combined}
        out["shade_seconds"] = time.perf_counter() - t0 - out["compile_seconds"]
        out["part"] = part
        return out
