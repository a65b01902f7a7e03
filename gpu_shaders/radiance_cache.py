"""World radiance cache (lecture 21, "World Space Radiance Cache"): the far field of the screen
probes' rays from world-space probes that persist across frames, so that a screen-probe ray
traces only about 2 m (mesh SDFs only) and a still camera re-traces little.

Layout (glsl/radiance_cache_layout_lib.glsl): LEVELS = 4 clipmaps of N^3 = 32^3 cells around the
camera, level-0 spacing s0 = `GISettings.rc_spacing` (0.577 m: the screen rays' 2 m is
2 sqrt(3) s0, see below; level k: s0 2^k, so level 0 spans 18.5 m and level 3 148 m), one
possible probe per cell centre; an indirection (cells: cell -> slot + 1) into `capacity` probe
slots (2048) of RES x RES = 8 x 8 octahedral texels (RGBA32F atlas: the hits' radiance, nearest
hit; R32F: the share of rays that left the scene, whose sky the lookup reads in the screen ray's
own direction).
Against the lecture's 4 x 48^3 at ~1 m and 32 x 32 texels: fewer cells per level (a 32^3 level
costs a quarter of the per-cell allocation pass of 48^3, and our scenes are rooms, not 50 m
levels) and 8 x 8 texels, the screen probes' own resolution: a screen probe reduces what it
gathers to 9 SH coefficients, and 1024 rays per probe are not affordable on llvmpipe; a texel
takes one jittered ray per trace and blends re-traces (F12: a running mean over the gathered
frames; viewport: exponential, 0.25).

Per frame (screen_probes.gather, between its trace and filter passes):
    screen_probe_trace       rays trace rc_trace_distance = 2 sqrt(3) s_k (the interpolation
                             footprint + the distance the world probes skip, as the lecture has
                             it); a ray without a hit is flagged and marks the 8 cells around its
                             origin (only where screen probes need probes)
    radiance_cache_free      per slot: probes unused for `keep` frames, outside their clipmap or
                             (scene change) all are freed; every free slot is listed
    radiance_cache_alloc     per cell: a marked cell without a probe takes a free slot
    radiance_cache_select    the trace list under the budget: new probes first, then at most
                             `retrace` traced ones in a round-robin window (the least
                             recently traced; the lecture's re-trace of a subset)
    radiance_cache_trace     per listed probe and texel: full-length rays from the probe centre
                             through gi_trace_lib (global SDF / voxel lighting / sky)
    radiance_cache_resolve   per flagged screen-probe texel: rc_lookup (8 probes, trilinear,
                             sphere parallax, visibility: a probe whose rays meet a surface before
                             the parallax point X is left out, so a probe behind a thin wall or in
                             a solid brings no light); none left: the ray traces on to t_max
    screen_probe_integrate   the pixels no screen probe serves gather 16 rays themselves: the same
                             short trace + cache (rc_radiance), marking cells for the next frame
The counts live on the GPU (R32I counters, atomics): nothing is read back in the frame loop;
`traced_count()` / `read()` are for tests. Needs a GPU context.
"""
from __future__ import annotations

import numpy as np

from . import compute

LEVELS, N, RES, SLOT_W = 4, 32, 8, 64          # radiance_cache_layout_lib.glsl's RC_*
RADIUS = 3.0 ** 0.5                              # RC_RADIUS, in spacings
SAMPLERS = ("rc_cells", "rc_slots", "rc_state", "rc_atlas", "rc_miss")
CAMERA = ('VEC4', 'rc_camera')
RW = {'READ', 'WRITE'}
FREE = compute.Pass("radiance_cache_free", samplers=("rc_marks",),
                    images=(("rc_slots_io", 'RGBA32F', RW), ("rc_cells_io", 'R32F', RW),
                            ("rc_free_out", 'R32F'), ("rc_counter", 'R32I', RW)),
                    push=(CAMERA, ('INT', 'rc_frame'), ('INT', 'rc_keep'), ('INT', 'rc_reset')))
ALLOC = compute.Pass("radiance_cache_alloc", samplers=("rc_marks", "rc_free"),
                     images=(("rc_cells_io", 'R32F', RW), ("rc_slots_io", 'RGBA32F', RW),
                             ("rc_state_io", 'RGBA32F', RW), ("rc_counter", 'R32I', RW)),
                     push=(CAMERA, ('INT', 'rc_frame')))
SELECT = compute.Pass("radiance_cache_select", samplers=("rc_slots", "rc_state"),
                      images=(("rc_list_out", 'RGBA32F'), ("rc_counter", 'R32I', RW)),
                      push=(('INT', 'rc_phase'), ('INT', 'rc_cap'), ('INT', 'rc_cursor'),
                            ('INT', 'rc_window'), CAMERA))   # (the layout lib names rc_camera)
TRACE = compute.Pass("radiance_cache_trace", samplers=("rc_list", "rc_slots"),
                     images=(("rc_atlas_io", 'RGBA32F', RW), ("rc_state_io", 'RGBA32F', RW),
                             ("rc_miss_io", 'R32F', RW)),
                     push=(CAMERA, ('INT', 'rc_frame'), ('VEC2', 'rc_jitter'), ('FLOAT', 't_max'),
                           ('FLOAT', 'rc_blend')))
RESOLVE = compute.Pass("radiance_cache_resolve",
                       samplers=("probe_info", "probe_normal", "probe_rays") + SAMPLERS,
                       images=(("probe_radiance_io", 'RGBA32F', RW),),
                       push=(CAMERA, ('INT', 'probe_res'), ('VEC2', 'ray_jitter'),
                             ('FLOAT', 't_max')))
VIEW = compute.Pass("radiance_cache_view", samplers=("gbuf_position", "gbuf_normal") + SAMPLERS,
                    push=(('VEC3', 'cam_pos'), CAMERA))


def trace_distance(spacing: float, level: int = 0) -> float:
    """How far a screen-probe ray whose origin is in `level` traces before the cache (metres)."""
    return 2.0 * RADIUS * spacing * 2 ** level


class RadianceCache:
    """The cache's textures and its per-frame update (see the module docstring)."""

    def __init__(self, spacing: float = 0.577, capacity: int = 2048, keep: int = 8):
        self.spacing, self.keep = float(spacing), int(keep)
        self.capacity = -(-int(capacity) // SLOT_W) * SLOT_W
        rows = self.capacity // SLOT_W
        self.cells = compute.texture((N * N, N * LEVELS), 'R32F')
        self.marks = compute.texture((N * N, N * LEVELS), 'R32F')
        self.slots = compute.texture((SLOT_W, rows))
        self.state = compute.texture((SLOT_W, rows))
        self.free = compute.texture((SLOT_W, rows), 'R32F')
        self.list = compute.texture((SLOT_W, rows))
        self.counter = compute.texture((4, 1), 'R32I')
        self.atlas = compute.texture((SLOT_W * RES, rows * RES))
        self.miss = compute.texture((SLOT_W * RES, rows * RES), 'R32F')   # sky share per texel
        self.cursor = 0
        self.reset = True          # free every probe on the next update (scene changed)
        self.camera = None         # rc_camera of the last update
        self.last = {}             # what the last update dispatched (budget, frame)

    def camera_vec(self, cam_pos) -> list:
        return compute.vec(cam_pos) + [self.spacing]

    def trace_inputs(self, cam_pos, frame: int) -> dict:
        """screen_probe_trace's rc_* inputs (cache on)."""
        return dict(rc_camera=self.camera_vec(cam_pos), rc_frame=int(frame), rc_marks=self.marks)

    def update(self, resources, gsdf, cache, sky, voxels, cam_pos, frame: int, t_max: float,
               budget: int, blend: float = 0.25, retrace: int | None = None):
        """Free, allocate, select and trace this frame's probes (after screen_probe_trace marked
        the cells): at most `budget` probes traced, new ones first, then at most `retrace`
        (default: budget) traced ones, the least recently traced; a re-traced probe's texels
        become mix(old, new, blend)."""
        cam = self.camera_vec(cam_pos)
        frame = int(frame)
        budget = max(0, min(int(budget), self.capacity))
        window = budget if retrace is None else max(0, min(int(retrace), budget))
        rows = self.capacity // SLOT_W
        self.counter.clear(format='INT', value=(0,))
        self.list.clear(format='FLOAT', value=(-1.0, 0.0, 0.0, 0.0))

        FREE.run((SLOT_W, rows), rc_marks=self.marks, rc_camera=cam, rc_frame=frame,
                 rc_keep=self.keep, rc_reset=int(self.reset), rc_slots_io=self.slots,
                 rc_cells_io=self.cells, rc_free_out=self.free, rc_counter=self.counter)
        self.reset = False

        ALLOC.run((N * N, N * LEVELS), rc_marks=self.marks, rc_free=self.free, rc_camera=cam,
                  rc_frame=frame, rc_cells_io=self.cells, rc_slots_io=self.slots,
                  rc_state_io=self.state, rc_counter=self.counter)

        for phase in (0, 1):
            SELECT.run((SLOT_W, rows), rc_slots=self.slots, rc_state=self.state, rc_phase=phase,
                       rc_cap=budget, rc_cursor=self.cursor, rc_window=window, rc_camera=cam,
                       rc_list_out=self.list, rc_counter=self.counter)
        self.cursor = (self.cursor + window) % self.capacity

        if budget:
            rng = np.random.default_rng(frame)        # the same rotation every F12 render
            TRACE.run((SLOT_W * RES, -(-budget // SLOT_W) * RES), scene=resources, cache=cache,
                      gsdf=gsdf, sky=sky, voxels=voxels, rc_list=self.list, rc_slots=self.slots,
                      rc_camera=cam, rc_frame=frame, rc_jitter=rng.random(2),
                      t_max=float(t_max), rc_blend=float(blend), rc_atlas_io=self.atlas,
                      rc_state_io=self.state, rc_miss_io=self.miss)
        self.camera = cam
        self.last = dict(budget=budget, frame=frame)

    def lookup(self) -> dict:
        """radiance_cache_lib.glsl's samplers (compute.Pass keywords)."""
        return dict(zip(SAMPLERS, (self.cells, self.slots, self.state, self.atlas, self.miss)))

    def resolve(self, resources, gsdf, cache, sky, voxels, probe_tex: dict, probe_res: int,
                ray_jitter, cam_pos, t_max: float):
        """radiance_cache_resolve on the screen probes' radiance texture (ray slots, their directions
        in probe_tex["rays"]), in place."""
        r = probe_tex["radiance"]
        RESOLVE.run((r.width, r.height), scene=resources, cache=cache, gsdf=gsdf, sky=sky,
                    voxels=voxels, **self.lookup(), probe_info=probe_tex["info"],
                    probe_rays=probe_tex["rays"], probe_normal=probe_tex["normal"],
                    rc_camera=self.camera_vec(cam_pos), probe_res=int(probe_res),
                    ray_jitter=compute.vec(ray_jitter, 2), t_max=float(t_max),
                    probe_radiance_io=r)

    # --- tests and debug views (read-backs) ----------------------------------------------------
    def traced_count(self) -> int:
        """Probes the last update traced (list entries)."""
        return int((compute.read(self.list)[..., 0] >= 0).sum())

    def read(self) -> dict:
        """{'slots': [capacity, 4] (world cell xyz, level + 1; 0 free), 'state' [capacity, 4]
        (x: frame + 1 of the last trace), 'atlas' [capacity, RES, RES, 4] (texel [y, x]),
        'miss' [capacity, RES, RES] (share of the texel's rays that left the scene),
        'cells' [LEVELS, N, N, N] (slot + 1 per texel, [level, z, y, x])}."""
        rows = self.capacity // SLOT_W
        atlas = compute.read(self.atlas).reshape(rows, RES, SLOT_W, RES, 4)
        return {"slots": compute.read(self.slots).reshape(-1, 4),
                "state": compute.read(self.state).reshape(-1, 4),
                "atlas": atlas.transpose(0, 2, 1, 3, 4).reshape(-1, RES, RES, 4),
                "miss": compute.read(self.miss)[..., 0].reshape(rows, RES, SLOT_W, RES)
                .transpose(0, 2, 1, 3).reshape(-1, RES, RES),
                "cells": compute.read(self.cells)[..., 0].reshape(LEVELS, N, N, N)}

    def view(self, gbuf: dict, sky, cam_pos, width: int, height: int) -> np.ndarray:
        """glsl/radiance_cache_view.comp.glsl (the RADIANCE_CACHE debug view): float32 [h, w, 4],
        per pixel what the cache gives a ray along the surface normal (w = level + 1; magenta,
        w = 0: no traced probe serves it; background w = -1)."""
        g = gbuf["textures"]
        out = compute.texture((width, height))
        VIEW.run((width, height), sky=sky, **self.lookup(), gbuf_position=g["position"],
                 gbuf_normal=g["normal"], cam_pos=compute.vec(cam_pos),
                 rc_camera=self.camera_vec(cam_pos), out_image=out)
        return compute.read(out)

    def stats(self) -> dict:
        """GPU bytes: the indirection and marks (R32F), slot tables, atlas (RGBA32F)."""
        def size(t, b):
            return t.width * t.height * b
        return {"radiance_cache_cells": size(self.cells, 4) + size(self.marks, 4),
                "radiance_cache_slots": size(self.slots, 16) + size(self.state, 16)
                + size(self.list, 16) + size(self.free, 4) + 16,
                "radiance_cache_atlas": size(self.atlas, 16) + size(self.miss, 4)}


def lookup_inputs(rcache, cam_pos) -> dict:
    """A pass that reads the cache (radiance_cache_lib.glsl) and marks cells (image rc_marks):
    `rcache`'s textures, or with None 1x1 placeholders and rc_camera.w = 0 (off)."""
    if rcache is not None:
        return dict(rcache.lookup(), rc_camera=rcache.camera_vec(cam_pos), rc_marks=rcache.marks)
    tex = compute.texture((1, 1), 'R32F')
    return dict({name: tex for name in SAMPLERS}, rc_camera=(0.0, 0.0, 0.0, 0.0), rc_marks=tex)


def trace_off() -> dict:
    """screen_probe_trace's rc_* inputs with the cache off (a 1x1 marks image)."""
    return dict(rc_camera=(0.0, 0.0, 0.0, 0.0), rc_frame=0,
                rc_marks=compute.texture((1, 1), 'R32F'))
