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
import mathutils
import numpy as np

from . import compute
from .gbuffer import ATTACHMENTS
from .resources import SceneResources, float_buffer, glsl
from .sky_light import SkyLight

GROUP = 8
SKY_CONES = 8
LIGHT_SAMPLES = 8          # points per light with a radius (light_lib.glsl: soft shadows)
_SHADER = {}


def direct_shader():
    if "direct" not in _SHADER:
        info = compute.new_info((GROUP, GROUP, 1))
        slot = SceneResources.declare(info, 0)
        for name in ATTACHMENTS:
            info.sampler(slot, 'FLOAT_2D', "gbuf_" + name)
            slot += 1
        info.sampler(slot, 'FLOAT_2D', "lights")
        slot = SkyLight.declare(info, slot + 1)
        info.image(0, 'RGBA32F', 'FLOAT_2D', 'direct_out', qualifiers={'WRITE'})
        info.image(1, 'RGBA32F', 'FLOAT_2D', 'combined_out', qualifiers={'WRITE'})
        info.push_constant('VEC3', 'cam_pos')
        info.push_constant('INT', 'light_count')
        info.push_constant('INT', 'sample_plan')   # samples + 256 first + 65536 take (128 B)
        info.push_constant('INT', 'sky_cones')
        info.push_constant('MAT4', 'inv_view_proj')
        _SHADER["direct"] = compute.create(info, glsl("direct_light.comp.glsl"))
    return _SHADER["direct"]


def shade(resources: SceneResources, gbuf: dict, lights: np.ndarray, sky: SkyLight, cam_pos,
          inv_view_proj, width: int, height: int, sky_cones: int = SKY_CONES, light_texture=None,
          light_samples: int = LIGHT_SAMPLES, part=None) -> dict:
    """Run the pass; returns {'textures': {'direct', 'combined'} (GPUTextures, not read back),
    timings}.
    `light_texture`: the rows already on the GPU (SceneState.light_texture), else made here.
    sky_cones = 0 leaves the sky light out (the GI passes bring it). part = (first, take): only
    those of each light's samples and of the sky cones (None: all; see Progressive)."""
    t0 = time.perf_counter()
    shader = direct_shader()
    t1 = time.perf_counter()
    rows = np.asarray(lights, np.float32).reshape(-1, 16)
    count = len(rows)
    if not count:
        rows = np.zeros((1, 16), np.float32)
    light_tex = light_texture if light_texture is not None else gpu.types.GPUTexture(
        (4, len(rows)), format='RGBA32F', data=float_buffer(rows))
    direct = gpu.types.GPUTexture((width, height), format='RGBA32F')
    combined = gpu.types.GPUTexture((width, height), format='RGBA32F')
    resources.bind(shader)
    for name in ATTACHMENTS:
        shader.uniform_sampler("gbuf_" + name, gbuf["textures"][name])
    shader.uniform_sampler("lights", light_tex)
    shader.image("direct_out", direct)
    shader.image("combined_out", combined)
    sky.bind(shader)
    shader.uniform_float("inv_view_proj",
                         mathutils.Matrix(np.asarray(inv_view_proj, np.float64).tolist()))
    shader.uniform_float("cam_pos", [float(c) for c in np.asarray(cam_pos, np.float64)[:3]])
    shader.uniform_int("light_count", count)
    shader.uniform_int("sky_cones", int(sky_cones))
    first, take = part if part is not None else (0, max(light_samples, sky_cones, 1))
    shader.uniform_int("sample_plan", int(light_samples) + 256 * int(first) + 65536 * int(take))
    compute.run(shader, -(-width // GROUP), -(-height // GROUP), 1)
    out = {"textures": {"direct": direct, "combined": combined}}
    out["compile_seconds"] = t1 - t0
    out["shade_seconds"] = time.perf_counter() - t1
    return out


class Progressive:
    """The viewport's direct light, spread over redraws and then kept (one per engine instance,
    on SceneState.direct).

    Why: the direct pass was a fifth of a 640x360 viewport frame (bench/pass_profile.py), and
    a still view computed the same shadows every redraw. Here redraw j evaluates TAKE of each
    light's LIGHT_SAMPLES strata and of the SKY_CONES sky cones (those from j * TAKE on), and the
    running mean of FRAMES such parts is exactly F12's full pass (light_lib.glsl:
    light_irradiance_part); after that the pass does not run again until the view, the scene or
    the world changes (`key`: camera, size, sky cones, the engine instance's depsgraph epoch).
    The first redraw after a change costs a quarter of the full pass."""

    TAKE = 2
    FRAMES = max(LIGHT_SAMPLES, SKY_CONES) // TAKE

    def __init__(self):
        self.key = None
        self.done = 0            # parts in the mean (FRAMES: converged)
        self.direct = None       # RGBA32F running means (the pass's 'direct', 'combined')
        self.combined = None
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
        out = shade(resources, gbuf, lights, sky, cam_pos, inv_view_proj, width, height,
                    sky_cones=sky_cones, light_texture=light_texture, part=part)
        self.dispatches += 1
        new = out["textures"]
        if self.done == 0:
            self.direct, self.combined = new["direct"], new["combined"]
        else:
            sh = compute.shader("direct_accumulate", samplers=("new_direct", "new_combined"),
                                images=(("direct_mean", 'RGBA32F', {'READ', 'WRITE'}),
                                        ("combined_mean", 'RGBA32F', {'READ', 'WRITE'})),
                                push=(('FLOAT', 'blend'),))
            sh.uniform_sampler("new_direct", new["direct"])
            sh.uniform_sampler("new_combined", new["combined"])
            sh.image("direct_mean", self.direct)
            sh.image("combined_mean", self.combined)
            sh.uniform_float("blend", 1.0 / (self.done + 1))
            compute.dispatch(sh, width, height)
        self.done += 1
        out["textures"] = {"direct": self.direct, "combined": self.combined}
        out["shade_seconds"] = time.perf_counter() - t0 - out["compile_seconds"]
        out["part"] = part
        return out
