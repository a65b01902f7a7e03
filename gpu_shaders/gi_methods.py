"""The render setting GI Method (`scene.lumen.engine.gi_method`): which technique of lecture 21
brings the indirect light, on the same G-buffer, direct light and composite.

    LUMEN  gi.py: surface cache, global SDF, screen probes (the default)
    SSGI   ssgi.py: HZB screen rays reading last frame's lit image; what the screen shows only
    RSM    rsm.py: one bounce of the lights from reflective shadow maps, no occlusion
    LPV    lpv.py: the RSMs' texels injected into a grid of 2-band SH, propagated to the six
           neighbours (SDF occlusion), read per pixel; one bounce, no emission
    VXGI   vxgi.py: voxel cone tracing over the voxel lighting clipmaps, as Lumen's final gather
           (gi.indirect_light keeps the global SDF, surface cache and voxel lighting updated)

SSGI, RSM and LPV bring the bounced light of what they see; the sky's light then comes from the
direct pass (its SDF-occluded sky light, as with GI Off), so their misses bring nothing and the
sky is counted once. LUMEN's rays and VXGI's cones read the sky where they pass through
(SKY_IN_GI). VXGI runs through gi.indirect_light itself, its cones in place of the screen
probes, so it reuses Lumen's global SDF, surface cache and voxel lighting updates. `indirect_light` returns what gi.indirect_light does (the E_indirect texture
and the numbers frame() records), so composite.composite works unchanged. Each method keeps its
textures and history on the engine's SceneState (`state.gi_methods`), freed with it.
bpy-free: `from_scene` reads plain attributes; MethodSettings' defaults are the properties' defaults
(operators/properties.py reads them from here).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

METHODS = ("LUMEN", "SSGI", "RSM", "LPV", "VXGI")
BUILT = ("LUMEN", "SSGI", "RSM", "LPV", "VXGI")
DEBUG_VIEWS = ("SSGI_HITS", "RSM_FLUX", "LPV_GRID", "VXGI_OCCLUSION")
SKY_IN_GI = ("LUMEN", "VXGI")      # methods whose rays / cones read the sky themselves


@dataclass(frozen=True)
class MethodSettings:
    method: str = "LUMEN"
    ssgi_rays: int = 4             # cosine rays per pixel per frame
    ssgi_steps: int = 50           # HZB cells a ray may visit (the lecture's "HZB Max Step=50")
    ssgi_thickness: float = 0.1    # metres a surface is assumed thick behind the depth buffer
    ssgi_reuse: int = 1            # neighbours' rays reused: (2 r + 1)^2 pixels
    rsm_resolution: int = 256      # texels per side of each light's map
    rsm_samples: int = 64          # RSM texels gathered per pixel per frame
    lpv_cells: int = 24            # LPV cells along the scene's longest side (RSMs: rsm_resolution)
    lpv_iterations: int = 48       # propagation steps: light travels at most this many cells
    lpv_occlusion: bool = True     # the mesh SDFs block the propagation
    vxgi_cones: int = 6            # cones per pixel: one along the normal, the rest on a ring
    vxgi_cone_angle: float = 60.0  # each cone's aperture (degrees, full angle)
    vxgi_distance: float = 20.0    # metres a cone marches at most (then the sky)
    vxgi_step: float = 1.0         # step in cone radii where no surface is near
    vxgi_offset: float = 1.0       # start off the surface, in level-0 voxels (self-occlusion)


def from_scene(engine_settings) -> tuple:
    """(MethodSettings, notes) from the scene's engine settings (`scene.lumen.engine`, or anything
    with those attributes): a method not built yet renders with LUMEN, with a note saying so."""
    s = engine_settings
    d = MethodSettings()
    method = str(getattr(s, "gi_method", d.method))
    notes = []
    if method not in BUILT:
        notes.append(f"GI Method {method} is not built yet: rendering with Lumen")
        method = "LUMEN"
    return MethodSettings(
        method=method, ssgi_rays=int(getattr(s, "ssgi_rays", d.ssgi_rays)),
        ssgi_steps=int(getattr(s, "ssgi_steps", d.ssgi_steps)),
        ssgi_thickness=float(getattr(s, "ssgi_thickness", d.ssgi_thickness)),
        ssgi_reuse=int(getattr(s, "ssgi_reuse", d.ssgi_reuse)),
        rsm_resolution=int(getattr(s, "rsm_resolution", d.rsm_resolution)),
        rsm_samples=int(getattr(s, "rsm_samples", d.rsm_samples)),
        lpv_cells=min(max(int(getattr(s, "lpv_cells", d.lpv_cells)), 4), 128),
        lpv_iterations=max(int(getattr(s, "lpv_iterations", d.lpv_iterations)), 0),
        lpv_occlusion=bool(getattr(s, "lpv_occlusion", d.lpv_occlusion)),
        vxgi_cones=min(max(int(getattr(s, "vxgi_cones", d.vxgi_cones)), 1), 32),
        vxgi_cone_angle=min(max(float(getattr(s, "vxgi_cone_angle", d.vxgi_cone_angle)), 5.0),
                            180.0),
        vxgi_distance=max(float(getattr(s, "vxgi_distance", d.vxgi_distance)), 0.01),
        vxgi_step=min(max(float(getattr(s, "vxgi_step", d.vxgi_step)), 0.1), 4.0),
        vxgi_offset=max(float(getattr(s, "vxgi_offset", d.vxgi_offset)), 0.0)), notes


def direct_has_sky(settings: MethodSettings, gi_enabled: bool) -> bool:
    """Whether the direct pass carries the sky light: with GI off, and with the methods whose
    rays do not read the sky (SSGI, RSM, LPV)."""
    return not gi_enabled or settings.method not in SKY_IN_GI


def schedule(gi_cfg, final: bool, frames_in_history: int, history: int, warm: bool):
    """Blends of the iterations of one frame: F12 runs bounces - 1 warm-up iterations (blend 1;
    only methods whose iterations feed each other, `warm`) then render_frames averaged (running
    mean); the viewport one iteration into an exponential history of about `history` frames."""
    if final:
        warmup = [1.0] * (max(gi_cfg.bounces - 1, 0) if warm else 0)
        return warmup + [1.0 / (j + 1) for j in range(max(gi_cfg.render_frames, 1))]
    m = frames_in_history
    return [max(1.0 / (m + 1), 1.0 / max(history, 1))]


SCENE_CHANGES = {"atlas", "objects", "cards", "lights"}   # SceneState.sync changes that reset


def _holder(state, name: str, width: int, height: int):
    """The method's object on the state (SSGI, RSM, LPV or VXGI, for this image size)."""
    from .lpv import LPV
    from .rsm import RSM
    from .ssgi import SSGI
    from .vxgi import VXGI

    methods = getattr(state, "gi_methods", None)
    if methods is None:
        methods = state.gi_methods = {}
    obj = methods.get(name)
    if obj is None or (obj.width, obj.height) != (width, height):
        obj = methods[name] = {"SSGI": SSGI, "RSM": RSM, "LPV": LPV, "VXGI": VXGI}[name](width, height)
    return obj


def indirect_light(settings: MethodSettings, state, gbuf: dict, objects, direct_textures: dict,
                   gi_cfg, view_key, view_proj, inv_view_proj, cam_pos, sky, t_max: float,
                   width: int, height: int, changes: set, final: bool) -> dict:
    """Run SSGI, RSM, LPV or VXGI for one frame; returns {'texture': E_indirect, 'timings',
    'iterations', 'progress', 'converged', 'sc_tiles', 'sc_tiles_total'} like
    gi.indirect_light. The history starts again for F12 and whenever the view, the settings,
    the sky or the scene changed."""
    t0 = time.perf_counter()
    release(state, keep=settings.method)
    m = _holder(state, settings.method, width, height)
    if settings.method == "VXGI":
        return _vxgi(m, settings, state, gbuf, gi_cfg, view_key, view_proj, cam_pos, sky, t_max,
                     width, height, changes, final)
    key = (view_key, settings, sky.key)
    if final or key != m.key or changes & SCENE_CHANGES:
        m.reset()
    m.key = key
    if settings.method == "LPV":
        return _lpv_frame(settings, state, m, gbuf, objects, cam_pos, changes, t0)
    if settings.method == "SSGI":
        m.prepare(gbuf, view_proj)
    else:
        m.render_maps(objects, state.lights, state.light_texture, settings.rsm_resolution)
    t1 = time.perf_counter()
    blends = schedule(gi_cfg, final, m.frames, gi_cfg.history, warm=settings.method == "SSGI")
    frame0 = 0 if final else state.gi_frame          # F12: the same jitter every render
    for j, blend in enumerate(blends):
        if settings.method == "SSGI":
            m.iterate(gbuf, direct_textures, sky, view_proj, inv_view_proj, cam_pos, settings,
                      frame0 + j, blend, t_max)
        else:
            m.iterate(gbuf, cam_pos, settings.rsm_samples, frame0 + j, blend)
    state.gi_frame = frame0 + len(blends)
    prep = "hzb" if settings.method == "SSGI" else "rsm_maps"
    timings = {prep: t1 - t0, settings.method.lower(): time.perf_counter() - t1,
               "total": time.perf_counter() - t0}
    h = max(int(gi_cfg.history), 1)
    progress = (len(blends), len(blends)) if final else (min(m.frames, h), h)
    return {"texture": m.history, "timings": timings, "iterations": len(blends),
            "progress": progress, "converged": final or m.frames >= h,
            "sc_tiles": 0, "sc_tiles_total": 0}


def _lpv_frame(settings, state, m, gbuf, objects, cam_pos, changes, t0) -> dict:
    """LPV is deterministic: one update and one gather per frame (F12 and viewport alike), no
    history to blend."""
    m.update(objects, state, settings.lpv_cells, settings.lpv_iterations, settings.lpv_occlusion,
             settings.rsm_resolution, bool(changes & {"objects", "atlas"}))
    t1 = time.perf_counter()
    m.iterate(gbuf, cam_pos)
    t2 = time.perf_counter()
    return {"texture": m.history, "timings": {"rsm_maps_lpv": t1 - t0, "lpv": t2 - t1,
                                              "total": t2 - t0},
            "iterations": 1, "progress": (1, 1), "converged": True,
            "sc_tiles": 0, "sc_tiles_total": 0}


def _vxgi(m, settings, state, gbuf, gi_cfg, view_key, view_proj, cam_pos, sky, t_max, width,
          height, changes, final) -> dict:
    """VXGI through Lumen's pipeline (gi.indirect_light with the cones as its final gather):
    the voxel lighting on whatever the setting says, the screen probes' history freed."""
    from dataclasses import replace

    from . import gi

    if m.key != (view_key, settings):
        m.reset()                        # gi.indirect_light resets it too when the scene changed
    m.key, m.settings = (view_key, settings), settings
    state.probes = None
    cfg = replace(gi_cfg, voxel_lighting=True, gather="PROBES")
    out = gi.indirect_light(state, gbuf, cfg, view_key, cam_pos, sky, t_max, width, height,
                            changes, final, view_proj=view_proj, gather=m)
    out["timings"]["vxgi"] = out["timings"].pop("probes", 0.0)
    return out


def release(state, keep: str = ""):
    """Free the other methods' textures and histories (a method switch in the viewport)."""
    methods = getattr(state, "gi_methods", None) or {}
    for name in [n for n in methods if n != keep]:
        del methods[name]


def notes(settings: MethodSettings, state) -> list:
    """What the frame's method leaves out, for frame()'s notes (F12 reports them)."""
    out = []
    if settings.method in ("RSM", "LPV"):
        m = (getattr(state, "gi_methods", None) or {}).get(settings.method)
        maps = m.maps if settings.method == "RSM" else (m.rsm.maps if m is not None else None)
        if m is not None and not maps:
            out.append(f"GI Method {settings.method}: no light, so no indirect light (emission "
                       "does not bounce through reflective shadow maps)")
    return out


def stats(state) -> dict:
    """GPU bytes of the methods' textures (ssgi_*, rsm_*, lpv_*, vxgi_*) for MEMORY /
    LAST_RENDER['gpu_bytes'] (VXGI's global SDF, surface cache and voxel lighting are
    SceneState's, counted by state.stats())."""
    out = {}
    for m in (getattr(state, "gi_methods", None) or {}).values():
        out.update(m.stats())
    return out


def debug_image(view: str, state, width: int, height: int):
    """The image of a GI method's debug view (SSGI_HITS, RSM_FLUX, LPV_GRID, VXGI_OCCLUSION), float32
    [h, w, 4]; black when that method is not the one rendering."""
    methods = getattr(state, "gi_methods", None) or {}
    if view == "SSGI_HITS" and "SSGI" in methods:
        img = methods["SSGI"].hit_image()
        if img.shape[:2] == (height, width):
            return img
    if view == "RSM_FLUX" and "RSM" in methods:
        return methods["RSM"].flux_image(width, height)
    if view == "LPV_GRID" and "LPV" in methods:
        return methods["LPV"].grid_image(width, height)
    if view == "VXGI_OCCLUSION" and "VXGI" in methods:
        img = methods["VXGI"].occlusion_image()
        if img.shape[:2] == (height, width):
            return img
    img = np.zeros((height, width, 4), np.float32)
    img[..., 3] = 1.0
    return img
