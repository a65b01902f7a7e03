"""The Lumen GI render engine (preview): G-buffer, direct light, dynamic global illumination.

`frame()` runs, for the scene camera (render) or the viewport's view (view_draw):
    G-buffer        mesh_batches.py: the unique meshes' batches kept on the GPU, drawn instanced
                    (the extraction re-reads only what view_update found changed)
    direct light    direct_light.py: lights with SDF cone-traced soft shadows (and, with GI off,
                    SDF-occluded sky light)
    GI              gi.py: global SDF clipmaps, surface cache (cards: direct light, radiosity
                    probes, bounces), screen probes, temporal (see gi.py for the order)
    composite       composite.py: albedo x (direct + indirect) + emission
It writes
    Combined         the lit image (world colour on the background), alpha 1
    Diffuse Direct   E_direct / pi, Cycles' convention (albedo excluded; with GI on the sky's
                     light is in Diffuse Indirect, where the probes' rays find it)
    Diffuse Indirect E_indirect / pi
    Diffuse Color    the albedo: G-buffer base colour
    Normal           world normal
(Blender 5.0's own names, so the passes line up with Cycles' in the compositor and in EXRs).

Debug views (`scene.lumen.engine.debug_view`, Render Properties) replace what Combined
shows: COMBINED, NORMAL, ALBEDO, DIRECT, INDIRECT; the SDF trace alone: DEPTH (hit distance),
STEPS (heat map), HYBRID (green: mesh-SDF hit, blue: global-SDF hit); the surface cache seen
through the cards: SC_FINAL, SC_ALBEDO, SC_NORMAL, SC_DIRECT, SC_INDIRECT, CARDS (a colour per
card; magenta where no card sees the point), SC_UPDATES (update heat of the budget: green relit
this frame to red 8+ frames ago, magenta not yet); PROBES (the probe radiance atlas) and
PROBE_FALLBACK (green: interpolated from probes, red: traced per pixel); VOXEL_LIGHTING;
RADIANCE_CACHE (what the world radiance cache gives a ray along the normal; magenta: no traced
probe there; the cache must be on: GISettings.radiance_cache, else Combined); TRACE_METHOD (the
share of each pixel's rays served by the screen trace (red), the mesh SDFs (green), the global
SDF (blue): GI Method Lumen with the screen trace on, else Combined).

GPU inputs live in a scene_state.SceneState owned by the engine instance, as Cycles' session
is: a viewport's engine keeps one for its lifetime, and a redraw re-uploads only what changed
(the object table for moved objects, the light rows for changed lights, the brick atlas and
indirection only when the set of baked meshes changed, the card textures when the cards did;
the G-buffer's mesh batches for meshes the depsgraph reported edited, its instance table for
moved objects);
an F12 render makes its own and frees it before it returns. F12 (`final=True`) accumulates GI
from scratch (GISettings.render_schedule: deterministic) and reads back only the passes it
writes; the viewport adds one GI iteration per redraw to its history, draws the Combined
texture as it is on the GPU (no read-back) through Blender's display transform, says
"refining n/N" until the history is full and asks for redraws until then. `view_update`
reads depsgraph.updates into LAST_VIEW_UPDATE, marks the objects, meshes, materials and images
it names for the staleness check and the extraction cache to read again, bumps the state's
epoch (and, unless objects only moved, the direct epoch: the progressive direct light starts
again everywhere; after a move only where the move reaches) and tags a redraw. Compiled passes are cached
per process and freed at exit before Blender's GPU module (gpu_shaders.free_shaders).

It works headless: Blender gives a RenderEngine with bl_use_gpu_context a GPU context in
background mode too (Mesa llvmpipe).

The bake comes from the bake operator's memory (operators.bake_op.LAST_BAKES, by scene name)
or else from the scene's cache folder (scene.lumen.bake.cache_dir, resolved like the operators do).
"""
from __future__ import annotations

import dataclasses
import gc
import time

import bpy
import numpy as np

from . import data_passes, sdf_trace
from .scene_state import SceneState

# Extra passes: (name in the render result, channels, channel ids, type).
PASSES = (("Diffuse Direct", 3, "RGB", 'COLOR'), ("Diffuse Indirect", 3, "RGB", 'COLOR'),
          ("Diffuse Color", 3, "RGB", 'COLOR'), ("Normal", 3, "XYZ", 'VECTOR'))
VIEW_PROPERTY = "lumen_preview_view"       # legacy: "DEPTH" selects the DEPTH debug view
DEBUG_VIEWS = ("COMBINED", "DEPTH", "STEPS", "NORMAL", "ALBEDO", "DIRECT", "INDIRECT", "HYBRID",
               "SC_FINAL", "SC_ALBEDO", "SC_NORMAL", "SC_DIRECT", "SC_INDIRECT", "CARDS",
               "SC_UPDATES", "PROBES",
               "PROBE_FALLBACK", "VOXEL_LIGHTING", "RADIANCE_CACHE", "TRACE_METHOD")
TRACE_VIEWS = ("DEPTH", "STEPS", "HYBRID")
CARD_VIEWS = {"SC_FINAL": "final", "SC_ALBEDO": "albedo", "SC_NORMAL": "normal",
              "SC_DIRECT": "direct", "SC_INDIRECT": "indirect", "CARDS": "cards",
              "SC_UPDATES": "updates"}
STEPS_FULL_SCALE = 128.0                    # STEPS heat map: red at this many steps

# GPU bytes per resource of the last frame, by scene name (the N-panel reads it).
MEMORY = {}
# Objects added or edited since the bake, by scene name, as the last frame found them (the
# N-panel reads it; lumen_addon/staleness.py).
STALE = {}
# What the last view_update saw in depsgraph.updates (flags) and how often it ran.
LAST_VIEW_UPDATE = {}
_DISK_BAKES = {}                            # folder -> (mtime, bake): the viewport reads once

# What the last frame did (read by tests and scripts): camera, timings, memory, notes. Its
# images (G-buffer, passes) are read back and kept only when KEEP_IMAGES is set (tests set it)
# or a debug view needs them: an idle add-on holds no full-size image.
LAST_RENDER = {}
KEEP_IMAGES = False


def scene_bake(scene):
    """(bake, source) for the scene: the operator's bake in memory, else the cache folder."""
    from ..operators import bake_op
    from ..lumen_addon.cache import CacheError, read_cache

    bake = bake_op.LAST_BAKES.get(scene.name)
    if bake is not None:
        return bake, "memory"
    folder = bake_op.scene_cache_folder(scene)
    try:
        mtime = folder.stat().st_mtime_ns if folder.exists() else None
        hit = _DISK_BAKES.get(str(folder))
        if hit is not None and hit[0] == mtime:
            return hit[1], str(folder)
        bake = read_cache(folder)
        _DISK_BAKES[str(folder)] = (mtime, bake)
        return bake, str(folder)
    except CacheError as exc:
        raise RuntimeError(f"No bake for scene {scene.name!r}: press Bake in the 3D viewport's "
                           f"Lumen tab (N). ({exc})") from exc


def view_projection(depsgraph, camera, width: int, height: int):
    """(view-projection numpy float64 4x4, camera world position, clip_end) for the render size."""
    render = depsgraph.scene.render
    cam = camera.evaluated_get(depsgraph)
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    view = cam.matrix_world.inverted()
    vp = np.array(proj, np.float64) @ np.array(view, np.float64)
    return vp, np.array(cam.matrix_world.translation, np.float64), float(cam.data.clip_end)


def _data_passes(fr, scene, extra) -> dict:
    """The view layer's enabled data passes (data_passes.DATA_PASSES rows `extra`) of an F12
    frame: one read-back of the G-buffer's position and emission."""
    g = fr.gbuffer
    world = scene.world
    mist = ((world.mist_settings.start, world.mist_settings.depth, world.mist_settings.falloff)
            if world is not None else (5.0, 25.0, 'QUADRATIC'))
    cam = scene.camera
    return data_passes.data_passes([row[1] for row in extra], fr.read(g["position"]),
                                   fr.read(g["emission"]), np.array(cam.matrix_world),
                                   getattr(cam.data, "type", "PERSP") == 'ORTHO', mist)


def camera_matrices(depsgraph, camera, width: int, height: int):
    """(inverse view-projection as numpy float64 4x4, clip_end) of `camera` for the render size."""
    vp, _, clip_end = view_projection(depsgraph, camera, width, height)
    return np.linalg.inv(vp), clip_end


def depth_grey(hit: np.ndarray) -> np.ndarray:
    """RGBA float [h, w, 4]: grey from 1 (nearest hit) to 0.2 (farthest), black on a miss."""
    rgba = np.zeros(hit.shape + (4,), np.float32)
    rgba[..., 3] = 1.0
    mask = hit >= 0
    if mask.any():
        lo, hi = float(hit[mask].min()), float(hit[mask].max())
        g = 1.0 - 0.8 * (hit - lo) / max(hi - lo, 1e-9)
        rgba[..., :3] = np.where(mask, g, 0.0)[..., None]
    return rgba


def steps_heat(steps: np.ndarray, full: float = STEPS_FULL_SCALE) -> np.ndarray:
    """RGBA float [h, w, 4]: blue (few steps) -> green -> red (>= `full` steps)."""
    t = np.clip(np.asarray(steps, np.float32) / full, 0.0, 1.0)
    rgba = np.ones(t.shape + (4,), np.float32)
    rgba[..., 0] = np.clip(2.0 * t - 1.0, 0.0, 1.0)
    rgba[..., 1] = 1.0 - np.abs(2.0 * t - 1.0)
    rgba[..., 2] = np.clip(1.0 - 2.0 * t, 0.0, 1.0)
    return rgba


def engine_settings(scene):
    """The scene's engine settings (`scene.lumen.engine`); None without the add-on's properties,
    and then gi_settings / gi_methods.from_scene give their defaults."""
    return getattr(getattr(scene, "lumen", None), "engine", None)


def settings_key(scene) -> tuple:
    """The scene settings a kept viewport image depends on (every engine setting, the pixel
    filter, Film > Transparent, the legacy view property): part of the anti-aliasing's key,
    which a depsgraph update that changed nothing drawn (a selection click) leaves alone."""
    eng = engine_settings(scene)
    values = []
    if eng is not None:
        for prop in eng.bl_rna.properties:
            if prop.identifier != "rna_type":
                v = getattr(eng, prop.identifier, None)
                values.append(tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v)
    render = scene.render
    return (tuple(values), float(getattr(render, "filter_size", 1.5)),
            bool(getattr(render, "film_transparent", False)), scene.get(VIEW_PROPERTY))


def debug_view(scene) -> str:
    view = getattr(engine_settings(scene), "debug_view", "COMBINED")
    if view == "COMBINED" and scene.get(VIEW_PROPERTY) == "DEPTH":
        view = "DEPTH"
    return view


def draw_message(text: str, width: int, height: int, line: int = 0):
    """A line of text in the viewport's top-left corner (no bake, a failed frame, objects changed
    since the bake), `line` lines down: the viewport must say why it shows nothing or what it
    shows wrong. Long messages are cut to the region's width."""
    import blf

    font = 0
    blf.size(font, 13)
    blf.color(font, 1.0, 1.0, 1.0, 1.0)
    limit = max(int(width / 7), 16)
    text = text if len(text) <= limit else text[:limit - 1] + "…"
    blf.position(font, 12, max(height - 24 - 18 * line, 4), 0)
    blf.draw(font, text)


def pixel_size(scene, context=None) -> int:
    """The viewport's pixel size: scene.render.preview_pixel_size, 'AUTO' meaning the interface's
    pixel size (high-DPI displays render at half resolution, as Cycles and EEVEE do)."""
    value = getattr(scene.render, "preview_pixel_size", "AUTO")
    if value == "AUTO":
        prefs = getattr(context, "preferences", None) or bpy.context.preferences
        return max(1, int(round(getattr(prefs.system, "pixel_size", 1.0))))
    return max(1, int(value))


def screen_bytes(width: int, height: int, gi: bool) -> dict:
    """GPU bytes of a frame's screen-size targets (RGBA32F unless said): the G-buffer's
    attachments and depth (32-bit), the direct light pass's two images and, with GI, the
    composite's two (the screen probes count their own)."""
    from .gbuffer import ATTACHMENTS

    px = int(width) * int(height)
    out = {"screen_gbuffer": px * 16 * len(ATTACHMENTS), "screen_depth": px * 4,
           "screen_direct": px * 16 * 2}
    if gi:
        out["screen_composite"] = px * 16 * 2
    return out


def gpu_backend() -> str:
    """'OPENGL', 'VULKAN', 'METAL' (...) of the running Blender, 'unknown' where it cannot say."""
    import gpu

    get = getattr(gpu.platform, "backend_type_get", None)
    return str(get()) if get else "unknown"


def mesh_matrices(depsgraph) -> dict:
    """{instance name: world 4x4} of the visible mesh instances (the trace views' placement;
    extract_scene's names, so an instance the scene no longer has leaves these views too)."""
    from ..operators.extract import instance_matrices
    return instance_matrices(depsgraph)


def extraction(state):
    """The engine instance's ExtractionCache (made on first use: everything is read once)."""
    from ..operators.extract import ExtractionCache

    if state.extraction is None:
        state.extraction = ExtractionCache()
    return state.extraction


def frame(state, depsgraph, scene, view_proj, cam_pos, clip_end, width, height,
          view="COMBINED", final=True, pixel_size=1):
    """One frame, for render() (final: F12, accumulates GI from scratch) and view_draw (one more
    GI iteration into the history) alike: sync `state` (the engine instance's SceneState), run
    the passes. Returns a Frame: the passes as GPU textures (nothing is read back here; F12
    reads the passes it writes, the viewport draws Combined), or `shown` (numpy) for a debug
    view. Fills LAST_RENDER with the frame's numbers (and images only when KEEP_IMAGES)."""
    from ..lumen_addon import staleness
    from ..operators.extract import hidden_renderable, render_only_geometry
    from ..operators.world_capture import world_light
    from . import composite, compute, direct_light, gi, gi_methods, gi_settings, mesh_batches

    t0 = time.perf_counter()
    bake, source = scene_bake(scene)
    sky_maps, sky_notes = world_light(scene)     # remembered per world: a capture only on change
    ext = extraction(state)
    lights = np.concatenate([ext.light_rows(depsgraph), sky_maps.sun_rows()])
    stale, t_stale = None, time.perf_counter()
    if view in TRACE_VIEWS:
        objects, warnings = None, []
        matrices = mesh_matrices(depsgraph)
    else:
        objects, warnings, keys, meshes, mats, visible, holdout = ext.update(depsgraph)
        # the screen trace's blind spots: what the depth buffer does not hold as a surface
        state.set_camera_hidden(objects, visible & ~holdout)
        matrices = ext.matrices        # the same dict object until the next walk (sync: no loop)
        t_stale = time.perf_counter()
        if ext.changed or state.stale.bake is not bake or state.stale.pending():
            stale = state.stale.changed(bake, objects, render_only_geometry(depsgraph))
        else:                    # same instances, no mesh re-read: the same verdicts
            stale = state.stale.unchanged()
        STALE[scene.name] = stale
    stale_seconds = time.perf_counter() - t_stale
    t1 = time.perf_counter()
    changes = state.sync(bake, matrices, lights,
                         shadow_pass=ext.shadow_pass if objects is not None else {})
    if state.sky.update(sky_maps):
        changes.add("sky")
    res = state.resources
    t2 = time.perf_counter()
    LAST_RENDER.update(source=source, width=width, height=height, view=view,
                       changes=sorted(changes), uploads=dict(state.uploads),
                       bricks=res.packed.bricks,
                       atlas_size=list(res.packed.atlas_size), upload_seconds=res.upload_seconds,
                       extract_seconds=t1 - t0, sync_seconds=t2 - t1)
    LAST_RENDER.update(stale=list(stale or []), gone=list(state.gone),
                       stale_hashed=state.stale.hashed, stale_seconds=stale_seconds)
    if state.extraction is not None:
        LAST_RENDER.update(meshes_read=state.extraction.reads,
                           meshes_read_total=state.extraction.reads_total,
                           extraction_walked=state.extraction.walked)
    if view in TRACE_VIEWS:
        inv_vp = np.linalg.inv(np.asarray(view_proj, np.float64))
        if view == "HYBRID":
            out = _hybrid_trace(state, scene, cam_pos, inv_vp, width, height, clip_end)
            img = hybrid_colours(out["hit"], out["global"])
        else:
            out = sdf_trace.trace(res, inv_vp, width, height, t_max=clip_end)
            img = depth_grey(out["hit"]) if view == "DEPTH" else steps_heat(out["steps"])
        LAST_RENDER.update(out, inv_view_proj=inv_vp, t_max=clip_end)
        MEMORY[scene.name] = state.stats()
        LAST_RENDER["gpu_bytes"] = MEMORY[scene.name]
        LAST_RENDER["shown"] = img
        return Frame({}, img)
    gi_cfg = gi_settings.from_scene(engine_settings(scene), viewport=not final)
    if pixel_size > 1:                          # the viewport's Pixel Size (view_draw)
        gi_cfg = dataclasses.replace(gi_cfg, pixel_size=int(pixel_size))
    method, method_notes = gi_methods.from_scene(engine_settings(scene))   # gi_methods.METHODS
    sky = state.sky
    sky.film_alpha = 0.0 if getattr(scene.render, "film_transparent", False) else 1.0
    inv_vp = np.linalg.inv(np.asarray(view_proj, np.float64))
    if state.mesh_batches is None:
        state.mesh_batches = mesh_batches.MeshBatches()
    state.mesh_batches.update(keys, meshes, mats, visible, holdout)
    gbuf = state.mesh_batches.draw(view_proj, width, height)
    t3 = time.perf_counter()
    sky_cones = direct_light.SKY_CONES if gi_methods.direct_has_sky(method, gi_cfg.enabled) else 0
    if final:
        out = direct_light.shade(res, gbuf, state.lights, sky, cam_pos, inv_vp, width, height,
                                 sky_cones=sky_cones, light_texture=state.light_texture)
    else:          # the viewport: a part of the samples per redraw, then kept (Progressive)
        if changes:
            state.epoch += 1
        if changes - {"objects"}:     # moved objects restart only the pixels they reach
            state.direct_epoch += 1
        key = (np.asarray(view_proj, np.float64).tobytes(), width, height, sky_cones,
               state.direct_epoch, sky.key, sky.film_alpha)
        out = state.direct.shade(key, res, gbuf, state.lights, sky, cam_pos, inv_vp, width,
                                 height, sky_cones, state.light_texture)
    t4 = time.perf_counter()
    g = gbuf["textures"]
    textures = {"Combined": out["textures"]["combined"],
                "Diffuse Direct": out["textures"]["direct"], "Diffuse Indirect": None,
                "Diffuse Color": g["albedo"], "Normal": g["normal"]}
    gi_info = {}
    LAST_RENDER.pop("trace_method", None)          # (the viewport keeps LAST_RENDER between frames)
    if gi_cfg.enabled:
        view_key = (np.asarray(view_proj, np.float64).tobytes(), width, height)
        if method.method == "LUMEN":
            gi_methods.release(state)
            gi_out = gi.indirect_light(state, gbuf, gi_cfg, view_key, cam_pos, sky,
                                       min(float(clip_end), 100.0), width, height, changes, final,
                                       view_proj=view_proj, direct=out["textures"]["direct"])
        else:
            state.screen_trace = None    # Lumen's: its HZB freed, TRACE_METHOD has none to show
            gi_out = gi_methods.indirect_light(method, state, gbuf, objects, out["textures"],
                                               gi_cfg, view_key, view_proj, inv_vp, cam_pos, sky,
                                               min(float(clip_end), 100.0), width, height,
                                               changes, final)
            method_notes += gi_methods.notes(method, state)
        comp = composite.composite(gbuf, out["textures"]["direct"], gi_out["texture"], sky,
                                   inv_vp, width, height)
        textures["Combined"] = comp["textures"]["combined"]
        textures["Diffuse Indirect"] = comp["textures"]["indirect"]
        gi_info = dict(gi_seconds=gi_out["timings"]["total"], gi_timings=gi_out["timings"],
                       gi_iterations=gi_out["iterations"], gi_converged=gi_out["converged"],
                       gi_bounces=gi_out.get("bounces"),
                       gi_frame_noise=gi_out.get("frame_noise", []),
                       gi_progress=gi_out["progress"],
                       gi_sc_tiles=(gi_out["sc_tiles"], gi_out["sc_tiles_total"]),
                       gi_settings=gi_cfg.__dict__.copy(),
                       gi_probe_tile=getattr(state.probes, "tile", None),
                       gi_probe_res=getattr(state.probes, "res", None),
                       gi_screen_hzb_reused=getattr(state.screen_trace, "hzb_reused", None))
        if not final and not gi_out["converged"]:
            # the refining redraw's time so far (G-buffer, direct light, GI, composite): what a
            # redraw of the anti-aliasing that follows may take. GI alone shrank once a tile's
            # later updates stopped relighting its direct light, and with it the samples a
            # redraw took
            state.refine_seconds = time.perf_counter() - t0
        if view == "PROBE_FALLBACK":                 # a read-back only the debug view needs
            LAST_RENDER["indirect_irradiance"] = compute.read(gi_out["texture"])
        if view == "TRACE_METHOD" and getattr(state, "screen_trace", None) is not None:
            LAST_RENDER["trace_method"] = state.screen_trace.method_image(
                state.resources, state.global_sdf, state.surface_cache, sky,
                state.voxel_lighting if gi_cfg.voxel_lighting else None,
                min(float(clip_end), 100.0), frame=state.gi_frame)
    if not final and not (gi_info.get("gi_converged", True) and state.direct.converged):
        state.unsettled += 1          # a refining frame: the anti-aliasing starts again after
    aa_info = {"aa_progress": None}
    if gi_cfg.aa_samples > 1 and view == "COMBINED":
        from . import antialias
        aa_args = (state, gbuf, textures, gi_out["texture"] if gi_cfg.enabled else None,
                   state.lights, sky, cam_pos, view_proj, width, height, gi_cfg.aa_samples,
                   float(getattr(scene.render, "filter_size", 1.5)), sky_cones)
        t_aa = time.perf_counter()
        if final:
            aa = antialias.supersample(*aa_args)
            textures = aa["textures"]
            aa_info = dict(aa_seconds=aa["seconds"], aa_samples=aa["samples"])
        elif gi_info.get("gi_converged", True) and state.direct.converged:
            # a still viewport: jittered samples, ending on the F12 image; as many a redraw as
            # fit in the last refining redraw's time (one at least)
            # what its samples are made of: the view, the world, the settings, the G-buffer's
            # instances and the frames that refined since (the GI's, the direct light's; the
            # state's epoch would also count a selection click, which changes none of them)
            key = (np.asarray(view_proj, np.float64).tobytes(), width, height, sky.key,
                   settings_key(scene), state.mesh_batches.generation, state.unsettled)
            textures = state.aa.step(key, *aa_args, seconds=state.refine_seconds)
            aa_info = dict(aa_seconds=time.perf_counter() - t_aa, aa_samples=state.aa.done,
                           aa_progress=(state.aa.done, gi_cfg.aa_samples))
        else:
            aa_info = dict(aa_progress=(0, gi_cfg.aa_samples))
    t5 = time.perf_counter()
    # the viewport has nothing left to refine (its GI, direct light and anti-aliasing all done):
    # view_draw draws this Combined again until something changes (SceneState.still)
    done = (not final and view == "COMBINED" and gi_info.get("gi_converged", True)
            and state.direct.converged
            and (aa_info["aa_progress"] is None
                 or aa_info["aa_progress"][0] >= aa_info["aa_progress"][1]))
    MEMORY[scene.name] = dict(state.stats(), **screen_bytes(width, height, gi_cfg.enabled),
                              **gi_methods.stats(state))
    LAST_RENDER.update(
        view_proj=np.asarray(view_proj, np.float64), cam_pos=cam_pos, lights=state.lights,
        gi_method=method.method,
        sky=sky.mean, sun=sky_maps.sun,
        notes=[f"{name}: {message}" for name, message in warnings] + sky_notes + method_notes + [
            f"{name}: its transform cannot be inverted (a scale of 0?): it casts and bounces no "
            f"light" for name in state.left_out], triangles=gbuf["triangles"],
        gbuffer_draws=gbuf["draws"], gbuffer_reused=gbuf.get("reused", False),
        texture_uploads=gbuf["texture_uploads"],
        gbuffer_batches_built=gbuf["batches_built"],
        instance_table_uploaded=gbuf["instance_table_uploaded"],
        gbuffer_seconds=t3 - t2, direct_seconds=t4 - t3, resources_seconds=t2 - t1,
        direct_compile_seconds=out["compile_seconds"], shade_seconds=out["shade_seconds"],
        direct_part=out.get("part", (0, direct_light.LIGHT_SAMPLES)),
        direct_restart=None if final else state.direct.last_restart,
        gpu_bytes=MEMORY[scene.name], frame_seconds=t5 - t0, reused_frame=False, **gi_info,
        **aa_info)
    if stale:
        # F12 draws what the viewport hides (the eye, Disable in Viewports); the bake, made from
        # the viewport, cannot hold those until they are shown
        hidden = (set(hidden_renderable(scene.view_layers[depsgraph.view_layer.name]))
                  if final and depsgraph.view_layer.name in scene.view_layers else set())
        unseen = [n for n in stale if staleness.name_parts(n) & hidden]
        stale = [n for n in stale if n not in unseen]
        if unseen:
            LAST_RENDER["notes"].append(
                staleness.summary(unseen, what="hidden in the viewport, so not baked")
                + ": drawn without their shadows and bounce light; show them and press Bake")
    if stale:
        LAST_RENDER["notes"].append(staleness.summary(stale) + ": drawn, but their light and "
                                    "shadows are the bake's; press Bake")
    result = Frame(textures, None, width, height)
    result.gbuffer = gbuf["textures"]          # F12's data passes (data_passes.py) read it
    result.shading_normals = bool(gbuf.get("shading_normals"))
    result.converged = bool(done)
    if KEEP_IMAGES or view != "COMBINED":
        images = dict(position=result.read(g["position"]), normal=result.read(g["normal"]),
                      albedo=result.read(g["albedo"]), emission=result.read(g["emission"]),
                      direct=result.read(textures["Diffuse Direct"]),
                      indirect=result.pass_array("Diffuse Indirect"),
                      combined=result.read(textures["Combined"]))
        if KEEP_IMAGES:
            LAST_RENDER.update(images, shown=images["combined"])
            if not final and state.direct.parts is not None:    # each pixel's parts so far
                LAST_RENDER["direct_parts"] = result.read(state.direct.parts)
        if view != "COMBINED":
            result.shown = (gi_methods.debug_image(view, state, width, height)
                            if view in gi_methods.DEBUG_VIEWS or (method.method != "LUMEN"
                                                                  and view == "PROBES")
                            else _debug_image(view, state, gbuf, images, cam_pos, width, height,
                                              gi_cfg))
            LAST_RENDER["shown"] = result.shown
    return result


class Frame:
    """A frame's passes as GPU textures ({pass name: GPUTexture or None}) or, for a debug view,
    `shown` (float32 [h, w, 4]) in place of Combined. Read-backs happen only on request."""

    def __init__(self, textures: dict, shown=None, width: int = 0, height: int = 0):
        self.textures, self.shown = textures, shown
        self.width, self.height = width, height
        self.converged = False       # the viewport's: nothing left to refine (frame())
        self.gbuffer = None          # the G-buffer's textures (position, normal, albedo, emission)
        self.shading_normals = False  # it packed shading normals (a drawn mesh has a normal map)

    def read(self, tex) -> np.ndarray:
        from .resources import read_texture
        return read_texture(tex, (self.height, self.width, -1))

    def pass_array(self, name: str) -> np.ndarray:
        """float32 [h, w, 4] of a pass (Combined: the debug view's image when there is one)."""
        if name == "Combined" and self.shown is not None:
            return self.shown
        tex = self.textures.get(name)
        if tex is None:
            return np.zeros((self.height, self.width, 4), np.float32)
        return self.read(tex)


def hybrid_colours(hit: np.ndarray, global_part) -> np.ndarray:
    """RGBA [h, w, 4]: green where the mesh SDFs hit, blue where the global SDF did, black misses."""
    rgba = np.zeros(hit.shape + (4,), np.float32)
    rgba[..., 3] = 1.0
    hits = hit >= 0
    rgba[hits & ~global_part, 1] = 1.0
    rgba[hits & global_part, 2] = 1.0
    return rgba


def _hybrid_trace(state, scene, cam_pos, inv_vp, width, height, clip_end):
    """The GI tracer (gi_trace_lib.glsl) along camera rays: where it hits and with which part."""
    from . import gi, gi_settings
    from .screen_probes import trace_view

    cfg = gi_settings.from_scene(engine_settings(scene))
    if not cfg.enabled:
        cfg = gi_settings.settings("MEDIUM")
    g = gi._global_sdf(state, cfg)
    g.update(cam_pos, state.gi_frame, "objects" in state.last_changes)
    return trace_view(state.resources, g, state.surface_cache, state.sky, inv_vp, width, height,
                      min(float(clip_end), 100.0))


def _debug_image(view, state, gbuf, images, cam_pos, width, height, gi_cfg):
    """The image Combined shows for a debug view (a copy, alpha 1); `images`: the frame's
    read-back passes (a debug view is the only viewport frame that reads back)."""
    if view in CARD_VIEWS:
        shown = state.surface_cache.view(state.resources, gbuf, cam_pos, width, height,
                                         CARD_VIEWS[view])
        shown[shown[..., 3] < 0] = 0.0
    elif view == "PROBES" and gi_cfg.enabled and "filtered" in state.probes.textures:
        shown = _probe_atlas_image(state, width, height)   # (none with the per-pixel gather)
    elif view == "PROBE_FALLBACK" and gi_cfg.enabled:
        w = LAST_RENDER["indirect_irradiance"][..., 3]
        shown = np.zeros((height, width, 4), np.float32)
        shown[..., 0] = (w == 0).astype(np.float32)
        shown[..., 1] = (w > 0).astype(np.float32)
    elif view == "TRACE_METHOD" and "trace_method" in LAST_RENDER:
        shown = LAST_RENDER["trace_method"]
    elif view == "VOXEL_LIGHTING" and getattr(state, "voxel_lighting", None) is not None:
        shown = state.voxel_lighting.view(state.global_sdf, gbuf, cam_pos, width, height)
        shown[shown[..., 3] < 0] = 0.0
    elif view == "RADIANCE_CACHE" and getattr(state, "radiance_cache", None) is not None:
        shown = state.radiance_cache.view(gbuf, state.sky, cam_pos, width, height)
        shown[shown[..., 3] < 0] = 0.0
    else:
        shown = {"DIRECT": images["direct"], "INDIRECT": images["indirect"],
                 "ALBEDO": images["albedo"],
                 "NORMAL": (data_passes.shading_normal(images["position"], images["albedo"],
                                                       images["emission"])
                            if gbuf.get("shading_normals") else images["normal"]) * 0.5 + 0.5
                 }.get(view, images["combined"]).copy()
    shown = np.array(shown, np.float32)
    shown[..., 3] = 1.0
    return shown


def _probe_atlas_image(state, width, height):
    """The probe radiance atlas (one probe_res^2 tile per probe) scaled to the image size."""
    from . import compute

    t = state.probes.textures["filtered"]
    atlas = compute.read(t)
    ys = np.minimum((np.arange(height) * t.height) // height, t.height - 1)
    xs = np.minimum((np.arange(width) * t.width) // width, t.width - 1)
    img = atlas[ys][:, xs].copy()
    img[..., 3] = 1.0
    return img


def border_rect(render, width: int, height: int, size=None) -> tuple:
    """(x0, y0, x1, y1): the pixels of a width x height render that Blender's render result
    holds: the render border's (Render Region), else the whole image. The frame is rendered
    whole and this part written (rows bottom-up, as Blender's). The edges as Blender's render
    pipeline makes them: border x size in float32, truncated (in double, 0.7 x 710 gave 496
    where Blender has 497). size: the result's (w, h), which wins if they disagree."""
    if not getattr(render, "use_border", False):
        return 0, 0, width, height

    def span(lo, hi, n, want):
        a, b = (int(np.float32(v) * np.float32(n)) for v in (lo, hi))
        a = min(max(a, 0), n - 1)
        b = a + want if want else b
        return a, max(min(b, n), a + 1)

    x0, x1 = span(render.border_min_x, render.border_max_x, width, size and size[0])
    y0, y1 = span(render.border_min_y, render.border_max_y, height, size and size[1])
    return x0, y0, x1, y1


class LumenGIRenderEngine(bpy.types.RenderEngine):
    """Lumen GI preview engine: G-buffer + SDF direct light, or an SDF trace debug view."""

    bl_idname = "LUMEN_GI"
    bl_label = "Lumen GI"
    bl_use_gpu_context = True
    bl_use_preview = False

    def render(self, depsgraph):
        scene = depsgraph.scene
        scale = scene.render.resolution_percentage / 100.0
        width = max(1, int(scene.render.resolution_x * scale))
        height = max(1, int(scene.render.resolution_y * scale))
        LAST_RENDER.clear()
        LAST_RENDER["gpu_backend"] = gpu_backend()
        layer = depsgraph.view_layer.name
        for name, channels, chan_id, _ in PASSES:
            self.add_pass(name, channels, chan_id, layer=layer)
        extra = data_passes.wanted(depsgraph.view_layer)
        for _, name, channels, chan_id, _ in extra:
            self.add_pass(name, channels, chan_id, layer=layer)
        result = self.begin_result(0, 0, width, height, layer=layer)
        # An F12 render owns its GPU state, as a Cycles session does: made here, released
        # before render() returns (while its GPU context is current).
        state = SceneState()
        try:
            if scene.camera is None:
                raise RuntimeError(f"scene {scene.name!r} has no camera")
            vp, cam_pos, clip_end = view_projection(depsgraph, scene.camera, width, height)
            fr = frame(state, depsgraph, scene, vp, cam_pos, clip_end, width, height,
                       debug_view(scene), final=True)
            passes = {name: fr.pass_array(name)
                      for name in ("Combined",) + tuple(p[0] for p in PASSES)
                      if name == "Combined" or fr.textures}
            if fr.shading_normals and "Normal" in passes:   # the normal maps' shading normal
                g = fr.gbuffer
                passes["Normal"] = data_passes.shading_normal(
                    fr.read(g["position"]), fr.read(g["albedo"]), fr.read(g["emission"]))
            if extra and fr.gbuffer is not None:
                passes.update(_data_passes(fr, scene, extra))
            if getattr(scene.camera.data, "type", "PERSP") == 'PANO':
                LAST_RENDER.setdefault("notes", []).append(
                    f"camera {scene.camera.name!r} is panoramic: rendered as a perspective "
                    f"camera of its lens (Cycles renders panoramas)")
            for note in LAST_RENDER.get("notes", []):
                self.report({'WARNING'}, f"Lumen GI: {note}")
        except Exception as exc:   # reported, never raised into Blender's render job
            import traceback
            self.report({'ERROR'}, f"Lumen GI: {exc}")
            LAST_RENDER["error"] = str(exc)
            LAST_RENDER["traceback"] = traceback.format_exc()
            passes = {"Combined": np.zeros((height, width, 4), np.float32)}
        finally:
            # free its textures now, with the GPU context current (reference cycles included):
            # left to the collector they are freed later without one, and Blender crashes
            fr = state = None
            gc.collect()
        rl = result.layers[0]
        written = []
        x0, y0, x1, y1 = border_rect(scene.render, width, height,
                                     (result.resolution_x, result.resolution_y))
        for name, rgba in passes.items():
            rgba = rgba[y0:y1, x0:x1]      # a render border: Blender's result is only that part
            rp = rl.passes.find_by_name(name, "") if hasattr(rl.passes, "find_by_name") else None
            rp = rp or rl.passes.get(name)
            if rp is None:
                continue
            rp.rect = np.ascontiguousarray(rgba[..., :rp.channels], np.float32).reshape(
                -1, rp.channels)
            written.append(name)
        LAST_RENDER["passes_written"] = written
        self.end_result(result)

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", 'COLOR')
        for name, channels, chan_id, kind in PASSES:
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for _, name, channels, chan_id, kind in data_passes.wanted(renderlayer):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    def view_update(self, context, depsgraph):
        """Record what the depsgraph says changed; the next view_draw's frame() syncs the scene
        state, which re-uploads only the resources those changes touch."""
        flags = set()
        moves_only = True            # only objects moved (or the selection changed): the
                                     # direct light restarts locally (or not at all)
        moved = set()                # objects that only moved, none an instancer: the
                                     # extraction reads their matrices without a walk
        lights_only = True           # only lights (objects or data) changed: no mesh walk
        edited, materials, images = set(), set(), False   # for the staleness check's re-hashing
        meshes, unsure = set(), False                      # for the extraction cache
        for u in depsgraph.updates:
            ident = u.id
            # (a selection click updates the Scene alone, with no flag: the direct pass's
            # scene settings are in its key, direct_light.Progressive)
            moves_only = moves_only and not u.is_updated_geometry \
                and not u.is_updated_shading and (
                    isinstance(ident, bpy.types.Scene) and not u.is_updated_transform
                    or isinstance(ident, bpy.types.Object) and ident.type != 'LIGHT'
                    and u.is_updated_transform)
            lights_only = lights_only and (
                isinstance(ident, bpy.types.Light)
                or isinstance(ident, bpy.types.Object) and ident.type == 'LIGHT')
            if moved is not None and isinstance(ident, bpy.types.Object) \
                    and ident.type != 'LIGHT' and u.is_updated_transform \
                    and not u.is_updated_geometry and not u.is_updated_shading \
                    and not ident.is_instancer:
                moved.add(ident.name)
            else:
                moved = None
            if isinstance(ident, bpy.types.Object):
                if u.is_updated_transform:
                    flags.add("light" if ident.type == 'LIGHT' else "transform")
                if u.is_updated_geometry:
                    flags.add("geometry")
                    edited.add(ident.name)    # (not shading: selection is shading too)
                    data = getattr(ident.original, "data", None)
                    if isinstance(data, bpy.types.Mesh):
                        meshes.add(data.name)
            elif isinstance(ident, bpy.types.Light):
                flags.add("light")
            elif isinstance(ident, (bpy.types.Mesh, bpy.types.Material)):
                flags.add("geometry")
                if isinstance(ident, bpy.types.Material):
                    materials.add(ident.name)
                elif u.is_updated_geometry:  # (a material edit lists its meshes as shading)
                    meshes.add(ident.name)
            elif isinstance(ident, bpy.types.World):
                flags.add("world")
            elif isinstance(ident, bpy.types.Image):
                images = True
            elif u.is_updated_geometry and not isinstance(
                    ident, (bpy.types.Scene, bpy.types.Collection, bpy.types.Camera,
                            bpy.types.NodeTree)):
                unsure = True                # an ID we do not follow: read everything again
        if getattr(self, "_state", None) is None:
            self._state = SceneState()
        self._state.stale.mark(edited, materials, images)
        if moved:
            extraction(self._state).mark_moved(moved)
        elif lights_only and len(depsgraph.updates):
            extraction(self._state).mark_lights()
        else:
            extraction(self._state).mark(edited, meshes, materials, images, unsure)
        if len(depsgraph.updates):
            self._state.epoch += 1     # what was drawn may have changed
            if not moves_only:         # the direct light again (a move: where it reaches,
                self._state.direct_epoch += 1    # direct_light.Progressive)
        LAST_VIEW_UPDATE["flags"] = sorted(flags)
        LAST_VIEW_UPDATE["count"] = LAST_VIEW_UPDATE.get("count", 0) + 1
        if flags:
            self.tag_redraw()

    def view_draw(self, context, depsgraph):
        """The viewport: frame() at the region size for the view's matrices, its Combined
        texture drawn as it is on the GPU (no read-back, no upload) with the display colour
        transform (Blender's RenderEngine template). The engine instance lives as long as the
        viewport and owns the GPU state, so redraws upload only what changed."""
        import gpu
        from gpu_extras.batch import batch_for_shader

        from .resources import float_buffer

        scene = depsgraph.scene
        w, h = context.region.width, context.region.height
        # Blender's viewport Pixel Size (Render Properties > Performance, as Cycles and EEVEE):
        # the frame runs at 1/ps of the region per side and is drawn stretched over it.
        ps = pixel_size(scene, context)
        fw, fh = max(1, -(-w // ps)), max(1, -(-h // ps))
        rd = context.region_data
        if getattr(self, "_state", None) is None:
            self._state = SceneState()
        st = self._state
        view_proj = np.array(rd.perspective_matrix, np.float64)
        clip_end = float(context.space_data.clip_end)
        view = debug_view(scene)

        def still_key():        # what a converged frame was drawn for (epoch: any depsgraph update)
            return (view_proj.tobytes(), fw, fh, ps, clip_end, view, st.epoch)

        if st.still is not None and st.still[0] == still_key():
            # converged and nothing changed since: its Combined again, no pass run (a still
            # viewport's redraws, from the UI around it, cost a refining frame before)
            tex, stale = st.still[1], st.still[2]
            LAST_RENDER.update(pixel_size=ps, reused_frame=True, direct_part=None,
                               direct_restart=None)
            self._draw_texture(scene, tex, w, h)
            if stale:
                self._draw_stale(stale, w, h, 0)
            return
        try:
            fr = frame(st, depsgraph, scene, view_proj,
                       np.array(rd.view_matrix.inverted().translation, np.float64),
                       clip_end, fw, fh, view, final=False, pixel_size=ps)
        except Exception as exc:
            LAST_RENDER["error"] = str(exc)
            draw_message(f"Lumen GI: {exc}", w, h)
            return
        LAST_RENDER["pixel_size"] = ps
        aa = LAST_RENDER.get("aa_progress")
        if LAST_RENDER.get("gi_converged") is False or (aa is not None and aa[0] < aa[1]):
            self.tag_redraw()              # progressive: keep accumulating GI frames, AA samples
        st.still = ((still_key(), fr.textures["Combined"], list(LAST_RENDER.get("stale") or []))
                    if fr.converged and fr.shown is None else None)
        if fr.shown is not None:           # a debug view's image (computed on the CPU)
            tex = gpu.types.GPUTexture((fw, fh), format='RGBA16F', data=float_buffer(fr.shown))
        else:
            tex = fr.textures["Combined"]
        self._draw_texture(scene, tex, w, h)
        progress = LAST_RENDER.get("gi_progress") or (0, 0)
        if aa is not None:                 # GI frames first, then the anti-aliasing samples
            progress = (progress[0] + aa[0], progress[1] + aa[1])
        line = 0
        if progress[0] < progress[1]:
            draw_message(f"Lumen GI: refining {progress[0]}/{progress[1]}", w, h)
            line = 1
        stale = LAST_RENDER.get("stale")
        if stale:
            self._draw_stale(stale, w, h, line)

    def _draw_texture(self, scene, tex, w, h):
        """`tex` over the region (w x h px) with the display colour transform."""
        import gpu
        from gpu_extras.batch import batch_for_shader

        shader = gpu.shader.from_builtin('IMAGE')
        batch = batch_for_shader(shader, 'TRI_FAN', {
            "pos": ((0, 0), (w, 0), (w, h), (0, h)),
            "texCoord": ((0, 0), (1, 0), (1, 1), (0, 1))})
        gpu.state.blend_set('ALPHA_PREMULT')
        self.bind_display_space_shader(scene)
        shader.uniform_sampler("image", tex)
        batch.draw(shader)
        self.unbind_display_space_shader()
        gpu.state.blend_set('NONE')

    @staticmethod
    def _draw_stale(stale, w, h, line):
        draw_message(f"Lumen GI: {len(stale)} object{'s' if len(stale) != 1 else ''} changed "
                     f"since the bake: press Bake", w, h, line)


def register():
    bpy.utils.register_class(LumenGIRenderEngine)


def unregister():
    bpy.utils.unregister_class(LumenGIRenderEngine)
