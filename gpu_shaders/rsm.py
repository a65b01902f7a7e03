"""Reflective shadow maps (lecture 21, "Reflective Shadow Maps (RSM, 2005)", Dachsbacher and
Stamminger): GI Method RSM, one bounce of the lights.

Per frame, for every light row (operators/lights.py; a sun taken out of an HDRI world is one too):
    render_maps     the G-buffer pass drawn from the light (gbuffer.render_gbuffer: the same
                    triangle extraction, materials and textures): depth, world position, normal,
                    albedo at `resolution`^2; a sun looks along its direction with an orthographic
                    frustum fitted to the scene's bounds, a spot through a square perspective
                    frustum as wide as its cone (at most 160 degrees), an area light through one
                    of 160 degrees along its normal, a point light through six of 90 (a cube)
    rsm_flux        the flux each texel reflects (albedo x the light's flux through the texel),
                    normals turned to the light
    rsm_gather      per pixel, `samples` RSM texels importance-sampled around the pixel's own
                    texel, each a small area light, no occlusion (the lecture: "Do not consider
                    occlusion"): E_indirect, summed over the lights
    gi_accumulate   F12's running mean over render_frames (a new sample rotation each), the
                    viewport's exponential history
The paper's maps are for spot and parallel lights; point and area lights are mapped the same way so
that any scene's lights bounce. A map shows what the light meets (light_view): objects hidden
from the camera or held out too, not those that cast no shadow (Ray Visibility > Shadow off:
light passes them), and those diffuse rays do not see (Ray Visibility > Diffuse off) black (they
stop the light and bounce none of it). Emission bounces only through the direct pass's lights:
an emissive surface is no light here. Needs a GPU context.
"""
from __future__ import annotations

import math

import numpy as np

from . import compute

SPOT_MAX_HALF = math.radians(80.0)   # a wider spot's map would spend its texels near the edges
FLUX = compute.Pass("rsm_flux", samplers=("rsm_position", "rsm_normal", "rsm_albedo", "lights"),
                    images=("flux_out", "normal_out"),
                    push=(('INT', 'light_index'), ('FLOAT', 'texel_area'), ('FLOAT', 'tan_half')))
GATHER = compute.Pass("rsm_gather",
                      samplers=("gbuf_position", "gbuf_normal", "rsm_position", "rsm_normal",
                                "rsm_flux"),
                      images=(("out_image", 'RGBA32F', {'READ', 'WRITE'}),),
                      push=(('MAT4', 'light_vp'), ('VEC3', 'cam_pos'), ('INT', 'samples'),
                            ('INT', 'frame'), ('INT', 'accumulate')))


def scene_bounds(objects):
    """(lo, hi) world corners of every extracted object's vertices (numpy float64 [3])."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for ob in objects or ():
        v = np.asarray(ob.vertices, np.float64).reshape(-1, 3)
        if not len(v):
            continue
        m = np.asarray(ob.matrix_world, np.float64)
        if not np.isfinite(m).all():
            continue
        corners = np.array([[x, y, z] for x in (v[:, 0].min(), v[:, 0].max())
                            for y in (v[:, 1].min(), v[:, 1].max())
                            for z in (v[:, 2].min(), v[:, 2].max())])
        w = corners @ m[:3, :3].T + m[:3, 3]
        lo, hi = np.minimum(lo, w.min(0)), np.maximum(hi, w.max(0))
    if not np.isfinite(lo).all():
        return np.full(3, -1.0), np.full(3, 1.0)
    return lo, hi


def look_along(eye, forward) -> np.ndarray:
    """World -> view 4x4 (OpenGL: the view looks down -Z) at `eye` looking along `forward`."""
    f = np.asarray(forward, np.float64)
    f = f / max(np.linalg.norm(f), 1e-12)
    up = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = r, u, -f
    view[:3, 3] = -view[:3, :3] @ np.asarray(eye, np.float64)
    return view


def _perspective(pos, forward, tan_half: float, far: float) -> np.ndarray:
    """View-projection of a square perspective frustum at pos along forward (OpenGL clip)."""
    near = max(1e-3 * far, 1e-3)
    f = 1.0 / tan_half
    proj = np.array([[f, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2.0 * far * near / (near - far)],
                     [0, 0, -1.0, 0]])
    return proj @ look_along(pos, forward)


CUBE = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))


def light_frusta(row, lo, hi, res: int) -> list:
    """[(light view-projection 4x4, texel area across a sun's light in m^2, tan of the half
    angle of a perspective map)] of one light row over the scene bounds lo..hi: a sun one
    orthographic map fitted to the bounds; a spot one perspective map as wide as its cone (at
    most 160 degrees); an area light (one-sided, I0 cos: operators/lights.py) one map of 160
    degrees along its normal (the 3% of its power beyond 80 degrees is left out); a point light
    six maps of 90 degrees, a cube."""
    kind = int(round(float(row[0])))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    pad = 1e-3 * max(float(np.linalg.norm(hi - lo)), 1e-3) + 1e-3
    if kind == 0:
        view = look_along(0.5 * (lo + hi), row[4:7])
        c = corners @ view[:3, :3].T + view[:3, 3]
        half = float(np.abs(c[:, :2]).max()) + pad          # square: texels of one area
        near, far = -float(c[:, 2].max()) - pad, -float(c[:, 2].min()) + pad
        proj = np.array([[1.0 / half, 0, 0, 0], [0, 1.0 / half, 0, 0],
                         [0, 0, -2.0 / (far - near), -(far + near) / (far - near)],
                         [0, 0, 0, 1.0]])
        return [(proj @ view, (2.0 * half / res) ** 2, 0.0)]
    pos = np.asarray(row[1:4], np.float64)
    far = float(np.linalg.norm(corners - pos, axis=1).max()) * 1.01 + pad
    if kind == 1:
        return [(_perspective(pos, axis, 1.0, far), 0.0, 1.0) for axis in CUBE]
    half_angle = SPOT_MAX_HALF
    if kind == 2:
        half_angle = min(math.acos(min(max(float(row[12]), -1.0), 1.0)), SPOT_MAX_HALF)
    tan_half = math.tan(half_angle)
    return [(_perspective(pos, row[4:7], tan_half, far), 0.0, tan_half)]


def light_view(objects) -> list:
    """The ObjectInputs as a light's map draws them (see the module docstring): the camera's
    flags cleared, shadowless ones left out, diffuse-invisible ones black."""
    import dataclasses

    from ..lumen_addon.materials import Material

    black = dict(base_color=(0.0, 0.0, 0.0), base_color_texture=None, vertex_colors=False)
    out = []
    for o in objects:
        if not o.casts_shadow:
            continue
        change = {}
        if not o.camera_visible or o.holdout:
            change.update(camera_visible=True, holdout=False)
        unseen = not o.diffuse_visible
        if o.materials and (unseen or any(m.holdout for m in o.materials)):
            look = black if unseen else {}
            change["materials"] = [dataclasses.replace(m, holdout=False, **look)
                                   for m in o.materials]
        elif unseen:                     # no materials: plain grey, so one black material
            change.update(materials=[Material(name="unseen", base_color=(0.0, 0.0, 0.0))],
                          material_ids=np.zeros(len(o.triangles), np.int32))
        out.append(dataclasses.replace(o, **change) if change else o)
    return out


class RSM:
    """The lights' reflective shadow maps of the last frame and the gathered history."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.maps = []               # per light: dict(light_vp, textures, row index)
        self.history = None
        self.frames = 0
        self.key = None              # (view key, settings, sky key) of the history
        self._view = None            # (objects, light_view(objects)) of the last maps

    def reset(self):
        self.history, self.frames = None, 0

    def render_maps(self, objects, lights: np.ndarray, light_texture, res: int):
        """Draw and shade the maps of every light (every frame: the lights, objects and
        materials may have changed; a map costs one G-buffer draw at res^2)."""
        rows = np.asarray(lights, np.float32).reshape(-1, 16)
        lo, hi = scene_bounds(objects)
        if self._view is None or self._view[0] is not objects:
            self._view = (objects, light_view(objects))    # the same list until a new walk
        objects = self._view[1]
        self.maps = []
        cache = {}                                   # texture uploads shared by the maps
        for index, row in enumerate(rows):
            for light_vp, texel_area, tan_half in light_frusta(row, lo, hi, res):
                self._render_map(objects, index, light_vp, texel_area, tan_half, light_texture,
                                 res, cache)

    def _render_map(self, objects, index, light_vp, texel_area, tan_half, light_texture, res,
                    cache):
        from .gbuffer import render_gbuffer

        g = render_gbuffer(objects, light_vp, res, res, texture_cache=cache)
        t = g["textures"]
        flux, normal = compute.texture((res, res)), compute.texture((res, res))
        FLUX.run((res, res), rsm_position=t["position"], rsm_normal=t["normal"],
                 rsm_albedo=t["albedo"], lights=light_texture, light_index=index,
                 texel_area=float(texel_area), tan_half=float(tan_half), flux_out=flux,
                 normal_out=normal)
        self.maps.append(dict(light=index, light_vp=light_vp, texel_area=texel_area,
                              textures=dict(depth=g["depth_texture"], position=t["position"],
                                            normal=normal, flux=flux)))

    def iterate(self, gbuf: dict, cam_pos, samples: int, frame: int, blend: float):
        """One gather (after render_maps()) blended into the history; returns the history."""
        from .ssgi import accumulate

        new = self.gather(gbuf, cam_pos, samples, frame)
        self.history, self.frames = accumulate(self.history, new, blend, self.width,
                                               self.height, self.frames)
        return self.history

    def gather(self, gbuf: dict, cam_pos, samples: int, frame: int):
        """This frame's E_indirect from every map (RGBA32F texture; zero without maps)."""
        out = compute.texture((self.width, self.height))
        g = gbuf["textures"]
        for k, m in enumerate(self.maps):
            t = m["textures"]
            GATHER.run((self.width, self.height), gbuf_position=g["position"],
                       gbuf_normal=g["normal"], rsm_position=t["position"],
                       rsm_normal=t["normal"], rsm_flux=t["flux"], light_vp=m["light_vp"],
                       cam_pos=compute.vec(cam_pos), samples=int(samples), frame=int(frame),
                       accumulate=int(k > 0), out_image=out)
        return out

    def flux_image(self, width: int, height: int) -> np.ndarray:
        """The RSM_FLUX debug view (reads the maps back): each light's map side by side, as the
        radiance its texels reflect, Phi / (pi A) (what the image would show of a surface lit by
        that light alone), stretched over the image; black without maps."""
        out = np.zeros((height, width, 4), np.float32)
        out[..., 3] = 1.0
        if not self.maps:
            return out
        tiles = []
        for m in self.maps:
            f = compute.read(m["textures"]["flux"])
            tiles.append(np.where(f[..., 3:] > 0, f[..., :3] / (np.pi * np.maximum(
                f[..., 3:], 1e-12)), 0.0))
        atlas = np.concatenate(tiles, axis=1)
        ys = np.minimum((np.arange(height) * atlas.shape[0]) // height, atlas.shape[0] - 1)
        xs = np.minimum((np.arange(width) * atlas.shape[1]) // width, atlas.shape[1] - 1)
        out[..., :3] = atlas[ys][:, xs]
        return out

    def stats(self) -> dict:
        """GPU bytes: per light the map's G-buffer (four RGBA32F + 32-bit depth, of which the
        passes keep position, normal, flux and depth), and the history."""
        out = {}
        for m in self.maps:
            for name, t in m["textures"].items():
                key = f"rsm_{name}"
                out[key] = out.get(key, 0) + t.width * t.height * (4 if name == "depth" else 16)
        if self.history is not None:
            out["rsm_history"] = self.width * self.height * 16
        return out
