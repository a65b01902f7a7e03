"""Screen probes (lecture 21, "Screen Space Probe" through "Final integration with SH"): the final
gather of indirect light for every pixel, from few probes.

Per frame, one GLSL pass each:
    screen_probe_place      one probe per tile x tile pixels on a jittered G-buffer pixel
    screen_probe_adaptive   (adaptive) probes at 8x8, then 4x4 pixel tiles whose jittered pixel
                            the uniform probes do not interpolate, in the atlas below them
                            (slots [0, 2gw) x [gh, 3gh) and [0, 4gw) x [3gh, 7gh), mostly empty:
                            a dense layout needs no atomics; every later pass runs over the
                            atlas, an empty slot returns at once)
    screen_probe_rays       importance sampling (from the second frame): per probe, which
                            texel or texel quarter each of its res^2 ray slots traces, by the
                            BRDF of the pixels around it x last frame's radiance of the nearest
                            history probe (ray redistribution: 4 low-pdf texels share a ray,
                            its 3 slots supersample a high-pdf texel)
    screen_probe_trace      res x res octahedral rays per probe (whole sphere, world directions,
                            jittered per frame) through gi_trace_lib: surface cache at hits, sky;
                            with the world radiance cache (radiance_cache.py) rays trace ~2 m,
                            then the cache's update and resolve passes give the far field
    screen_probe_compose    (importance sampling) the texel atlas from the slots, weighted so
                            each texel's estimate stays unbiased
    screen_probe_links      which of its 3x3 neighbours each probe sees (short SDF rays, once
                            per probe)
    screen_probe_filter     3x3 probe spatial filter: plane weights, angle-error rejection,
                            hit-distance clamp, the links
    screen_probe_sh         9 SH coefficients per probe (exact texel solid angles; the probe's
                            mean projected exactly: a constant L gives pi L every frame)
    screen_probe_integrate  per pixel: 4 probes by bilinear x plane-distance weights, those a wall
                            hides left out, SH irradiance; where they fail, the adaptive probes
                            of the nearest 8x8 and 4x4 tiles on the pixel's plane; a pixel that
                            still has none traces 16 rays; every pixel adds the emitters
                            nearer its surface than a ray starts (sc_near_emission)
    screen_probe_temporal   mix with the history (running mean for F12, exponential in the viewport)
Output: per-pixel indirect irradiance E (W/m^2); the composite divides by pi (Diffuse Indirect).
Needs a GPU context.
"""
from __future__ import annotations

import numpy as np

from . import compute, radiance_cache, screen_trace, voxel_lighting
from .probe_math import hammersley

VL = voxel_lighting.SAMPLERS      # every pass that traces reads the voxel lighting at far hits


class ScreenProbes:
    """Probe textures and the temporal history for one image size."""

    def __init__(self, width: int, height: int, tile: int = 16, res: int = 8):
        self.width, self.height, self.tile, self.res = int(width), int(height), int(tile), int(res)
        self.grid = (-(-self.width // self.tile), -(-self.height // self.tile))
        self.history = None          # RGBA32F [h, w]: accumulated E
        self.frames = 0              # frames in the history
        self.textures = {}
        self.prev = None             # last frame's probes (info, normal, history): the prior
        self.atlas = self.grid       # probe slots: the grid, + adaptive levels (gather)
        self.zero_rays = None        # the slot table without importance sampling (all own texel)

    def jitter(self, frame: int):
        """(tile pixel offset, ray jitter in [0,1)^2) of a frame: 16-point Hammersley sets."""
        h = hammersley(16)
        tile = np.minimum((h[frame % 16] * self.tile).astype(int), self.tile - 1)
        ray = np.mod(h[(frame * 7 + 5) % 16] + 0.5 / 16.0, 1.0)
        return tile, ray

    def gather(self, resources, gsdf, cache, gbuf: dict, cam_pos, sky, frame: int, t_max: float,
               voxels=None, rcache=None, rc_budget: int = 0, rc_blend: float = 0.25,
               rc_retrace=None, importance: bool = True, adaptive: bool = True,
               screen=None):
        """This frame's per-pixel indirect irradiance (RGBA32F texture; w: 1 interpolated,
        0 fallback, -1 background). voxels: voxel_lighting.VoxelLighting for the rays' far hits
        (None: refined on the mesh SDFs). rcache: radiance_cache.RadianceCache (None: off): rays
        trace ~2 m and take the far field from it, `rc_budget` cache probes traced (new first),
        of them at most `rc_retrace` re-traced. importance: importance-sample the probes' rays
        from last frame's probes (screen_probe_rays; needs res == compute.GROUP, one work group
        per probe; the first frame after a reset traces uniform rays). adaptive: probes at 8x8
        and 4x4 pixel tiles where the uniform ones do not interpolate a pixel
        (screen_probe_adaptive), traced and filtered in the same atlas, in place of most of
        the integrate pass's per-pixel fallback rays. screen: screen_trace.ScreenTrace (None: off),
        Lumen's first trace on the HZB before the SDFs."""
        gw, gh = self.grid
        r = self.res
        tile_j, ray_j = self.jitter(frame)
        g = gbuf["textures"]
        tex = self.textures
        tex["info"] = compute.texture((gw, gh))
        tex["normal"] = compute.texture((gw, gh))
        sh = compute.shader("screen_probe_place", samplers=("gbuf_position", "gbuf_normal"),
                            images=("out_image", "probe_normal_out"),
                            push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('VEC2', 'tile_jitter')))
        sh.uniform_sampler("gbuf_position", g["position"])
        sh.uniform_sampler("gbuf_normal", g["normal"])
        sh.uniform_float("cam_pos", compute.vec(cam_pos))
        sh.uniform_int("probe_tile", self.tile)
        sh.uniform_float("tile_jitter", [float(tile_j[0]), float(tile_j[1])])
        sh.image("out_image", tex["info"])
        sh.image("probe_normal_out", tex["normal"])
        compute.dispatch(sh, gw, gh)
        if adaptive:       # the atlas grows by the 8x8 and 4x4 levels below the uniform probes
            aw, ah = 4 * gw, 7 * gh
            tex["uniform_info"], tex["uniform_normal"] = tex["info"], tex["normal"]
            tex["info"] = compute.texture((aw, ah))
            tex["normal"] = compute.texture((aw, ah))
            sh = compute.shader("screen_probe_adaptive",
                                samplers=("gbuf_position", "gbuf_normal", "probe_uniform",
                                          "probe_uniform_normal"),
                                images=("out_image", "probe_normal_out"),
                                push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'),
                                      ('VEC2', 'tile_jitter'), ('INT', 'uniform_rows')))
            sh.uniform_sampler("gbuf_position", g["position"])
            sh.uniform_sampler("gbuf_normal", g["normal"])
            sh.uniform_sampler("probe_uniform", tex["uniform_info"])
            sh.uniform_sampler("probe_uniform_normal", tex["uniform_normal"])
            sh.uniform_float("cam_pos", compute.vec(cam_pos))
            sh.uniform_int("probe_tile", self.tile)
            sh.uniform_float("tile_jitter", [float(tile_j[0]), float(tile_j[1])])
            sh.uniform_int("uniform_rows", gh)
            sh.image("out_image", tex["info"])
            sh.image("probe_normal_out", tex["normal"])
            compute.dispatch(sh, aw, ah)
        else:
            aw, ah = gw, gh
            tex.pop("uniform_info", None)
            tex.pop("uniform_normal", None)
        if self.prev is not None and self.prev["info"].width != aw:
            self.prev = None               # adaptive probes switched: no prior this frame
        self.atlas = (aw, ah)

        sampled = importance and self.prev is not None and r == compute.GROUP
        if sampled:
            self._plan_rays(gbuf, cam_pos, frame)
        else:
            if self.zero_rays is None or self.zero_rays.width != aw * r \
                    or self.zero_rays.height != ah * r:
                self.zero_rays = compute.texture((aw * r, ah * r), 'R32F')
            tex["rays"] = self.zero_rays
            for k in ("plan", "prior", "traced"):
                tex.pop(k, None)
        self.sampled = sampled

        tex["radiance"] = compute.texture((aw * r, ah * r))
        sh = compute.shader("screen_probe_trace",
                            samplers=("probe_info", "probe_normal", "probe_rays") + VL
                            + screen_trace.SAMPLERS,
                            images=("out_image", ("rc_marks", 'R32F')),
                            push=(screen_trace.PUSH[0], radiance_cache.CAMERA,
                                  ('VEC2', 'ray_jitter'), ('INT', 'probe_res'), ('FLOAT', 't_max'),
                                  ('INT', 'rc_frame'), screen_trace.PUSH[1]))
        resources.bind(sh)
        cache.bind(sh)
        gsdf.bind(sh)
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_normal", tex["normal"])
        sh.uniform_sampler("probe_rays", tex["rays"])
        sky.bind(sh)
        held = voxel_lighting.bind(sh, voxels)  # noqa: F841 (held until the dispatch)
        if screen is not None:
            screen.bind(sh)
        else:
            off = screen_trace.bind_off(sh, gbuf)  # noqa: F841 (held until the dispatch)
        sh.uniform_int("probe_res", r)
        sh.uniform_float("ray_jitter", compute.vec(ray_j, 2))
        sh.uniform_float("t_max", float(t_max))
        if rcache is not None:
            rcache.bind_trace(sh, cam_pos, frame)
        else:
            marks = radiance_cache.bind_off(sh)  # noqa: F841 (held until the dispatch)
        sh.image("out_image", tex["radiance"])
        compute.dispatch(sh, aw * r, ah * r)
        if rcache is not None:    # the far field of the rays that met nothing within ~2 m
            rcache.update(resources, gsdf, cache, sky, voxels, cam_pos, frame, t_max, rc_budget,
                          rc_blend, rc_retrace)
            rcache.resolve(resources, gsdf, cache, sky, voxels, tex, r, ray_j, cam_pos, t_max)
        if sampled:       # the slots -> unbiased texel estimates
            tex["traced"] = tex["radiance"]
            tex["radiance"] = compute.texture((aw * r, ah * r))
            tex["history"] = compute.texture((aw * r, ah * r))
            sh = compute.shader("screen_probe_compose",
                                samplers=("probe_traced", "probe_plan", "probe_prior"),
                                images=("out_image", "probe_history_out"),
                                push=(('INT', 'probe_res'),))
            sh.uniform_sampler("probe_traced", tex["traced"])
            sh.uniform_sampler("probe_plan", tex["plan"])
            sh.uniform_sampler("probe_prior", tex["prior"])
            sh.uniform_int("probe_res", r)
            sh.image("out_image", tex["radiance"])
            sh.image("probe_history_out", tex["history"])
            compute.dispatch(sh, aw * r, ah * r)
        else:
            tex["history"] = tex["radiance"]

        tex["links"] = compute.texture((aw, ah), 'R32F')
        sh = compute.shader("screen_probe_links", samplers=("probe_info", "probe_normal"),
                            images=(("out_image", 'R32F'),), push=(('IVEC2', 'uniform_grid'),))
        sh.uniform_int("uniform_grid", [gw, gh])
        resources.bind(sh)
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_normal", tex["normal"])
        sh.image("out_image", tex["links"])
        compute.dispatch(sh, aw, ah)

        tex["filtered"] = compute.texture((aw * r, ah * r))
        sh = compute.shader("screen_probe_filter",
                            samplers=("probe_info", "probe_normal", "probe_radiance",
                                      "probe_links"),
                            push=(('INT', 'probe_res'), ('VEC2', 'ray_jitter'),
                                  ('IVEC2', 'uniform_grid')))
        sh.uniform_int("uniform_grid", [gw, gh])
        sh.uniform_sampler("probe_links", tex["links"])
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_normal", tex["normal"])
        sh.uniform_sampler("probe_radiance", tex["radiance"])
        sh.uniform_int("probe_res", r)
        sh.uniform_float("ray_jitter", compute.vec(ray_j, 2))
        sh.image("out_image", tex["filtered"])
        compute.dispatch(sh, aw * r, ah * r)
        self.prev = {k: tex[k] for k in ("info", "normal", "history")}   # next frame's prior

        tex["sh"] = compute.texture((aw * 3, ah * 3))
        sh = compute.shader("screen_probe_sh", samplers=("probe_info", "probe_filtered"),
                            push=(('INT', 'probe_res'), ('VEC2', 'ray_jitter')))
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_filtered", tex["filtered"])
        sh.uniform_int("probe_res", r)
        sh.uniform_float("ray_jitter", compute.vec(ray_j, 2))
        sh.image("out_image", tex["sh"])
        compute.dispatch(sh, aw, ah)

        tex["integrated"] = compute.texture((self.width, self.height))
        sh = compute.shader("screen_probe_integrate",
                            samplers=("gbuf_position", "gbuf_normal", "probe_info", "probe_normal",
                                      "probe_sh") + VL + radiance_cache.SAMPLERS,
                            images=("out_image", ("rc_marks", 'R32F')),
                            push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('INT', 'frame'),
                                  ('FLOAT', 't_max'), radiance_cache.CAMERA,
                                  ('INT', 'uniform_rows')))
        resources.bind(sh)
        cache.bind(sh)
        gsdf.bind(sh)
        sky.bind(sh)
        held = voxel_lighting.bind(sh, voxels)  # noqa: F841 (held until the dispatch)
        sh.uniform_int("frame", int(frame))
        sh.uniform_float("t_max", float(t_max))
        sh.uniform_sampler("gbuf_position", g["position"])
        sh.uniform_sampler("gbuf_normal", g["normal"])
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_normal", tex["normal"])
        sh.uniform_sampler("probe_sh", tex["sh"])
        sh.uniform_float("cam_pos", compute.vec(cam_pos))
        sh.uniform_int("probe_tile", self.tile)
        sh.uniform_int("uniform_rows", gh if adaptive else 0)
        rc_held = radiance_cache.bind_lookup(sh, rcache, cam_pos)  # noqa: F841 (dispatch)
        sh.image("out_image", tex["integrated"])
        compute.dispatch(sh, self.width, self.height)
        return tex["integrated"]

    def _plan_rays(self, gbuf: dict, cam_pos, frame: int):
        """screen_probe_rays: tex['rays'] (slot codes), ['plan'], ['prior'] from the G-buffer's
        normals around each probe and last frame's probes (self.prev)."""
        aw, ah = self.atlas
        r = self.res
        g = gbuf["textures"]
        tex = self.textures
        tex["rays"] = compute.texture((aw * r, ah * r), 'R32F')
        tex["plan"] = compute.texture((aw * r, ah * r))
        tex["prior"] = compute.texture((aw * r, ah * r))
        sh = compute.shader("screen_probe_rays",
                            samplers=("gbuf_position", "gbuf_normal", "probe_info", "probe_normal",
                                      "hist_info", "hist_normal", "hist_radiance"),
                            images=(("out_image", 'R32F'), "probe_plan", "probe_prior"),
                            push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('INT', 'probe_res'),
                                  ('INT', 'frame'), ('INT', 'uniform_rows')))
        sh.uniform_sampler("gbuf_position", g["position"])
        sh.uniform_sampler("gbuf_normal", g["normal"])
        sh.uniform_sampler("probe_info", tex["info"])
        sh.uniform_sampler("probe_normal", tex["normal"])
        sh.uniform_sampler("hist_info", self.prev["info"])
        sh.uniform_sampler("hist_normal", self.prev["normal"])
        sh.uniform_sampler("hist_radiance", self.prev["history"])
        sh.uniform_float("cam_pos", compute.vec(cam_pos))
        sh.uniform_int("probe_tile", self.tile)
        sh.uniform_int("probe_res", r)
        sh.uniform_int("frame", int(frame))
        sh.uniform_int("uniform_rows", self.grid[1])
        sh.image("out_image", tex["rays"])
        sh.image("probe_plan", tex["plan"])
        sh.image("probe_prior", tex["prior"])
        compute.run(sh, aw, ah)          # one work group (res x res) per probe

    def temporal(self, new, blend: float):
        """history = mix(history, new, blend) (blend 1 or no history: start again)."""
        if self.history is None or blend >= 1.0:
            self.history, self.frames = new, 1
            return new
        out = compute.texture((self.width, self.height))
        sh = compute.shader("screen_probe_temporal", samplers=("indirect_new", "indirect_history"),
                            push=(('FLOAT', 'blend'),))
        sh.uniform_sampler("indirect_new", new)
        sh.uniform_sampler("indirect_history", self.history)
        sh.uniform_float("blend", float(blend))
        sh.image("out_image", out)
        compute.dispatch(sh, self.width, self.height)
        self.history, self.frames = out, self.frames + 1
        return out

    def stats(self) -> dict:
        """GPU bytes of the probe textures (RGBA32F, the links R32F) and the history."""
        seen, out = set(), {}
        for k, t in self.textures.items():
            if id(t) not in seen:        # 'history' is 'radiance' itself without sampling
                seen.add(id(t))
                out["probes_" + k] = t.width * t.height * (4 if t.format == 'R32F' else 16)
        if self.history is not None:
            out["probes_history"] = self.width * self.height * 16
        return out


def pixel_gather(resources, gsdf, cache, gbuf: dict, cam_pos, sky, frame: int, t_max: float,
                 rays: int, width: int, height: int, voxels=None):
    """Reference gather (glsl/pixel_gather.comp.glsl): `rays` cosine rays per pixel through the
    same tracer, surface cache and voxel lighting as the probes. RGBA32F texture of E."""
    g = gbuf["textures"]
    out = compute.texture((width, height))
    sh = compute.shader("pixel_gather", samplers=("gbuf_position", "gbuf_normal") + VL,
                        push=(('VEC3', 'cam_pos'), ('INT', 'rays'), ('INT', 'frame'),
                              ('FLOAT', 't_max')))
    resources.bind(sh)
    cache.bind(sh)
    gsdf.bind(sh)
    sh.uniform_sampler("gbuf_position", g["position"])
    sh.uniform_sampler("gbuf_normal", g["normal"])
    sh.uniform_float("cam_pos", compute.vec(cam_pos))
    sky.bind(sh)
    held = voxel_lighting.bind(sh, voxels)  # noqa: F841 (held until the dispatch)
    sh.uniform_int("rays", int(rays))
    sh.uniform_int("frame", int(frame))
    sh.uniform_float("t_max", float(t_max))
    sh.image("out_image", out)
    compute.dispatch(sh, width, height)
    return out


def trace_view(resources, gsdf, cache, sky, inv_view_proj, width: int, height: int, t_max: float,
               voxels=None) -> dict:
    """glsl/gi_trace_view.comp.glsl: gi_trace per camera ray (the HYBRID debug view).
    Returns {'hit' (-1 miss), 'global' (bool: the hit came from the global-SDF part), 'voxel'
    (bool: a global hit served by `voxels`, the voxel lighting; None: every global hit is
    refined on the mesh SDFs)}."""
    import mathutils

    out = compute.texture((width, height))
    sh = compute.shader("gi_trace_view", samplers=VL,
                        push=(('MAT4', 'inv_view_proj'), ('FLOAT', 't_max')))
    resources.bind(sh)
    cache.bind(sh)
    gsdf.bind(sh)
    sky.bind(sh)
    held = voxel_lighting.bind(sh, voxels)  # noqa: F841 (held until the dispatch)
    sh.uniform_float("inv_view_proj", mathutils.Matrix(np.asarray(inv_view_proj, np.float64).tolist()))
    sh.uniform_float("t_max", float(t_max))
    sh.image("out_image", out)
    compute.dispatch(sh, width, height)
    data = compute.read(out)
    return {"hit": data[..., 0].copy(), "global": data[..., 1] > 0.5,
            "voxel": (data[..., 0] >= 0) & (data[..., 2] < -0.5)}
