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
import weakref

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
                      samplers=tuple("gbuf_" + n for n in ATTACHMENTS) + ("lights", "parts_in"),
                      images=("direct_out", "combined_out",
                              ("single", 'RGBA32F', {'READ', 'WRITE'})),
                      push=(('VEC3', 'cam_pos'), ('INT', 'light_count'),
                            ('INT', 'sample_plan'),   # samples + 256 first + 65536 take + 2^24 mode
                                                      # + 2^28 transparent film + 2^29 shading
                                                      # normals packed (gbuffer.glsl)
                            ('INT', 'sky_cones'), ('MAT4', 'inv_view_proj')))
ACCUMULATE = compute.Pass("direct_accumulate", samplers=("new_direct", "new_combined"),
                          images=(("direct_mean", 'RGBA32F', {'READ', 'WRITE'}),
                                  ("combined_mean", 'RGBA32F', {'READ', 'WRITE'}),
                                  ("parts", 'R32F', {'READ', 'WRITE'})),
                          push=(('INT', 'frames'),))
RESTART = compute.Pass("direct_restart",
                       samplers=tuple("gbuf_" + n for n in ATTACHMENTS) + ("lights", "regions"),
                       images=(("signature", 'R32I', {'READ', 'WRITE'}),
                               ("parts", 'R32F', {'READ', 'WRITE'})),
                       push=(('VEC3', 'cam_pos'), ('INT', 'light_count'), ('INT', 'region_count'),
                             ('INT', 'sky_cones'), ('INT', 'full'), ('INT', 'light_samples')))
MAX_REGIONS = 32           # boxes a restart tests; more start every pixel again


def shade(resources: SceneResources, gbuf: dict, lights: np.ndarray, sky: SkyLight, cam_pos,
          inv_view_proj, width: int, height: int, sky_cones: int = SKY_CONES, light_texture=None,
          light_samples: int = LIGHT_SAMPLES, part=None, single=None) -> dict:
    """Run the pass; returns {'textures': {'direct', 'combined'} (GPUTextures, not read back),
    timings}.
    `light_texture`: the rows already on the GPU (SceneState.light_texture), else made here.
    sky_cones = 0 leaves the sky light out (the GI passes bring it). part = (first, take): only
    those of each light's samples and of the sky cones (None: all). single = (texture, mode,
    parts): mode 1 stores the one-sample lights' E into the texture, 2 reads it instead of
    evaluating them, 3 (part = (frames, take); `parts` the R32F texture of each pixel's parts so
    far) each pixel its own part, nothing where it has `frames` (Progressive); None: every light
    evaluated."""
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
    single_tex, mode, parts = (_dummy(), 0, None) if single is None else single
    DIRECT.run((width, height), scene=resources, sky=sky,
               **{"gbuf_" + n: gbuf["textures"][n] for n in ATTACHMENTS}, lights=light_tex,
               direct_out=direct, combined_out=combined, inv_view_proj=inv_view_proj,
               single=single_tex, parts_in=parts if parts is not None else _dummy('R32F'),
               cam_pos=compute.vec(cam_pos), light_count=count, sky_cones=int(sky_cones),
               sample_plan=int(light_samples) + 256 * int(first) + 65536 * int(take)
               + 16777216 * mode
               + 268435456 * int(getattr(sky, "film_alpha", 1.0) == 0.0)    # Film > Transparent
               + 536870912 * int(bool(gbuf.get("shading_normals"))))
    out = {"textures": {"direct": direct, "combined": combined}}
    out["compile_seconds"] = t1 - t0
    out["shade_seconds"] = time.perf_counter() - t1
    return out


def _dummy(fmt='RGBA32F'):
    """A 1x1 texture for an input or output a dispatch does not use."""
    return gpu.types.GPUTexture((1, 1), format=fmt)


class Progressive:
    """The viewport's direct light, spread over redraws and then kept (one per engine instance,
    on SceneState.direct).

    Why: the direct pass was a fifth of a 640x360 viewport frame (bench/pass_profile.py), and
    a still view computed the same shadows every redraw. Each pixel keeps a running mean of
    parts: part c evaluates TAKE of each light's LIGHT_SAMPLES strata and of the SKY_CONES sky
    cones (those from c * TAKE on), and the mean of FRAMES parts is exactly F12's full pass
    (light_lib.glsl: light_irradiance_part); a pixel whose mean is whole costs nothing, and once
    every pixel's is the pass does not run. TAKE = 1: the first redraw after a change costs an
    eighth of the full pass, as the GI's GISettings.split spreads its own work. A light with one
    sample (a sun, a light without radius) is the same in every part: part 0 stores its E
    (`single`) and the later parts read it (a sun's shadow cone made every part cost as much as
    the whole pass).
    Every pixel starts again when `key` changes (camera, size, sky cones, the engine instance's
    epoch of edits other than moves, the world) or when where the scene SDF changed is not
    known; otherwise only the pixels direct_restart.comp.glsl picks: where the G-buffer
    changed, or whose shadow rays pass where an object-table change moved the scene SDF
    (SceneResources.regions_since). Why: one object dragged among 1,000 restarted every
    pixel's shadows each redraw (76 ms of a 306 ms redraw, bench/object_scaling.py --move)."""

    TAKE = 1
    FRAMES = max(LIGHT_SAMPLES, SKY_CONES) // TAKE

    def __init__(self):
        self.key = None
        self.size = None
        self.direct = None       # RGBA32F running means (the pass's 'direct', 'combined')
        self.combined = None
        self.single = None       # RGBA32F: the one-sample lights' E, from each pixel's part 0
        self.parts = None        # R32F: parts in each pixel's mean (FRAMES: whole)
        self.signature = None    # R32I: a hash of the G-buffer each pixel was shaded from
        self.pending = 0         # redraws that may still have parts to run (0: converged)
        self.step = 0            # parts run since the last restart (the restarted pixels' part)
        self.traced = None       # (weakref to the SceneResources, objects_version) traced in
        self.gbuffer = None      # the G-buffer position texture last checked
        self.dispatches = 0      # direct passes run (tests: none once converged)
        self.restarts = {"full": 0, "local": 0}   # restart passes run
        self.last_restart = None  # "full", "local" or None (this redraw)

    @property
    def converged(self) -> bool:
        return self.pending <= 0

    def stats(self) -> dict:
        """GPU bytes of its kept textures: the two means and the one-sample lights' E (RGBA32F),
        the parts and the signatures (4 bytes a pixel each)."""
        if self.size is None:
            return {}
        px = self.size[0] * self.size[1]
        return {"screen_direct_progressive": px * (16 * 3 + 4 + 4)}

    def _regions(self, resources):
        """Where the scene SDF changed since the pixels were traced ([] nothing, None unknown)."""
        if self.traced is None or self.traced[0]() is not resources:
            return None
        regions = resources.regions_since(self.traced[1])
        return None if regions is None or len(regions) > MAX_REGIONS else regions

    def _restart(self, full, regions, resources, gbuf, cam_pos, light_texture, light_count,
                 sky_cones):
        """Set the parts of the pixels that start again to 0 (all of them when `full`)."""
        rows = np.zeros((max(len(regions), 1), 2, 4), np.float32)
        pad = 1e-4 * (1.0 + float(resources.grid_info["cell"]) * 32)   # float rounding
        for k, (lo, hi) in enumerate(regions):
            rows[k, 0, :3] = np.asarray(lo, np.float64) - pad
            rows[k, 1, :3] = np.asarray(hi, np.float64) + pad
        RESTART.run((self.size[0], self.size[1]),
                    **{"gbuf_" + n: gbuf["textures"][n] for n in ATTACHMENTS},
                    lights=light_texture,
                    regions=gpu.types.GPUTexture((2, len(rows)), format='RGBA32F',
                                                 data=float_buffer(rows)),
                    signature=self.signature, parts=self.parts, cam_pos=compute.vec(cam_pos),
                    light_count=int(light_count), region_count=len(regions),
                    sky_cones=int(sky_cones), full=int(full), light_samples=LIGHT_SAMPLES,
                    scene=resources)
        self.pending, self.step = self.FRAMES, 0
        self.last_restart = "full" if full else "local"
        self.restarts[self.last_restart] += 1

    def shade(self, key, resources, gbuf: dict, lights, sky, cam_pos, inv_view_proj,
              width: int, height: int, sky_cones: int, light_texture) -> dict:
        """shade() for this redraw: a new part blended into the pixels' means that are not
        whole, or the means as they are."""
        assert LIGHT_SAMPLES % self.TAKE == 0 and SKY_CONES % self.TAKE == 0
        t0 = time.perf_counter()
        self.last_restart = None
        if (width, height) != self.size:
            self.size = (width, height)
            self.direct, self.combined, self.single = (
                gpu.types.GPUTexture((width, height), format='RGBA32F') for _ in range(3))
            self.parts = gpu.types.GPUTexture((width, height), format='R32F')
            self.signature = gpu.types.GPUTexture((width, height), format='R32I')
            self.key = None
        rows = np.asarray(lights, np.float32).reshape(-1, 16)
        if light_texture is None:            # (the engine passes SceneState.light_texture)
            light_texture = gpu.types.GPUTexture(
                (4, max(len(rows), 1)), format='RGBA32F',
                data=float_buffer(rows if len(rows) else np.zeros((1, 16), np.float32)))
        regions = self._regions(resources)
        position = gbuf["textures"]["position"]
        full = key != self.key or regions is None
        if full or regions or position is not self.gbuffer:
            self._restart(full, regions or [], resources, gbuf, cam_pos, light_texture,
                          len(rows), sky_cones)
        self.key, self.gbuffer = key, position
        self.traced = (weakref.ref(resources), resources.objects_version)
        if self.converged:
            return {"textures": {"direct": self.direct, "combined": self.combined},
                    "compile_seconds": 0.0, "shade_seconds": 0.0, "part": None}
        part = ((self.step * self.TAKE) % LIGHT_SAMPLES, self.TAKE)
        out = shade(resources, gbuf, lights, sky, cam_pos, inv_view_proj, width, height,
                    sky_cones=sky_cones, light_texture=light_texture,
                    part=(self.FRAMES, self.TAKE), single=(self.single, 3, self.parts))
        self.dispatches += 1
        new = out["textures"]
        ACCUMULATE.run((width, height), new_direct=new["direct"], new_combined=new["combined"],
                       direct_mean=self.direct, combined_mean=self.combined, parts=self.parts,
                       frames=self.FRAMES)
        self.pending -= 1
        self.step += 1
        out["textures"] = {"direct": self.direct, "combined": self.combined}
        out["shade_seconds"] = time.perf_counter() - t0 - out["compile_seconds"]
        out["part"] = part
        return out
