"""Voxel cone tracing (lecture 21, "Voxelization Based Global Illumination (VXGI)" and "Shading
with Cone Tracing"): GI Method VXGI. The final gather of gi.indirect_light in place of the screen
probes: per pixel a few wide cones in the normal's hemisphere, marched front to back through the
global SDF's clipmaps (glsl/vxgi_cones.comp.glsl):

    opacity   from the global SDF: saturate(1 - d / r) at each sample, r the cone's radius
    radiance  from the voxel lighting (voxel_lighting.py: the surface cache's final light in 6
              axis directions per clipmap voxel), the level chosen by the cone's radius
    sky       sky_ray along the cone's axis for what passes through

Everything VXGI reads is kept up to date by Lumen's own pipeline (gi.indirect_light with
`gather=`): the global SDF, the surface cache (direct, radiosity bounces, combine) and the voxel
lighting, which VXGI switches on whatever the Voxel Lighting setting says. So the voxels carry
the surface cache's multi-bounce light, and a VXGI frame costs Lumen's minus the screen probes
plus the cones.

Pre-filtering: none beyond what the clipmaps are. A wide cone reads a coarser level, whose voxel
faces hold the light of the surface that level's own short rays meet (a point sample at the
coarse voxel's size, not an average of the finer voxels); the trilinear lookup over 8 voxels
spans two voxels, so the level whose voxel is the cone's radius covers the cone's diameter. An
averaging pass (level k's 2x2x2 voxels into level k + 1) was left out: the levels differ in
extent (clipmaps around the camera), the averages would need their own 6-direction visibility
(an average over a thin wall mixes its two sides) and its own cadence. What it costs: a bright
object smaller than a coarse voxel is seen by a wide cone only if a short ray of that level
meets it (aliasing instead of blur).

Known failures, as the lecture says: opacity comes from a distance field sampled at points a
cone radius apart, so a wall thinner than the sampling leaks part of what lies behind it; and
far cones read voxels of up to 1 m (Medium), which blur light across a room. Needs a GPU context.
"""
from __future__ import annotations

import math

import numpy as np

from . import compute

CONES = compute.Pass("vxgi_cones", samplers=("gbuf_position", "gbuf_normal"),
                     push=(('VEC4', 'cam_tmax'), ('VEC4', 'cone'), ('IVEC4', 'counts')))

class VXGI:
    """The cones' output and history for one image size (held on SceneState.gi_methods); the
    gather gi.indirect_light calls in place of ScreenProbes (same history / frames / gather /
    temporal)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.history = None          # accumulated E (RGBA32F; w: mean cone opacity)
        self.frames = 0
        self.key = None
        self.settings = None         # gi_methods.MethodSettings of this frame (vxgi_*)
        self.textures = {}

    def reset(self):
        self.history, self.frames = None, 0

    def gather(self, resources, gsdf, cache, gbuf: dict, cam_pos, sky, frame: int, t_max: float,
               voxels=None):
        """This frame's E_indirect from the cones (RGBA32F texture; w = mean opacity, -1 on the
        background). `resources` and `cache` are unused: the cones read the clipmaps only."""
        if voxels is None:
            raise ValueError("VXGI needs the voxel lighting")
        s = self.settings
        half = math.radians(float(s.vxgi_cone_angle) * 0.5)
        g = gbuf["textures"]
        out = self.textures["cones"] = compute.texture((self.width, self.height))
        CONES.run((self.width, self.height), gsdf=gsdf, sky=sky, voxels=voxels,
                  gbuf_position=g["position"], gbuf_normal=g["normal"],
                  cam_tmax=compute.vec(cam_pos) + [float(min(t_max, s.vxgi_distance))],
                  cone=(math.sin(half), math.cos(half), float(s.vxgi_step), float(s.vxgi_offset)),
                  counts=(int(s.vxgi_cones), int(frame), 0, 0), out_image=out)
        return out

    def temporal(self, new, blend: float):
        """history = mix(history, new, blend) (blend 1 or no history: start again); the F12
        frames rotate the ring of cones, so their running mean smooths its directions."""
        from .ssgi import accumulate

        self.history, self.frames = accumulate(self.history, new, blend, self.width,
                                               self.height, self.frames)
        return self.history

    def occlusion_image(self) -> np.ndarray:
        """The VXGI_OCCLUSION debug view (reads the history back): grey = the cones' mean opacity
        (1: every cone stopped on a surface, 0: every cone saw the sky); black background."""
        out = np.zeros((self.height, self.width, 4), np.float32)
        out[..., 3] = 1.0
        if self.history is None:
            return out
        a = compute.read(self.history)[..., 3]
        out[..., :3] = np.clip(a, 0.0, 1.0)[..., None]
        return out

    def stats(self) -> dict:
        """GPU bytes: this frame's cones and the history (RGBA32F each)."""
        px = self.width * self.height * 16
        out = {"vxgi_" + k: t.width * t.height * 16 for k, t in self.textures.items()}
        if self.history is not None and self.history is not self.textures.get("cones"):
            out["vxgi_history"] = px
        return out
