"""Screen-space global illumination (lecture 21, "Screen Space Global Illumination (SSGI)", after
Frostbite's stochastic screen-space reflections): GI Method SSGI. Per iteration, on the frame's
G-buffer:

    hzb.depth_pyramid   HZB: MIN chain of window depths (once per frame)
    hzb.colour_pyramid  the radiance source: last iteration's lit image (albedo x (direct +
                        indirect) + emission; the first: the direct pass's Combined), premultiplied
                        by coverage, mean chain: the cone filter
    ssgi_trace          `rays` cosine rays per pixel through the HZB (at most `steps` cells)
    ssgi_resolve        every pixel reuses the rays of its (2 reuse + 1)^2 neighbours on its
                        surface (ratio estimator, cos / pdf weights) and reads the pyramid at the
                        cone's footprint: E_indirect
    gi_accumulate       temporal: F12's running mean, the viewport's exponential history

What leaves the screen, runs out of steps or starts on the background brings nothing: the sky's
light comes from the direct pass (its SDF-occluded sky light, as with GI Off) and what the screen
does not show is missing, as the lecture says of SSGI. Each F12 iteration's lit image feeds the
next, so light bounces once more per iteration (bounces - 1 warm-up iterations, then
render_frames averaged); the viewport keeps last redraw's lit image while the view and the scene
stay, and starts again from the direct image when they change (no reprojection).
Needs a GPU context.
"""
from __future__ import annotations

import math

import mathutils
import numpy as np

from . import compute, hzb

LEFT, STEPS, NONE = -1.0, -2.0, -3.0      # ssgi_trace's miss codes (the hits' w)
GBUF = ("gbuf_position", "gbuf_normal")
TRACE = compute.Pass("ssgi_trace", samplers=GBUF + ("hzb",),
                     push=(('MAT4', 'view_proj'), ('VEC4', 'cam_tmax'), ('IVEC4', 'counts'),
                           ('FLOAT', 'thickness')))
RESOLVE = compute.Pass("ssgi_resolve", samplers=GBUF + ("hits", "colour"),
                       push=(('MAT4', 'view_proj'), ('VEC3', 'cam_pos'), ('INT', 'rays'),
                             ('INT', 'reuse'), ('FLOAT', 'cone_tan')))
ACCUMULATE = compute.Pass("gi_accumulate", samplers=("e_new", "e_history"),
                          push=(('FLOAT', 'blend'), ('INT', 'mix_alpha')))


def cone_tan(rays: int, reuse: int) -> float:
    """tan of the half-angle of the cone one sample stands for: rays x (2 reuse + 1)^2 samples
    share the hemisphere's 2 pi sr, a cone of solid angle 2 pi / n has cos = 1 - 1 / n."""
    n = max(int(rays) * (2 * int(reuse) + 1) ** 2, 2)
    c = 1.0 - 1.0 / n
    return math.sqrt(max(1.0 - c * c, 0.0)) / c


class SSGI:
    """SSGI's textures and history for one image size (held by the engine's SceneState)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.history = None          # accumulated E (RGBA32F)
        self.frames = 0
        self.source = None           # last iteration's lit image (the next radiance source)
        self.key = None              # (view key, settings, sky key) of the history and source
        self.textures = {}

    def reset(self):
        self.history, self.frames, self.source = None, 0, None

    def prepare(self, gbuf: dict, view_proj):
        """Build this frame's HZB (once per frame: every iteration of a frame traces the same
        G-buffer)."""
        self.textures["hzb"] = hzb.depth_pyramid(gbuf, view_proj, self.width, self.height)

    def iterate(self, gbuf: dict, direct_textures: dict, sky, view_proj, inv_view_proj, cam_pos,
                settings, frame: int, blend: float, t_max: float):
        """One SSGI iteration (after prepare()): trace, resolve, blend into the history, and the
        lit image that the next iteration reads. Returns the accumulated E texture."""
        from . import composite

        w, h = self.width, self.height
        tex = self.textures
        g = gbuf["textures"]
        source = self.source if self.source is not None else direct_textures["combined"]
        tex["colour"] = hzb.colour_pyramid(source, gbuf, w, h)
        vp = mathutils.Matrix(np.asarray(view_proj, np.float64).tolist())
        rays = max(int(settings.ssgi_rays), 1)

        tex["hits"] = compute.texture((w * rays, h))
        gbuf_in = dict(gbuf_position=g["position"], gbuf_normal=g["normal"], view_proj=vp)
        TRACE.run((w * rays, h), **gbuf_in, hzb=tex["hzb"],
                  cam_tmax=compute.vec(cam_pos) + [float(t_max)],
                  counts=(rays, int(frame), int(settings.ssgi_steps), 0),
                  thickness=float(settings.ssgi_thickness), out_image=tex["hits"])

        new = compute.texture((w, h))
        RESOLVE.run((w, h), **gbuf_in, hits=tex["hits"], colour=tex["colour"],
                    cam_pos=compute.vec(cam_pos), rays=rays, reuse=int(settings.ssgi_reuse),
                    cone_tan=cone_tan(rays, settings.ssgi_reuse), out_image=new)

        self.history, self.frames = accumulate(self.history, new, blend, w, h, self.frames)
        comp = composite.composite(gbuf, direct_textures["direct"], self.history, sky,
                                   inv_view_proj, w, h)
        self.source = comp["textures"]["combined"]
        return self.history

    def hit_image(self) -> np.ndarray:
        """The SSGI_HITS debug view (reads the last trace back): per pixel the share of its own
        rays that hit on screen (green), left the screen (blue), ran out of steps (red); black
        on the background."""
        w, h = self.width, self.height
        out = np.zeros((h, w, 4), np.float32)
        out[..., 3] = 1.0
        hits = self.textures.get("hits")
        if hits is None:
            return out
        code = compute.read(hits)[..., 3].reshape(h, w, -1)
        surface = (code > NONE + 0.5).any(axis=-1)
        n = np.maximum(code.shape[-1], 1)
        out[..., 0] = np.where(surface, (np.abs(code - STEPS) < 0.5).sum(-1) / n, 0.0)
        out[..., 1] = np.where(surface, (code >= 0.0).sum(-1) / n, 0.0)
        out[..., 2] = np.where(surface, (np.abs(code - LEFT) < 0.5).sum(-1) / n, 0.0)
        return out

    def stats(self) -> dict:
        """GPU bytes: HZB (R32F), colour pyramid and hits (RGBA32F), history and source."""
        out = {}
        for name, t in self.textures.items():
            out["ssgi_" + name] = t.width * t.height * (4 if name == "hzb" else 16)
        px = self.width * self.height * 16
        if self.history is not None:
            out["ssgi_history"] = px
        if self.source is not None:
            out["ssgi_source"] = px
        return out


def accumulate(history, new, blend: float, width: int, height: int, frames: int,
               mix_alpha: bool = False):
    """(mix(history, new, blend), frames in it): blend >= 1 or no history starts again. The
    alpha is new's (a flag), or with mix_alpha mixed as the colour."""
    if history is None or blend >= 1.0:
        return new, 1
    out = compute.texture((width, height))
    ACCUMULATE.run((width, height), e_new=new, e_history=history, blend=float(blend),
                   mix_alpha=int(mix_alpha), out_image=out)
    return out, frames + 1
