"""Indirect light of one frame, in the order of the passes (the lecture's pipeline):

    global SDF clipmaps  (global_sdf.py: rebuilt when objects moved, levels on their cadence)
    voxel lighting       (voxel_lighting.py: the clipmaps' voxels lit from the surface cache, 6
                         directions; levels that moved before the rays, and after each combine
                         the levels due (same cadence as the clipmaps; every level when objects
                         moved and every F12 iteration)): what the rays' global-SDF hits read
    surface cache        direct light per card texel, then per iteration: indirect rays reading
                         last iteration's final light (one more bounce each time), combine;
                         the viewport relights a budget of tiles per frame by priority
                         (surface_cache_pages.py; still: the tiles the view reads first,
                         and only they are waited for), F12 every tile the view reads
                         (PageSchedule.seen) and GISettings.render_sc_share() of the
                         others per iteration, by each tile's own visibility, distance
                         and age (never-lit tiles first), at most render_sc_texels per
                         image pixel once every tile is lit (the oldest seen first)
    screen probes        place, trace, filter, SH, integrate per pixel, temporal (screen_probes.py);
                         with GISettings.screen_trace their rays walk the HZB first
                         (screen_trace.py: HZB once per frame, the screen colour per iteration
                         from the last gather: none on a frame's first gather)
                         or another final gather passed as `gather` (GI Method VXGI: vxgi.py's
                         cones read the same voxel lighting)
                         with GISettings.radiance_cache the rays trace ~2 m and the world
                         radiance cache (radiance_cache.py, kept in the SceneState, reset when
                         the scene changes) gives the far field

`indirect_light` returns the per-pixel indirect irradiance texture. For F12 renders
(`final=True`) everything accumulated is reset first and GISettings.render_schedule() runs:
bounces - 1 surface-cache iterations (with GISettings.converge_bounces, more until
gi_settings.bounces_converged says the cache's total light is within bounce_tolerance of its
limit: a small read-back per warm-up), then render_frames iterations of cache (one more bounce
each) and probes (averaged), so a render is deterministic. In the viewport one iteration runs per redraw, blended into the
history (exponential over `history` frames; reset when the camera or the scene changes).
Needs a GPU context.
"""
from __future__ import annotations

import time

import numpy as np

from . import compute
from .frame_noise import FrameNoise
from .gi_settings import (MAX_BOUNCES, MIN_RENDER_FRAMES, RENDER_SC_MIN_TILES, SEED_FRAMES,
                          GISettings, bounces_converged)
from .screen_probes import VIEWPORT_FALLBACK_BUDGET
from .surface_cache_pages import TILE


def _global_sdf(state, gi: GISettings):
    from .global_sdf import GlobalSDF

    g = state.global_sdf
    if g is None or g.resources is not state.resources or g.n != gi.gsdf_n \
            or abs(g.base_voxel - gi.gsdf_voxel) > 1e-9:
        g = state.global_sdf = GlobalSDF(state.resources, n=gi.gsdf_n, base_voxel=gi.gsdf_voxel)
    return g


def _voxel_lighting(state, gsdf):
    from .voxel_lighting import VoxelLighting

    v = getattr(state, "voxel_lighting", None)
    if v is None or v.n != gsdf.n:
        v = state.voxel_lighting = VoxelLighting(gsdf.n)
    return v


def _radiance_cache(state, gi: GISettings):
    from .radiance_cache import RadianceCache

    rc = getattr(state, "radiance_cache", None)
    if rc is None or rc.spacing != float(gi.rc_spacing) or rc.capacity < gi.rc_capacity:
        rc = state.radiance_cache = RadianceCache(gi.rc_spacing, gi.rc_capacity)
    return rc


def _probes(state, gi: GISettings, width: int, height: int):
    from .screen_probes import ScreenProbes

    p = state.probes
    tile, res = gi.probe_tile_for(width, height), gi.probe_res_for(width, height)
    if p is None or (p.width, p.height, p.tile, p.res) != (width, height, tile, res):
        p = state.probes = ScreenProbes(width, height, tile, res)
    return p


def _seen_tiles(cache, res, cam_pos, view_proj):
    """PageSchedule.seen for this camera (the tiles' world geometry first, once per surface
    cache and after objects moved): bool per tile, the tiles the image reads."""
    cache.ensure_geometry(res.packed.objects)
    return cache.pages.seen(cam_pos, view_proj)


def sc_ray_lod(view_proj, cam_pos, height: int, rays_per_pixel: float):
    """The surface cache's ray LOD (SurfaceCache.light_indirect's `lod`): (camera position,
    pixels per metre at 1 m = |P[1][1]| H / 2, read from the view-projection's row 1 whose
    view part is a unit vector, rays per pixel); None without a perspective camera (an
    orthographic one's w row is (0, 0, 0, 1): no distance makes a texel smaller)."""
    if view_proj is None or rays_per_pixel <= 0.0:
        return None
    m = np.asarray(view_proj, np.float64)
    if np.linalg.norm(m[3, :3]) < 1e-9:
        return None
    return (cam_pos, float(np.linalg.norm(m[1, :3]) * height / 2.0), float(rays_per_pixel))


def _first_updates(cache, tiles) -> tuple:
    """The part of plan()'s (tile indices, blends) that is each tile's first update since the
    last reset (committed: update count 1)."""
    idx, blends = tiles
    first = cache.pages.count[idx] == 1
    return idx[first], blends[first]


def indirect_light(state, gbuf: dict, gi: GISettings, view_key, cam_pos, sky, t_max: float,
                   width: int, height: int, changes: set, final: bool, view_proj=None,
                   gather=None, direct=None) -> dict:
    """Run the GI passes; returns {'texture': per-pixel E_indirect, 'timings': {...},
    'iterations': n, 'sc_tiles': surface-cache tiles relit (all iterations), 'sc_tiles_total',
    'converged': bool (viewport: probe history full and every tile updated `history` times)}.
    gather: the final gather in place of the screen probes (an object with ScreenProbes'
    history, frames, gather() and temporal(): vxgi.VXGI), so another method reuses this
    pipeline's global SDF, surface cache and voxel lighting instead of duplicating it.
    direct: the direct pass's E_direct / pi texture (the screen trace's colour; None: no screen
    trace)."""
    t0 = time.perf_counter()
    res, cache = state.resources, state.surface_cache
    gsdf = _global_sdf(state, gi)
    voxels = _voxel_lighting(state, gsdf) if gi.voxel_lighting else None
    probes = gather if gather is not None else _probes(state, gi, width, height)
    scene_changed = bool(changes & {"atlas", "objects", "cards", "lights"}) \
        or state.gi_sky != sky.key
    if final or scene_changed or view_key != state.gi_view_key:
        probes.history = None                    # the pixels' history no longer applies
    if final and hasattr(probes, "prev"):
        probes.prev = None       # no importance-sampling prior from before (deterministic F12)
    rcache = (_radiance_cache(state, gi)          # the screen probes' far field (not VXGI's)
              if gi.radiance_cache and gi.gather == "PROBES" and gather is None else None)
    # F12 and a new atlas or cards start from zero; the viewport keeps the light it has while
    # the budget relights every tile (surface_cache.refresh_lighting)
    hard_reset = final or bool(changes & {"atlas", "cards"})
    if final or scene_changed:
        if hard_reset:
            cache.reset_lighting()
        else:
            cache.refresh_lighting()
        if rcache is not None:
            rcache.reset = True                  # every probe is traced again
    if final:
        # the same jitter sequences every render, a seed's own (SEED_FRAMES apart)
        state.gi_frame = int(gi.seed) * SEED_FRAMES
        cache.pages.set_geometry(None)           # tiles' world boxes: objects may have moved
    state.gi_view_key, state.gi_sky = view_key, sky.key
    objects_changed = bool(changes & {"atlas", "objects"})
    t1 = time.perf_counter()
    if final:      # F12: every tile, every iteration (deterministic)
        tiles = None
    else:          # viewport: a budget of tiles by priority, the same for direct and radiosity
        frame0 = state.gi_frame
        if objects_changed:
            cache.pages.set_geometry(None)
        # still for two redraws: which tiles the image reads (F12's `seen`, once per camera),
        # updated first and the only ones "refining n/N" waits for
        seen = (_seen_tiles(cache, res, cam_pos, view_proj)
                if probes.history is not None and probes.frames >= 2 and view_proj is not None
                else None)
        where = dict(instance_spheres=res.packed.objects[:, 8], view_proj=view_proj,
                     cam_pos=cam_pos, seen=seen)
        tiles = cache.plan(frame0, blend=gi.cache_blend, budget=gi.sc_tiles, history=gi.history,
                           where=where)
    # A tile's direct light changes only with what resets the cache (lights, objects, cards,
    # sky): the viewport lights it on the tile's first update since then and keeps it for the
    # next ones (bench/object_scaling.py, 10 objects, 84 still redraws at 128 px: the
    # surface_cache_direct pass 10.4 -> 4.4 ms a redraw on average, 0 once every tile is lit).
    direct_tiles = tiles if final else _first_updates(cache, tiles)
    cache.light_direct(res, state.light_texture, len(state.lights), tiles=direct_tiles)
    if scene_changed and hard_reset and not final:
        # the whole atlas once after a reset (combine then follows the relit tiles): the tiles
        # not yet relit show their emission at once (F12's first iteration relights them all)
        cache.combine(res)
    t2 = time.perf_counter()
    timings = {"gsdf": 0.0, "voxel_lighting": 0.0, "sc_indirect": 0.0, "probes": 0.0}
    screen = None
    if gi.screen_trace and gather is None and gi.gather == "PROBES" and direct is not None \
            and view_proj is not None:
        from .screen_trace import ScreenTrace
        screen = ScreenTrace(gbuf, view_proj, cam_pos, width, height, gi.screen_steps,
                             gi.screen_thickness, hidden=state.hidden_rows(),
                             rays=probes.res ** 2, hit=gi.screen_hit,
                             previous=getattr(state, "screen_trace", None))
    state.screen_trace = screen
    if final:
        schedule = list(gi.render_schedule())
        share = gi.render_sc_share()
        # the image's budget of relit tiles per iteration (the first relights them all), never
        # under RENDER_SC_MIN_TILES: a small image of a room keeps every wall every iteration
        cap = (max(int(np.ceil(gi.render_sc_texels * width * height / TILE ** 2)),
                   RENDER_SC_MIN_TILES) if gi.render_sc_texels > 0 else 0)
        warm = sum(1 for _, px in schedule if px is None)
        if gi.converge_bounces and warm < 2:      # two changes estimate the bounces left
            schedule[warm:warm] = [(gi.cache_blend, None)] * (2 - warm)
            warm = 2
    else:
        warm = 0
        # one iteration; the surface cache's tiles take one more bounce per update, then average
        # (plan() above)
        m = probes.history is not None and probes.frames or 0
        schedule = [(1.0, max(1.0 / (m + 1), 1.0 / gi.history))]
    # the viewport's split: one pixel of each block integrated per redraw, in turns counted from
    # the history's reset (only Lumen's own screen probes without the radiance cache or
    # importance sampling, whose rays depend on the frame; VXGI and PIXEL run whole)
    split = int(gi.split) if (not final and gather is None and gi.gather == "PROBES"
                              and rcache is None and not gi.probe_importance) else 1
    split_frame = probes.frames if probes.history is not None else 0
    result, relit, gathered, last = None, 0, 0, None
    lod = sc_ray_lod(view_proj, cam_pos, height, gi.sc_lod_rays)
    # the voxel lighting holds light from before a reset: relit whole after a hard one; after
    # the viewport's refresh (the surface cache keeps its light) its levels follow on their
    # own frames (level k every 2^k), a moved object's hits re-traced then (geometry epoch):
    # all four at once took 215 ms of the redraw after one sphere moved among 1,000
    relight = final or (scene_changed and hard_reset)
    totals = [0.0]           # F12: the cache's total indirect light after each warm-up
    noise = None                 # F12: the gathered frames' noise (two read-backs here)
    if final and direct is not None:
        noise = FrameNoise(compute.read(direct),
                           compute.read(gbuf["textures"]["position"])[..., 3] > 0.5)
    noise_log = []
    j = 0
    while j < len(schedule):
        sc_blend, px_blend = schedule[j]
        j += 1
        frame = state.gi_frame
        state.gi_frame += 1
        a = time.perf_counter()
        gsdf.update(cam_pos, frame, objects_changed)
        b = time.perf_counter()
        if voxels is not None:       # its levels are the clipmaps': where they moved, follow;
            # after a reset, all from the reset light (an F12 render is the same every time)
            # (objects changed: relight, so every level's rays are traced again here)
            voxels.update(res, gsdf, cache, frame, everything=relight, aligned_only=not relight,
                          geometry=objects_changed)
            relight = False
        v = time.perf_counter()
        if sc_blend is not None:
            if final:    # a share of the tiles, never-lit, then visible, near and old first
                frame_tiles = cache.plan(frame, blend=sc_blend, fraction=share,
                                         where=dict(view_proj=view_proj, cam_pos=cam_pos),
                                         objects=res.packed.objects, cap=cap)
            else:
                frame_tiles = tiles                  # one iteration per viewport frame
            relit += cache.light_indirect(res, gsdf, sky, frame, t_max, frame_tiles, voxels,
                                          lod=lod)
            cache.combine(res, frame_tiles)     # the tiles relit (direct and indirect) only
        c = time.perf_counter()
        if voxels is not None:       # this combine's light, for the probes and the next rays
            voxels.update(res, gsdf, cache, frame,
                          everything=final or (objects_changed and hard_reset))
        objects_changed = False
        c2 = time.perf_counter()
        if px_blend is not None:
            if gi.gather == "PIXEL" and gather is None:
                from .screen_probes import pixel_gather
                new = pixel_gather(res, gsdf, cache, gbuf, cam_pos, sky, frame, t_max,
                                   gi.pixel_rays, width, height, voxels)
            else:
                # F12: every cache probe traced every gathered frame, texels a running mean
                # (as the screen probes' own rays are: the same image quality); viewport: the
                # budget, new probes first, exponential
                # the split viewport: no adaptive probes; a pixel the uniform probes miss traces
                # its own rays on its turn (bench/glsl_ab.py --setting adaptive_probes=0 with the
                # split: probe trace 0.50x, probe filter 0.08x, frame 0.78x)
                rc = {} if gather is not None else {"importance": gi.probe_importance,
                                                 "adaptive": gi.adaptive_probes and split == 1}
                if screen is not None and screen.needs_colour and probes.history is not None:
                    # F12: the last gather's own light (the running mean lags behind the cache's
                    # bounces); the viewport: the history (its converged light)
                    screen.light(direct, last if final and last is not None
                                 else probes.history, sky)
                if screen is not None:
                    rc["screen"] = screen
                if rcache is not None:
                    rc.update(rcache=rcache, rc_budget=gi.rc_budget, rc_blend=0.25,
                              rc_retrace=gi.rc_retrace)
                    if final:
                        rc.update(rc_budget=rcache.capacity, rc_blend=1.0 / (gathered + 1),
                                  rc_retrace=None)
                if split > 1:
                    rc.update(split=split, split_frame=split_frame)
                if not final and gather is None:
                    rc["fallback_budget"] = VIEWPORT_FALLBACK_BUDGET
                new = probes.gather(res, gsdf, cache, gbuf, cam_pos, sky, frame, t_max, voxels,
                                    **rc)
                gathered += 1
            last = new
            if noise is not None:            # F12: one read-back per gathered frame
                chk = time.perf_counter()
                noise.add(compute.read(new))
                noise_log.append(noise.relative_noise())
                timings["frame_noise"] = timings.get("frame_noise", 0.0) \
                    + time.perf_counter() - chk
                if gi.noise_threshold > 0.0 and gathered >= MIN_RENDER_FRAMES \
                        and noise_log[-1] <= gi.noise_threshold:
                    del schedule[j:]             # converged: the frames left are not needed
            if split > 1:
                result = probes.temporal_split(new, gbuf, cam_pos, split, gi.history)
            else:
                result = probes.temporal(new, px_blend)
        timings["gsdf"] += b - a
        timings["voxel_lighting"] += (v - b) + (c2 - c)
        timings["sc_indirect"] += c - v
        timings["probes"] += time.perf_counter() - c2
        if final and gi.converge_bounces and px_blend is None and sc_blend is not None:
            # F12 bounces until converged (gi_settings.bounces_converged): one small read-back
            # per warm-up iteration, at most MAX_BOUNCES - 1 of them
            chk = time.perf_counter()
            totals.append(cache.indirect_total())
            timings["bounce_check"] = timings.get("bounce_check", 0.0) + time.perf_counter() - chk
            if j == warm and warm < MAX_BOUNCES - 1 \
                    and not bounces_converged(totals, gi.bounce_tolerance):
                schedule.insert(j, (sc_blend, None))
                warm += 1
    timings.update(setup=t1 - t0, sc_direct=t2 - t1, total=time.perf_counter() - t0)
    if final:
        progress = (len(schedule), len(schedule))
    else:          # the viewport: frames in the probe history and the least-updated tile's count
        h = max(int(gi.history), 1)
        n = h * split                    # redraws: each pixel's `history` turns, one per split
        progress = (min(probes.frames, min(cache.pages.least_count(seen), h) * split, n), n)
    return {"texture": result, "timings": timings, "iterations": len(schedule),
            "bounces": 1 + warm if final else None,
            "frame_noise": noise_log,
            "progress": progress,
            "sc_tiles": relit, "sc_tiles_total": len(cache.pages),
            "converged": final or (probes.frames >= gi.history * split
                                   and cache.pages.converged(gi.history, seen))}
