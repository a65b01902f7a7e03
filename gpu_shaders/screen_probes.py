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
                            per probe and placement)
    screen_probe_occlusion  each uniform probe's occlusion map: how far its lifted end sees
                            along its surface, 16 azimuths (once per placement; integrate's
                            wall test)
    screen_probe_filter     3x3 probe spatial filter: plane weights, angle-error rejection,
                            hit-distance clamp, the links
    screen_probe_sh         9 SH coefficients per probe of the hemisphere above its surface
                            (exact texel solid angles; the hemisphere's mean projected exactly
                            over the whole sphere: a constant L gives pi L every frame)
    screen_probe_integrate  per pixel: 4 probes by bilinear x plane-distance weights, those off
                            its plane or a wall hides (their occlusion maps) left out, SH
                            irradiance; where they fail, the adaptive probes
                            of the nearest 8x8 and 4x4 tiles on the pixel's plane; every
                            pixel adds the emitters nearer its surface than a ray starts
                            (sc_near_emission); the pixels still without probes go to a list
    screen_probe_fallback   16 rays per listed pixel, one invocation each (full work groups:
                            traced inside integrate, each group waited on its slowest pixel);
                            at most as many rays in all as the uniform probes trace (fewer per
                            pixel, strata rotating over frames, when the list is long; past 1
                            ray a pixel, the viewport's later rounds trace each 4x4 block of
                            pixels on one turn in 2, 4, ... and keep its history on the others)
    screen_probe_temporal   mix with the history (running mean for F12, exponential in the viewport)
    screen_probe_temporal_split  the viewport with GISettings.split > 1: one pixel of each
                            block integrated per redraw (integrate's px_step, px_phase), its
                            own mix by its own sample count, the others kept or filled
Output: per-pixel indirect irradiance E (W/m^2); the composite divides by pi (Diffuse Indirect).
Needs a GPU context.
"""
from __future__ import annotations

import numpy as np

from . import compute, radiance_cache, screen_trace
from .gi_settings import SEED_FRAMES, GISettings
from .probe_math import hammersley

GBUF = ("gbuf_position", "gbuf_normal")
PROBE_OUT = ("out_image", "probe_normal_out")
PLACE = compute.Pass("screen_probe_place", samplers=GBUF, images=PROBE_OUT,
                     push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('VEC2', 'tile_jitter')))
ADAPTIVE = compute.Pass("screen_probe_adaptive",
                        samplers=GBUF + ("probe_uniform", "probe_uniform_normal"),
                        images=PROBE_OUT,
                        push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('VEC2', 'tile_jitter'),
                              ('INT', 'uniform_rows')))
RAYS = compute.Pass("screen_probe_rays",
                    samplers=GBUF + ("probe_info", "probe_normal", "hist_info", "hist_normal",
                                     "hist_radiance"),
                    images=(("out_image", 'R32F'), "probe_plan", "probe_prior"),
                    push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('INT', 'probe_res'),
                          ('INT', 'frame'), ('INT', 'uniform_rows')))
# the probe rays (screen_probe_trace_lib.glsl), one invocation per ray of a live probe (LIST:
# the atlas's live slots, their count read back): without the screen trace one pass, TRACE; with
# it and hits read from the surface cache (screen_trace.HITS "CACHE") one pass, LUMEN_TRACE (the
# walk, then the SDFs from where it stops vouching); with the screen colour's hits SCREEN_TRACE
# (the walk; its hits listed, the other rays listed), SCREEN_HIT (the hits' light) then
# TRACE_LIST (the others on the SDFs), each over its list's count: full work groups)
LIST = compute.Pass("screen_probe_list", samplers=("probe_info",),
                    images=(("probe_list", 'RGBA32F'), ("probe_counter", 'R32I', {'READ', 'WRITE'}),
                            ("out_image", 'RGBA32F')),
                    push=(('INT', 'probe_res'), ('INT', 'texel_step'), ('IVEC2', 'texel_phase')))
RAY_GROUP = 64
TRACE_SAMPLERS = ("probe_info", "probe_normal", "probe_rays", "probe_list")
TRACE_IMAGES = (("out_image", 'RGBA32F', {'READ', 'WRITE'}), ("rc_marks", 'R32F'))
TRACE_PUSH = (radiance_cache.CAMERA, ('VEC2', 'ray_jitter'), ('INT', 'probe_res'),
              ('FLOAT', 't_max'), ('INT', 'rc_frame'), ('INT', 'texel_step'),
              ('IVEC2', 'texel_phase'), ('INT', 'texel_fill'), ('INT', 'probe_count'))
TRACE = compute.Pass("screen_probe_trace", samplers=TRACE_SAMPLERS, images=TRACE_IMAGES,
                     push=TRACE_PUSH, group=(RAY_GROUP, 1, 1))
SCREEN_PUSH = screen_trace.PUSH[:1] + TRACE_PUSH + screen_trace.PUSH[1:]
SCREEN_TRACE = compute.Pass("screen_probe_screen_trace",
                            samplers=TRACE_SAMPLERS + screen_trace.SAMPLERS,
                            images=TRACE_IMAGES + (("hit_list", 'RGBA32F', {'WRITE'}),
                                                   ("hit_counter", 'R32I', {'READ', 'WRITE'}),
                                                   ("ray_list", 'RGBA32F', {'WRITE'}),
                                                   ("ray_counter", 'R32I', {'READ', 'WRITE'})),
                            push=SCREEN_PUSH, group=(RAY_GROUP, 1, 1))
SCREEN_HIT = compute.Pass("screen_probe_screen_hit",
                          samplers=TRACE_SAMPLERS + screen_trace.SAMPLERS,
                          images=TRACE_IMAGES + (("hit_list", 'RGBA32F', {'READ'}),
                                                 ("hit_counter", 'R32I', {'READ'})),
                          push=SCREEN_PUSH, group=(RAY_GROUP, 1, 1))
LUMEN_TRACE = compute.Pass("screen_probe_lumen_trace",
                           samplers=TRACE_SAMPLERS + screen_trace.SAMPLERS, images=TRACE_IMAGES,
                           push=SCREEN_PUSH, group=(RAY_GROUP, 1, 1))
TRACE_LIST = compute.Pass("screen_probe_trace_list", samplers=TRACE_SAMPLERS,
                          images=TRACE_IMAGES + (("ray_list", 'RGBA32F', {'READ'}),
                                                 ("ray_counter", 'R32I', {'READ'})),
                          push=TRACE_PUSH, group=(RAY_GROUP, 1, 1))
COMPOSE = compute.Pass("screen_probe_compose",
                       samplers=("probe_traced", "probe_plan", "probe_prior"),
                       images=("out_image", "probe_history_out"), push=(('INT', 'probe_res'),))
LINKS = compute.Pass("screen_probe_links", samplers=("probe_info", "probe_normal"),
                     images=(("out_image", 'R32F'),), push=(('IVEC2', 'uniform_grid'),))
OCCLUSION = compute.Pass("screen_probe_occlusion", samplers=("probe_info", "probe_normal"),
                         push=(('IVEC2', 'uniform_grid'),))
OCC_TEXELS = 5             # probe_occlusion_lib.glsl's PROBE_OCC_TEXELS
FILTER = compute.Pass("screen_probe_filter",
                      samplers=("probe_info", "probe_normal", "probe_radiance", "probe_links"),
                      push=(('INT', 'probe_res'), ('VEC2', 'ray_jitter'),
                            ('IVEC2', 'uniform_grid')))
SH = compute.Pass("screen_probe_sh", samplers=("probe_info", "probe_normal", "probe_filtered"),
                  push=(('INT', 'probe_res'), ('VEC2', 'ray_jitter')))
INTEGRATE = compute.Pass("screen_probe_integrate",
                         samplers=GBUF + ("gbuf_albedo", "gbuf_emission", "probe_info",
                                          "probe_normal", "probe_sh", "probe_occ"),
                         images=("out_image", "fb_list", ("fb_counter", 'R32I', {'READ', 'WRITE'})),
                         push=(('VEC3', 'cam_pos'), ('INT', 'probe_tile'), ('INT', 'uniform_rows'),
                               ('IVEC2', 'px_phase'), ('INT', 'px_step'), ('INT', 'fb_turn'),
                               ('INT', 'fb_skip'), ('INT', 'shading_normals')))
FALLBACK_GROUP = 64
FALLBACK_BUDGET = 1.0      # the fallback's rays per frame, in the uniform probes' ray count
FALLBACK_SKIP_MAX = 16     # screen_probe_fallback.comp.glsl's: a pixel traces at least 1 turn in 16
VIEWPORT_FALLBACK_BUDGET = 0.5  # the viewport's (gather's fallback_budget): among 1,000 small
                                # objects 131 of a 397 ms still frame at 1.0 at 128 px; its
                                # strata then turn over twice the redraws
FALLBACK = compute.Pass("screen_probe_fallback",
                        samplers=GBUF + radiance_cache.SAMPLERS,
                        images=(("out_image", 'RGBA32F', {'READ', 'WRITE'}),
                                ("fb_list", 'RGBA32F', {'READ'}), ("fb_counter", 'R32I', {'READ'}),
                                ("rc_marks", 'R32F')),
                        push=(('VEC3', 'cam_pos'), ('INT', 'frame'), ('FLOAT', 't_max'),
                              radiance_cache.CAMERA, ('INT', 'fb_budget'), ('INT', 'fb_turn'),
                              ('INT', 'fb_round')),
                        group=(FALLBACK_GROUP, 1, 1))
TEMPORAL = compute.Pass("screen_probe_temporal", samplers=("indirect_new", "indirect_history"),
                        push=(('FLOAT', 'blend'),))
TEMPORAL_SPLIT = compute.Pass("screen_probe_temporal_split",
                              samplers=("indirect_new", "indirect_history") + GBUF,
                              push=(('VEC3', 'cam_pos'), ('INT', 'px_step'),
                                    ('IVEC2', 'px_phase'), ('INT', 'frame'),
                                    ('FLOAT', 'history_len')))
PIXEL_GATHER = compute.Pass("pixel_gather", samplers=GBUF,
                            push=(('VEC3', 'cam_pos'), ('INT', 'rays'), ('INT', 'frame'),
                                  ('FLOAT', 't_max')))
TRACE_VIEW = compute.Pass("gi_trace_view", push=(('MAT4', 'inv_view_proj'), ('FLOAT', 't_max')))


R2 = (0.7548776662466927, 0.5698402909980532)  # the R2 sequence's step (1/phi2, 1/phi2^2)


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
        self.split_radiance = None   # the split viewport's probe texels, kept across redraws
        self.split_links = None      # and its probes' links, kept for their placement
        self.split_occ = None        # and their occlusion maps
        self.fb_estimate = 0         # the last redraw's fallback pixels, skipped ones counted

    def jitter(self, frame: int):
        """(tile pixel offset, ray jitter in [0,1)^2) of a frame: 16-point Hammersley sets, shifted
        (Cranley-Patterson, an R2 step) by the F12 Seed (frame // SEED_FRAMES): the sets repeat
        every 16 frames and SEED_FRAMES is a multiple of 16, so without the shift every Seed
        placed and traced the same screen probes (only the surface cache's rays changed; the
        screen trace's A/B over three seeds in bench/quality.py was one sample three times).
        Seed 0 (and the viewport's first SEED_FRAMES redraws) is unshifted."""
        h = hammersley(16)
        shift = np.mod((frame // SEED_FRAMES) * np.array(R2), 1.0)
        tile = np.mod(h[frame % 16] + shift[::-1], 1.0)
        tile = np.minimum((tile * self.tile).astype(int), self.tile - 1)
        ray = np.mod(h[(frame * 7 + 5) % 16] + 0.5 / 16.0 + shift, 1.0)
        return tile, ray

    def gather(self, resources, gsdf, cache, gbuf: dict, cam_pos, sky, frame: int, t_max: float,
               voxels=None, rcache=None, rc_budget: int = 0, rc_blend: float = 0.25,
               rc_retrace=None, importance: bool = True, adaptive: bool = True,
               screen=None, split: int = 1, split_frame: int = 0,
               fallback_budget: float | None = None):
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
        Lumen's first trace on the HZB before the SDFs. split (1, 4 or 16; the viewport's
        GISettings.split): integrate only one pixel of every sqrt(split)^2 block, the one whose
        turn it is at redraw `split_frame` since the history's reset (temporal_split fills the
        rest), and trace one texel of every such block of the probes' octahedral maps, the
        others kept from earlier redraws (placement held for `split` redraws).
        fallback_budget: the fallback's rays at most, in the uniform probes' ray count of this
        redraw (screen_probe_fallback.comp.glsl; None: FALLBACK_BUDGET)."""
        gw, gh = self.grid
        r = self.res
        step = GISettings(split=split).split_step
        if r % step:
            raise ValueError(f"probe resolution {r} is not a multiple of the split's {step}")
        # the split: placement and ray jitter held for `split` redraws (one per texel turn)
        tile_j, ray_j = self.jitter(frame - split_frame + split_frame // split)
        g = gbuf["textures"]
        tex = self.textures
        tex["info"] = compute.texture((gw, gh))
        tex["normal"] = compute.texture((gw, gh))
        cam = compute.vec(cam_pos)
        gpos, gnor = g["position"], g["normal"]
        PLACE.run((gw, gh), gbuf_position=gpos, gbuf_normal=gnor, cam_pos=cam,
                  probe_tile=self.tile, tile_jitter=tile_j, out_image=tex["info"],
                  probe_normal_out=tex["normal"])
        if adaptive:       # the atlas grows by the 8x8 and 4x4 levels below the uniform probes
            aw, ah = 4 * gw, 7 * gh
            tex["uniform_info"], tex["uniform_normal"] = tex["info"], tex["normal"]
            tex["info"] = compute.texture((aw, ah))
            tex["normal"] = compute.texture((aw, ah))
            ADAPTIVE.run((aw, ah), gbuf_position=gpos, gbuf_normal=gnor,
                         probe_uniform=tex["uniform_info"],
                         probe_uniform_normal=tex["uniform_normal"], cam_pos=cam,
                         probe_tile=self.tile, tile_jitter=tile_j, uniform_rows=gh,
                         out_image=tex["info"], probe_normal_out=tex["normal"])
        else:
            aw, ah = gw, gh
            tex.pop("uniform_info", None)
            tex.pop("uniform_normal", None)
        if self.prev is not None and self.prev["info"].width != aw:
            self.prev = None               # adaptive probes switched: no prior this frame
        self.atlas = (aw, ah)

        sampled = importance and self.prev is not None and r == compute.GROUP and step == 1
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

        fill = step > 1 and (split_frame == 0 or self.split_radiance is None
                             or self.split_radiance.width != aw * r
                             or self.split_radiance.height != ah * r)
        if step == 1:
            tex["radiance"] = compute.texture((aw * r, ah * r))
        else:          # kept across redraws: each traces one texel of every 2x2 block
            if fill:
                self.split_radiance = compute.texture((aw * r, ah * r))
            tex["radiance"] = self.split_radiance
        tracers = dict(scene=resources, cache=cache, gsdf=gsdf, sky=sky, voxels=voxels)
        phase = split_phase_pixel(split_frame % split, step)
        if "probe_list" not in tex or (tex["probe_list"].width, tex["probe_list"].height) != (aw, ah):
            tex["probe_list"] = compute.texture((aw, ah))
            tex["probe_counter"] = compute.texture((1, 1), 'R32I')
        tex["probe_counter"].clear(format='INT', value=(0,))
        LIST.run((aw, ah), probe_info=tex["info"], probe_res=r, texel_step=step,
                 texel_phase=phase, probe_list=tex["probe_list"],
                 probe_counter=tex["probe_counter"], out_image=tex["radiance"])
        live = compute.read_counter(tex["probe_counter"])     # the dispatch's size: a sync
        rays_per = (r // step) ** 2
        rays = dict(tracers, probe_info=tex["info"], probe_normal=tex["normal"],
                    probe_rays=tex["rays"], probe_list=tex["probe_list"], probe_count=live,
                    texel_step=step, texel_phase=phase, texel_fill=int(fill), probe_res=r,
                    ray_jitter=ray_j, t_max=float(t_max), out_image=tex["radiance"],
                    **(rcache.trace_inputs(cam_pos, frame) if rcache is not None
                       else radiance_cache.trace_off()))
        screen_on = screen is not None and screen.inputs()["screen_steps"] > 0
        if live and not screen_on:
            TRACE.run(live * rays_per, **rays)
        elif live and not screen.needs_colour:
            LUMEN_TRACE.run(live * rays_per, **rays, **screen.inputs())
        elif live:
            if "ray_list" not in tex or tex["ray_list"].width * tex["ray_list"].height \
                    < live * rays_per:
                tex["ray_list"] = compute.texture((r * aw // step, r * ah // step))
                tex["hit_list"] = compute.texture((2 * r * aw // step, r * ah // step))
                tex["ray_counter"] = compute.texture((1, 1), 'R32I')
                tex["hit_counter"] = compute.texture((1, 1), 'R32I')
            lists = {k: tex[k] for k in ("ray_list", "ray_counter", "hit_list", "hit_counter")}
            tex["ray_counter"].clear(format='INT', value=(0,))
            tex["hit_counter"].clear(format='INT', value=(0,))
            SCREEN_TRACE.run(live * rays_per, **rays, **screen.inputs(), **lists)
            hits = compute.read_counter(tex["hit_counter"])
            if hits:
                SCREEN_HIT.run(hits, **rays, **screen.inputs(), hit_list=tex["hit_list"],
                               hit_counter=tex["hit_counter"])
            listed = compute.read_counter(tex["ray_counter"])
            if listed:
                TRACE_LIST.run(listed, **rays, ray_list=tex["ray_list"],
                               ray_counter=tex["ray_counter"])
        if rcache is not None:    # the far field of the rays that met nothing within ~2 m
            rcache.update(resources, gsdf, cache, sky, voxels, cam_pos, frame, t_max, rc_budget,
                          rc_blend, rc_retrace)
            rcache.resolve(resources, gsdf, cache, sky, voxels, tex, r, ray_j, cam_pos, t_max)
        if sampled:       # the slots -> unbiased texel estimates
            tex["traced"] = tex["radiance"]
            tex["radiance"] = compute.texture((aw * r, ah * r))
            tex["history"] = compute.texture((aw * r, ah * r))
            COMPOSE.run((aw * r, ah * r), probe_traced=tex["traced"], probe_plan=tex["plan"],
                        probe_prior=tex["prior"], probe_res=r, out_image=tex["radiance"],
                        probe_history_out=tex["history"])
        else:
            tex["history"] = tex["radiance"]

        # which neighbours each probe sees: once per placement (the split holds the probes for
        # `split` redraws, and anything that moves them resets the split's count)
        kept = self.split_links
        if step == 1 or split_frame % split == 0 or kept is None or kept.width != aw \
                or kept.height != ah:
            tex["links"] = compute.texture((aw, ah), 'R32F')
            LINKS.run((aw, ah), scene=resources, uniform_grid=(gw, gh), probe_info=tex["info"],
                      probe_normal=tex["normal"], out_image=tex["links"])
            tex["occ"] = compute.texture((aw * OCC_TEXELS, ah))
            OCCLUSION.run((aw * OCC_TEXELS, ah), scene=resources, uniform_grid=(gw, gh),
                          probe_info=tex["info"], probe_normal=tex["normal"],
                          out_image=tex["occ"])
            self.split_links = tex["links"] if step > 1 else None
            self.split_occ = tex["occ"] if step > 1 else None
        else:
            tex["links"], tex["occ"] = kept, self.split_occ

        tex["filtered"] = compute.texture((aw * r, ah * r))
        FILTER.run((aw * r, ah * r), uniform_grid=(gw, gh), probe_links=tex["links"],
                   probe_info=tex["info"], probe_normal=tex["normal"],
                   probe_radiance=tex["radiance"], probe_res=r, ray_jitter=ray_j,
                   out_image=tex["filtered"])
        self.prev = {k: tex[k] for k in ("info", "normal", "history")}   # next frame's prior

        tex["sh"] = compute.texture((aw * 3, ah * 3))
        SH.run((aw, ah), probe_info=tex["info"], probe_normal=tex["normal"],
               probe_filtered=tex["filtered"], probe_res=r, ray_jitter=ray_j, out_image=tex["sh"])

        tex["integrated"] = compute.texture((self.width, self.height))
        lw, lh = -(-self.width // step), -(-self.height // step)    # integrated pixels
        if "fb_list" not in tex or (tex["fb_list"].width, tex["fb_list"].height) != (lw, lh):
            tex["fb_list"] = compute.texture((lw, lh))
            tex["fb_counter"] = compute.texture((1, 1), 'R32I')
        tex["fb_counter"].clear(format='INT', value=(0,))
        fb_budget = int((FALLBACK_BUDGET if fallback_budget is None else fallback_budget)
                        * gw * gh * r * r) // (step * step)
        fb_turn = int(frame) // split              # a pixel's turns (the split's)
        # its rounds since the history's reset: from the second, a pixel over the budget may
        # skip a turn (temporal_split keeps its history); F12 -1
        fb_round = int(split_frame) // split if split > 1 else -1
        # the skip, from the last redraw's list (the fallback's own rule), applied in integrate:
        # a pixel off its turn is not listed, so the fallback's groups hold only pixels that
        # trace (skipped in the fallback, a group of 64 list slots spanning a few 4x4 blocks
        # still waited on its one tracing block)
        fb_skip = 1
        while (fb_round >= 1 and fb_skip < FALLBACK_SKIP_MAX
               and self.fb_estimate > fb_budget * fb_skip):
            fb_skip *= 2
        INTEGRATE.run((lw, lh), scene=resources, cache=cache,
                      px_step=step, px_phase=split_phase_pixel(split_frame % split, step),
                      gbuf_position=gpos, gbuf_normal=gnor, gbuf_albedo=g["albedo"],
                      gbuf_emission=g["emission"], probe_info=tex["info"],
                      probe_normal=tex["normal"], probe_sh=tex["sh"], probe_occ=tex["occ"],
                      cam_pos=cam,
                      probe_tile=self.tile, uniform_rows=gh if adaptive else 0,
                      out_image=tex["integrated"], fb_list=tex["fb_list"],
                      fb_counter=tex["fb_counter"], fb_turn=fb_turn, fb_skip=fb_skip,
                      shading_normals=int(bool(gbuf.get("shading_normals"))))
        # the pixels integrate listed: their own rays, in full work groups, and only theirs
        # (their count read back: llvmpipe runs an invocation of a tracing shader that returns
        # at once nearly as slowly as one that traces, screen_probe_list.comp.glsl)
        # its budget: the uniform probes' rays of this redraw (a list of thousands of pixels
        # among many small objects cost 4x a whole viewport frame at 16 rays each)
        listed = compute.read_counter(tex["fb_counter"])
        self.fb_estimate = listed * fb_skip       # about the pixels it would have listed
        if not listed:
            return tex["integrated"]
        FALLBACK.run(listed, **tracers, frame=int(frame), t_max=float(t_max),
                     fb_budget=fb_budget, fb_turn=fb_turn, fb_round=fb_round,
                     gbuf_position=gpos, gbuf_normal=gnor, cam_pos=cam,
                     out_image=tex["integrated"], fb_list=tex["fb_list"],
                     fb_counter=tex["fb_counter"],
                     **radiance_cache.lookup_inputs(rcache, cam_pos))
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
        RAYS.run_groups((aw, ah),        # one work group (res x res) per probe
                        gbuf_position=g["position"], gbuf_normal=g["normal"],
                        probe_info=tex["info"], probe_normal=tex["normal"],
                        hist_info=self.prev["info"], hist_normal=self.prev["normal"],
                        hist_radiance=self.prev["history"], cam_pos=compute.vec(cam_pos),
                        probe_tile=self.tile, probe_res=r, frame=int(frame),
                        uniform_rows=self.grid[1], out_image=tex["rays"],
                        probe_plan=tex["plan"], probe_prior=tex["prior"])

    def temporal(self, new, blend: float):
        """history = mix(history, new, blend) (blend 1 or no history: start again)."""
        if self.history is None or blend >= 1.0:
            self.history, self.frames = new, 1
            return new
        out = compute.texture((self.width, self.height))
        TEMPORAL.run((self.width, self.height), indirect_new=new, indirect_history=self.history,
                     blend=float(blend), out_image=out)
        self.history, self.frames = out, self.frames + 1
        return out

    def temporal_split(self, new, gbuf: dict, cam_pos, split: int, history_len: float):
        """The viewport's history when each redraw integrates 1 / split of the pixels
        (screen_probe_temporal_split.comp.glsl): per pixel, its own running-then-exponential
        mean over its own turns; a pixel not yet integrated since the reset is filled from
        this redraw's integrated neighbours. self.frames counts redraws since the reset."""
        frame = self.frames if self.history is not None else 0
        step = GISettings(split=split).split_step
        out = compute.texture((self.width, self.height))
        g = gbuf["textures"]
        TEMPORAL_SPLIT.run((self.width, self.height), indirect_new=new,
                           indirect_history=self.history if frame else new,
                           gbuf_position=g["position"], gbuf_normal=g["normal"],
                           cam_pos=compute.vec(cam_pos), px_step=step,
                           px_phase=split_phase_pixel(frame % split, step), frame=int(frame),
                           history_len=float(history_len), out_image=out)
        self.history, self.frames = out, frame + 1
        return out

    def stats(self) -> dict:
        """GPU bytes of the probe textures (RGBA32F; the links R32F, the fallback counter R32I)
        and the history."""
        seen, out = set(), {}
        for k, t in self.textures.items():
            if id(t) not in seen:        # 'history' is 'radiance' itself without sampling
                seen.add(id(t))
                out["probes_" + k] = t.width * t.height * (4 if t.format in ('R32F', 'R32I') else 16)
        if self.history is not None:
            out["probes_history"] = self.width * self.height * 16
        return out


def split_phase(x, y, step: int):
    """The redraw (mod step^2) on which block pixel (x, y) is integrated: Bayer order (0 3 / 2 1
    for a 2x2 block), the twin of screen_probe_temporal_split.comp.glsl's split_phase."""
    x, y = np.asarray(x), np.asarray(y)
    b = 2 * ((x & 1) ^ (y & 1)) + (y & 1)
    if step <= 2:
        return b
    return 4 * b + 2 * (((x >> 1) & 1) ^ ((y >> 1) & 1)) + ((y >> 1) & 1)


def split_phase_pixel(phase: int, step: int):
    """The block pixel (x, y) integrated on a redraw of the given phase."""
    ys, xs = np.mgrid[0:step, 0:step]
    k = np.flatnonzero(split_phase(xs, ys, step).ravel() == phase)[0]
    return int(xs.ravel()[k]), int(ys.ravel()[k])


def pixel_gather(resources, gsdf, cache, gbuf: dict, cam_pos, sky, frame: int, t_max: float,
                 rays: int, width: int, height: int, voxels=None):
    """Reference gather (glsl/pixel_gather.comp.glsl): `rays` cosine rays per pixel through the
    same tracer, surface cache and voxel lighting as the probes. RGBA32F texture of E."""
    g = gbuf["textures"]
    out = compute.texture((width, height))
    PIXEL_GATHER.run((width, height), scene=resources, cache=cache, gsdf=gsdf, sky=sky,
                     voxels=voxels, gbuf_position=g["position"], gbuf_normal=g["normal"],
                     cam_pos=compute.vec(cam_pos), rays=int(rays), frame=int(frame),
                     t_max=float(t_max), out_image=out)
    return out


def trace_view(resources, gsdf, cache, sky, inv_view_proj, width: int, height: int, t_max: float,
               voxels=None) -> dict:
    """glsl/gi_trace_view.comp.glsl: gi_trace per camera ray (the HYBRID debug view).
    Returns {'hit' (-1 miss), 'global' (bool: the hit came from the global-SDF part), 'voxel'
    (bool: a global hit served by `voxels`, the voxel lighting; None: every global hit is
    refined on the mesh SDFs)}."""
    out = compute.texture((width, height))
    TRACE_VIEW.run((width, height), scene=resources, cache=cache, gsdf=gsdf, sky=sky,
                   voxels=voxels, inv_view_proj=inv_view_proj, t_max=float(t_max),
                   out_image=out)
    data = compute.read(out)
    return {"hit": data[..., 0].copy(), "global": data[..., 1] > 0.5,
            "voxel": (data[..., 0] >= 0) & (data[..., 2] < -0.5)}
