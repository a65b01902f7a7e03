"""Benchmark: global-illumination quality of the LUMEN_GI engine against Cycles, in one process.

    .venv/bin/python bench/quality.py [--size 256] [--scenes cornell,window,thin]
        [--cycles-samples 1024] [--engines cycles_ref,cycles_4spp_oidn,eevee,eevee_rt,
        eevee_volume,lumen,lumen_high,lumen_ssgi,lumen_rsm,lumen_lpv,lumen_vxgi,lumen_off,
        lumen_rc,lumen_noscreen,lumen_screen,lumen_noaa,
        lumen_noadaptive] [--out out/quality]
        [--quick] [--verbose] [--keep-exr]

Scenes (bench/quality_scenes.py, built in code, pure Lambert materials): `cornell` (area light
in a Cornell box), `window` (a closed room lit by a sun through one window), `thin` (a closed
room with 1.5 cm walls and roof, under one SDF voxel, on a sunlit ground under a uniform sky;
its roof is invisible to the camera, which looks down into the room: Cycles shows the interior
black, so any light there is a leak), `yard` (open, lit only by the courtyard.exr HDRI) and
`glow` (a room of single-sided quads lit only by an emissive panel).

Engines, each rendering the scene camera at --size x --size with bpy.ops.render.render:
    cycles_ref        Cycles CPU, --cycles-samples (1024), no denoiser, no adaptive sampling,
                      default pixel filter (Blackman-Harris 1.5 px), clamps off, 12 bounces
                      (12 diffuse); cached in <out>/ref_<scene>_<hash>.exr, keyed by a hash of
                      the built scene's data and these settings, so a rerun reuses it
    cycles_4spp_oidn  the same with 4 samples + OpenImageDenoise (skipped when the build has no OIDN)
    eevee             BLENDER_EEVEE, default settings (64 samples, no ray tracing)
    eevee_rt          EEVEE with scene.eevee.use_raytracing = True, defaults otherwise
    eevee_volume      EEVEE defaults + an irradiance volume (light probe volume) over the room,
                      baked with bpy.ops.object.lightprobe_cache_bake(subset='ALL')
    lumen             bpy.ops.lumen.bake(), then LUMEN_GI, every setting at its default (what a
                      user gets without touching anything; per-object settings too: the roof is
                      not two-sided)
    lumen_high        the same with render_quality='HIGH', render_frames=16, bounces=3
    lumen_ssgi        GI Method SSGI (screen-space GI on an HZB, lecture 21), Medium, 8 frames
    lumen_rsm         GI Method RSM (reflective shadow maps, one bounce), Medium, 8 frames
    lumen_lpv         GI Method LPV (light propagation volumes, one bounce), Medium, default
                      cells and iterations (deterministic: one frame)
    lumen_vxgi        GI Method VXGI (voxel cone tracing over the voxel lighting), Medium, 8 frames
    lumen_off         GI Off (gi_quality='OFF'): direct light and the SDF-occluded sky only, the
                      floor every GI method must beat
    lumen_rc          lumen with the world radiance cache on (gpu_shaders/radiance_cache.py)
    lumen_noscreen    lumen without its first trace on the screen (screen_trace off): every
                      probe ray on the SDFs from its origin
    lumen_screen      lumen with the screen trace on (off by default)
    lumen_noaa        lumen without anti-aliasing (aa_samples 1: one G-buffer sample per pixel)
    lumen_noadaptive  lumen without adaptive screen probes (adaptive_probes off)
    lumen_res4/6/8    lumen with gi_settings.MIN_PROBE_RES 4, 6 or 8: the octahedral texels per
                      side a probe keeps when a small image halves the probe tile (4: the same
                      rays per pixel as the preset's tile; 8: every probe 64 rays)
    lumen_frames4/6   lumen with render_frames 4 or 6 (default 8)
    lumen_bounces5    lumen with bounces 5 (default 3: 2 surface-cache iterations before the gather)
    lumen_b5f6        lumen with bounces 5 and render_frames 6 (as many iterations as the default)
EEVEE and LUMEN_GI first render once at 32x32 (shader compilation, uploads): that warm-up is
reported apart from the timed render; so are the one-off bakes (light probes, Lumen).

Images are compared in scene-linear RGB (view transform Standard; each render is written as a
32-bit multilayer EXR and its Combined pass read back with OpenImageIO). Metrics against
cycles_ref over all pixels and RGB channels:
    relMSE  mean((x - ref)^2 / (ref^2 + 0.01))
    MAE     mean |x - ref|
    bias    mean lum(x) / mean lum(ref) - 1          (lum: Rec.709 weights)
    SSIM    mean SSIM (Wang et al. 2004, 11x11 Gaussian window) of the tone-mapped luminance,
            with the side-by-side images' exposure and tone map
    leak    `thin` only: mean lum(x) over the pixels where Cycles is black (lum < 1e-4) divided
            by mean lum(x) over the lit ones (the rest, background excluded)
The table is printed and written to <out>/results.json; <out>/all_scenes.png stacks the scenes'
images (a row per scene); <out>/<scene>.png shows the engines side
by side (left to right in the order printed), each exposure-normalised by the reference's mean
luminance, Reinhard-mapped and sRGB-encoded the same way. Blender's own render output goes to
<out>/blender.log (--verbose: to the terminal). An engine that fails is reported in its row and
the others continue. --quick: 64x64, 64 Cycles samples, cornell only (a smoke run). --keep-exr
keeps every engine's <out>/<scene>_<engine>.exr (bench/ssim_map.py reads them).
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import sys
import time
import traceback
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

import quality_scenes  # noqa: E402

ENGINES = ("cycles_ref", "cycles_4spp_oidn", "eevee", "eevee_rt", "eevee_volume", "lumen",
           "lumen_high", "lumen_ssgi", "lumen_rsm", "lumen_lpv", "lumen_vxgi",
           "lumen_off", "lumen_rc", "lumen_noscreen", "lumen_screen", "lumen_noaa",
           "lumen_noadaptive", "lumen_res4", "lumen_res6", "lumen_res8",
           "lumen_frames4", "lumen_frames6", "lumen_bounces5", "lumen_b5f6")
CYCLES_BOUNCES = dict(max_bounces=12, diffuse_bounces=12)
FAST_SAMPLES = 4
WARMUP_SIZE = 32
BLACK = 1e-4                          # luminance under which a Cycles pixel counts as black
EPS = 0.01                            # relMSE denominator term
LUM = np.array([0.2126, 0.7152, 0.0722])
# lumen: every setting at its default (what a user gets); lumen_high: the High preset. Overrides
# are scene.lumen.engine's properties
LUMEN_HIGH_SETTINGS = (("render_quality", "HIGH"), ("render_frames", 16), ("bounces", 3),
                       ("gi_method", "LUMEN"))
# the lecture's other methods on the same G-buffer and direct light (scene.lumen.engine.gi_method)
LUMEN_SSGI_SETTINGS = (("render_quality", "MEDIUM"), ("render_frames", 8), ("bounces", 3),
                       ("gi_method", "SSGI"))
LUMEN_RSM_SETTINGS = (("render_quality", "MEDIUM"), ("render_frames", 8), ("bounces", 3),
                      ("gi_method", "RSM"))
LUMEN_LPV_SETTINGS = (("render_quality", "MEDIUM"), ("gi_method", "LPV"))
LUMEN_VXGI_SETTINGS = (("render_quality", "MEDIUM"), ("render_frames", 8), ("bounces", 3),
                       ("gi_method", "VXGI"))
LUMEN_OFF_SETTINGS = (("render_quality", "OFF"), ("gi_method", "LUMEN"))


# Rendering -------------------------------------------------------------------------------------
class Log:
    """Blender's C-level stdout (render progress lines) goes to a log file during renders."""

    def __init__(self, path: Path | None):
        self.path = path
        self.fh = open(path, "a") if path else None

    @contextlib.contextmanager
    def quiet(self):
        if self.fh is None:
            yield
            return
        sys.stdout.flush()
        saved = os.dup(1)
        try:
            os.dup2(self.fh.fileno(), 1)
            yield
        finally:
            sys.stdout.flush()
            self.fh.flush()
            os.dup2(saved, 1)
            os.close(saved)


def say(*args):
    print(*args, flush=True)


def read_exr(path: Path) -> dict:
    """{pass name: float32 (H, W, C)} of a multilayer EXR (channels 'Layer.Pass.C')."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    out = {}
    try:
        sub = 0
        while inp.seek_subimage(sub, 0):
            spec = inp.spec()
            px = np.asarray(inp.read_image(sub, 0, 0, spec.nchannels, "float"), np.float32)
            px = px.reshape(spec.height, spec.width, spec.nchannels)
            groups = {}
            for i, name in enumerate(spec.channelnames):
                prefix, _, chan = name.rpartition(".")
                groups.setdefault(prefix.split(".", 1)[-1] if "." in prefix else prefix or "Combined",
                                  []).append((chan, i))
            for pname, chans in groups.items():
                order = "RGBAXYZVUW"
                chans.sort(key=lambda c: order.index(c[0]) if c[0] in order else 99)
                out[pname] = px[..., [i for _, i in chans]]
            sub += 1
    finally:
        inp.close()
    return out


def set_size(scene, size):
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100


def render(scene, path: Path, log: Log) -> tuple:
    """F12 into a 32-bit multilayer EXR at `path`: (wall seconds of the render call, passes)."""
    import bpy

    if path.exists():
        path.unlink()
    scene.render.filepath = str(path)
    t = time.perf_counter()
    with log.quiet():
        bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t
    if not path.exists():
        raise RuntimeError(f"the render wrote no image ({path.name})")
    return seconds, read_exr(path)


def warm_up(scene, path: Path, log: Log, samples_attr=None) -> float:
    """One render at WARMUP_SIZE (1 sample where the engine has a sample count): seconds."""
    size = scene.render.resolution_x
    saved = None
    if samples_attr is not None:
        owner, attr = samples_attr
        saved = getattr(owner, attr)
        setattr(owner, attr, 1)
    set_size(scene, WARMUP_SIZE)
    try:
        seconds, _ = render(scene, path, log)
    finally:
        set_size(scene, size)
        if saved is not None:
            setattr(samples_attr[0], samples_attr[1], saved)
        if path.exists():
            path.unlink()
    return seconds


def common_setup(scene, size):
    """Resolution, linear output (Standard view transform, 32-bit multilayer EXR)."""
    set_size(scene, size)
    vs = scene.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    im = scene.render.image_settings
    if hasattr(im, "media_type"):
        im.media_type = "MULTI_LAYER_IMAGE"
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    scene.render.use_file_extension = False


def cycles_settings(samples, denoise):
    s = dict(device="CPU", samples=samples, use_adaptive_sampling=False, use_denoising=denoise,
             sample_clamp_direct=0.0, sample_clamp_indirect=0.0, seed=1, **CYCLES_BOUNCES)
    if denoise:
        s["denoiser"] = "OPENIMAGEDENOISE"
    return s


def apply_cycles(scene, settings):
    scene.render.engine = "CYCLES"
    for k, v in settings.items():
        setattr(scene.cycles, k, v)


def scene_digest(scene) -> str:
    """sha256 of what the built scene renders from: objects (transforms, ray visibility, mesh
    vertices and faces, light and camera data), materials' node inputs, the world, the size."""
    h = hashlib.sha256()

    def put(*values):
        h.update(repr(values).encode())

    def node_inputs(tree):
        for node in sorted(tree.nodes, key=lambda n: n.name):
            vals = []
            for sock in node.inputs:
                v = getattr(sock, "default_value", None)
                if v is not None:
                    try:
                        v = tuple(round(float(x), 6) for x in v)
                    except TypeError:
                        v = round(float(v), 6) if isinstance(v, (int, float)) else str(v)
                vals.append((sock.identifier, v, sock.is_linked))
            put(node.bl_idname, node.name, vals)

    for obj in sorted(scene.objects, key=lambda o: o.name):
        put(obj.name, obj.type, [round(x, 6) for row in obj.matrix_world for x in row],
            obj.visible_camera, obj.visible_shadow, obj.hide_render)
        data = obj.data
        if obj.type == "MESH":
            co = np.empty(len(data.vertices) * 3, np.float32)
            data.vertices.foreach_get("co", co)
            h.update(co.tobytes())
            put([tuple(p.vertices) for p in data.polygons])
            for mat in data.materials:
                put(mat.name if mat else None)
                if mat and mat.node_tree:
                    node_inputs(mat.node_tree)
        elif obj.type == "LIGHT":
            put(data.type, tuple(data.color), data.energy,
                *(getattr(data, a, None) for a in ("size", "size_y", "shape", "angle",
                                                   "shadow_soft_size", "spot_size", "spot_blend")))
        elif obj.type == "CAMERA":
            put(data.type, data.lens, data.sensor_width, data.sensor_fit, data.clip_start,
                data.clip_end)
    world = scene.world
    if world is not None:
        put(tuple(world.color))
        if world.node_tree:
            node_inputs(world.node_tree)
    put(scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage)
    return h.hexdigest()


# Engines ---------------------------------------------------------------------------------------
class Skip(Exception):
    """The engine is unavailable here; the row says why."""


def run_cycles_ref(ctx):
    """The reference: two renders of half the samples each with seeds 1 and 2, averaged (the same
    estimate as one render of all samples); their difference estimates the reference's own
    noise: relMSE/MAE of the average against the converged image ~ mean(((a - b) / 2)^2 /
    (ref^2 + 0.01)) and mean |a - b| / 2."""
    import bpy

    scene, n = ctx["scene"], ctx["samples"]
    halves = [(1, n - n // 2), (2, n // 2)] if n >= 2 else [(1, n)]
    settings = [dict(cycles_settings(k, False), seed=seed) for seed, k in halves]
    key = hashlib.sha256(json.dumps(dict(scene=ctx["digest"], cycles=settings,
                                         version=bpy.app.version_string),
                                    sort_keys=True).encode()).hexdigest()[:16]
    exrs = [ctx["out"] / f"ref_{scene.name}_{key}_s{seed}.exr" for seed, _ in halves]
    meta = ctx["out"] / f"ref_{scene.name}_{key}.json"
    reused = False
    if meta.exists() and all(p.exists() for p in exrs):
        try:
            passes = [read_exr(p) for p in exrs]
            info = json.loads(meta.read_text())
            seconds, reused = info["seconds"], True
            say(f"  cycles_ref: reused {', '.join(p.name for p in exrs)} (rendered in "
                f"{seconds:.1f} s)")
        except Exception as exc:   # a broken cache is rendered again
            say(f"  cycles_ref: cache {meta.name} unreadable ({exc}); rendering")
    if not reused:
        vl = scene.view_layers[0]
        vl.use_pass_z = True                   # background mask (depth 1e10 where rays miss)
        passes, seconds = [], 0.0
        try:
            for s, p in zip(settings, exrs):
                apply_cycles(scene, s)
                sec, px = render(scene, p, ctx["log"])
                say(f"  cycles_ref: seed {s['seed']}, {s['samples']} samples: {sec:.1f} s")
                seconds += sec
                passes.append(px)
        finally:
            vl.use_pass_z = False
            scene.cycles.seed = 1
        meta.write_text(json.dumps(dict(seconds=seconds, settings=settings, scene=scene.name,
                                        digest=ctx["digest"], files=[p.name for p in exrs]),
                                   indent=1))
    images = [px["Combined"][..., :3].astype(np.float64) for px in passes]
    weights = [k for _, k in halves]
    ref = sum(w * im for w, im in zip(weights, images)) / sum(weights)
    out = dict(image=ref.astype(np.float32), depth=passes[0].get("Depth"), seconds=seconds,
               reused=reused, notes=[("reused " if reused else "cached as ") + meta.stem + "_s*.exr"])
    if len(images) == 2:
        d = (images[0] - images[1]) / 2.0
        out["noise"] = dict(rel_mse=float(np.mean(d ** 2 / (ref ** 2 + EPS))),
                            mae=float(np.mean(np.abs(d))))
        out["notes"].insert(0, f"{n} spp as 2 x {n // 2} (seeds 1, 2); relMSE/MAE here: the "
                               f"reference's own noise estimate")
    return out


def oidn_available():
    try:
        import _cycles
        return bool(getattr(_cycles, "with_openimagedenoise", False))
    except ImportError:
        return False


def run_cycles_fast(ctx):
    if not oidn_available():
        raise Skip("this bpy build has no OpenImageDenoise (_cycles.with_openimagedenoise False)")
    scene = ctx["scene"]
    settings = cycles_settings(FAST_SAMPLES, True)
    try:
        apply_cycles(scene, settings)
    except TypeError as exc:           # the enum lacks OPENIMAGEDENOISE (e.g. an old CPU)
        raise Skip(f"OpenImageDenoise cannot be selected: {exc}")
    try:
        seconds, passes = render(scene, ctx["path"], ctx["log"])
    finally:
        scene.cycles.use_denoising = False
    return dict(image=passes["Combined"][..., :3], seconds=seconds,
                notes=[f"{FAST_SAMPLES} spp + OIDN ({scene.cycles.denoising_input_passes}, "
                       f"prefilter {scene.cycles.denoising_prefilter})"])


def eevee_id():
    import bpy

    items = [i.identifier for i in
             bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items]
    return "BLENDER_EEVEE" if "BLENDER_EEVEE" in items else next(
        i for i in items if i.startswith("BLENDER_EEVEE"))


def eevee_render(ctx, raytracing, extra_notes=()):
    scene = ctx["scene"]
    scene.render.engine = eevee_id()
    default_rt = ctx["eevee_defaults"]["use_raytracing"]
    scene.eevee.use_raytracing = raytracing
    try:
        warm = warm_up(scene, ctx["path"], ctx["log"], (scene.eevee, "taa_render_samples"))
        seconds, passes = render(scene, ctx["path"], ctx["log"])
    finally:
        scene.eevee.use_raytracing = default_rt
    notes = [f"{scene.eevee.taa_render_samples} samples"] + list(extra_notes)
    if raytracing:
        notes.append(f"ray tracing {scene.eevee.ray_tracing_method.lower()}, fast GI "
                     f"{scene.eevee.fast_gi_method.lower()}")
    return dict(image=passes["Combined"][..., :3], seconds=seconds, warmup=warm, notes=notes)


def run_eevee(ctx):
    return eevee_render(ctx, False)


def run_eevee_rt(ctx):
    if not hasattr(ctx["scene"].eevee, "use_raytracing"):
        raise Skip("scene.eevee has no use_raytracing in this build")
    return eevee_render(ctx, True)


def bake_probe_volume(scene, probe):
    """Bake every light probe of the scene (the operator's exec path runs the bake job to the
    end in background mode). Returns (seconds, how it was called)."""
    import bpy

    scene.render.engine = eevee_id()
    view_layer = bpy.context.view_layer
    for obj in view_layer.objects:
        obj.select_set(False)
    probe.select_set(True)
    view_layer.objects.active = probe
    t = time.perf_counter()
    try:
        result = bpy.ops.object.lightprobe_cache_bake(subset='ALL')
        how = "plain call, probe selected and active"
    except RuntimeError as plain:
        try:
            with bpy.context.temp_override(object=probe, active_object=probe,
                                           selected_objects=[probe], scene=scene,
                                           view_layer=view_layer):
                result = bpy.ops.object.lightprobe_cache_bake(subset='ALL')
            how = f"context override (plain call failed: {plain})"
        except RuntimeError as exc:
            raise Skip(f"lightprobe_cache_bake cannot run headless: {str(exc).strip()}")
    seconds = time.perf_counter() - t
    if result != {'FINISHED'}:
        raise Skip(f"lightprobe_cache_bake returned {sorted(result)} in background mode")
    return seconds, how


def run_eevee_volume(ctx):
    import bpy

    scene = ctx["scene"]
    probe = quality_scenes.add_probe_volume(scene)
    try:
        res = probe.data
        with ctx["log"].quiet():
            bake_seconds, how = bake_probe_volume(scene, probe)
        half = "x".join(f"{2 * v:g}" for v in probe.scale)
        out = eevee_render(ctx, False, [f"probe grid {res.resolution_x}x{res.resolution_y}x"
                                        f"{res.resolution_z} over {half} m, bake: {how}"])
        out["bake"] = bake_seconds
        return out
    finally:
        bpy.data.objects.remove(probe)


def lumen_engine():
    return sys.modules["lumen_gi"].gpu_shaders.engine


def lumen_error():
    R = lumen_engine().LAST_RENDER
    if R.get("error"):
        return f"LAST_RENDER error: {R['error']}"
    return None


def run_lumen_high(ctx):
    return run_lumen(ctx, LUMEN_HIGH_SETTINGS)


def run_lumen(ctx, overrides=()):
    import bpy

    scene = ctx["scene"]
    notes = []
    settings = getattr(getattr(scene, "lumen", None), "engine", None)
    if settings is None:
        raise RuntimeError("scene.lumen.engine is missing: the add-on is not registered")
    for prop in settings.bl_rna.properties:       # every engine starts from the defaults
        if prop.identifier != "rna_type" and not prop.is_readonly:
            settings.property_unset(prop.identifier)
    if ctx.get("lumen_seed"):
        settings.seed = ctx["lumen_seed"]
        notes.append(f"seed {ctx['lumen_seed']}")
    for attr, value in overrides:
        if hasattr(settings, attr):
            try:
                setattr(settings, attr, value)
                notes.append(f"{attr}={value}")
            except (TypeError, ValueError) as exc:
                notes.append(f"{attr}: {exc}")
        else:
            notes.append(f"no {attr}")
    t = time.perf_counter()
    with ctx["log"].quiet():
        result = bpy.ops.lumen.bake()
    bake_seconds = time.perf_counter() - t
    if result != {'FINISHED'}:
        raise RuntimeError(f"lumen.bake returned {sorted(result)}: "
                           f"{scene.lumen.last_bake.status}")
    scene.render.engine = "LUMEN_GI"
    engine = lumen_engine()
    engine.KEEP_IMAGES = True        # hidden_drawn reads the G-buffer positions
    engine.LAST_RENDER.clear()
    warm = warm_up(scene, ctx["path"], ctx["log"])
    err = lumen_error()
    if err:
        raise RuntimeError(f"warm-up: {err}")
    compile_s = sum(v for k, v in engine.LAST_RENDER.items()
                    if "compile" in k and isinstance(v, (int, float)))
    engine.LAST_RENDER.clear()
    seconds, passes = render(scene, ctx["path"], ctx["log"])
    err = lumen_error()
    if err:
        raise RuntimeError(err)
    R = engine.LAST_RENDER
    seen = hidden_drawn(scene, R.get("position"))
    if seen:
        notes.append(seen)
    last = scene.lumen.last_bake
    notes.append(f"bake {last.objects} objects, {last.bricks} bricks, {last.cards} cards")
    if compile_s >= 0.005:
        notes.append(f"warm-up compile {compile_s:.2f} s")
    if R.get("gi_bounces"):
        notes.append(f"{R['gi_bounces']} bounces")
    if R.get("gi_frame_noise"):
        notes.append(f"{len(R['gi_frame_noise'])} frames, noise {R['gi_frame_noise'][-1]:.4f}")
    frame = {k: round(v, 3) for k, v in R.items()
             if k.endswith("_seconds") and isinstance(v, (int, float))}
    return dict(image=passes["Combined"][..., :3], seconds=seconds, warmup=warm,
                bake=bake_seconds, notes=notes, lumen_seconds=frame)


def hidden_drawn(scene, position, share=0.02):
    """A note when the engine's G-buffer (world positions, [h, w, >=3]) shows objects that are
    invisible to camera rays: the share of pixels inside such an object's world bounds."""
    import mathutils

    names = quality_scenes.CAMERA_HIDDEN.get(scene.name, ())
    if position is None or not names:
        return ""
    pos = np.asarray(position, np.float64)[..., :3].reshape(-1, 3)
    notes = []
    for name in names:
        obj = scene.objects.get(name)
        if obj is None or obj.visible_camera:
            continue
        corners = np.array([obj.matrix_world @ mathutils.Vector(c) for c in obj.bound_box])
        lo, hi = corners.min(0) - 1e-3, corners.max(0) + 1e-3
        inside = float(np.all((pos >= lo) & (pos <= hi), axis=1).mean())
        if inside > share:
            notes.append(f"G-buffer shows '{name}' (visible_camera False) on {inside:.0%} of pixels")
    return "; ".join(notes)


def run_lumen_rc(ctx):
    """lumen with the world radiance cache on (scene.lumen.engine.radiance_cache)."""
    return run_lumen(ctx, (("radiance_cache", True),))


def run_lumen_res(ctx, res):
    """lumen with gi_settings.MIN_PROBE_RES = res for this render (a module constant, no user
    setting), restored after."""
    gs = sys.modules["lumen_gi.gpu_shaders.gi_settings"]
    saved = gs.MIN_PROBE_RES
    gs.MIN_PROBE_RES = res
    try:
        out = run_lumen(ctx)
    finally:
        gs.MIN_PROBE_RES = saved
    out["notes"].append(f"probe res {lumen_engine().LAST_RENDER.get('gi_probe_res')}")
    return out


RUNNERS = {"cycles_ref": run_cycles_ref, "cycles_4spp_oidn": run_cycles_fast, "eevee": run_eevee,
           "eevee_rt": run_eevee_rt, "eevee_volume": run_eevee_volume, "lumen": run_lumen,
           "lumen_high": run_lumen_high,
           "lumen_bounces5": lambda ctx: run_lumen(ctx, (("bounces", 5),)),
           "lumen_b5f6": lambda ctx: run_lumen(ctx, (("bounces", 5), ("render_frames", 6))),
           "lumen_ssgi": lambda ctx: run_lumen(ctx, LUMEN_SSGI_SETTINGS),
           "lumen_rsm": lambda ctx: run_lumen(ctx, LUMEN_RSM_SETTINGS),
           "lumen_lpv": lambda ctx: run_lumen(ctx, LUMEN_LPV_SETTINGS),
           "lumen_vxgi": lambda ctx: run_lumen(ctx, LUMEN_VXGI_SETTINGS),
           "lumen_off": lambda ctx: run_lumen(ctx, LUMEN_OFF_SETTINGS),
           "lumen_rc": run_lumen_rc,
           "lumen_noscreen": lambda ctx: run_lumen(ctx, (("screen_trace", False),)),
           "lumen_screen": lambda ctx: run_lumen(ctx, (("screen_trace", True),)),
           "lumen_noaa": lambda ctx: run_lumen(ctx, (("aa_samples", 1),)),
           "lumen_noadaptive": lambda ctx: run_lumen(ctx, (("adaptive_probes", False),)),
           "lumen_res4": lambda ctx: run_lumen_res(ctx, 4),
           "lumen_res6": lambda ctx: run_lumen_res(ctx, 6),
           "lumen_res8": lambda ctx: run_lumen_res(ctx, 8),
           "lumen_frames4": lambda ctx: run_lumen(ctx, (("render_frames", 4),)),
           "lumen_frames6": lambda ctx: run_lumen(ctx, (("render_frames", 6),))}


# Metrics and images ----------------------------------------------------------------------------
def lum(img):
    return img[..., :3] @ LUM


def _gauss_blur(img, sigma=1.5, radius=5):
    """Separable Gaussian (11 taps, sigma 1.5: Wang et al.'s SSIM window), edges clamped."""
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    k /= k.sum()
    for axis in (0, 1):
        pad = [(0, 0)] * img.ndim
        pad[axis] = (radius, radius)
        p = np.pad(img, pad, mode="edge")
        img = sum(w * np.take(p, np.arange(i, i + img.shape[axis]), axis=axis)
                  for i, w in enumerate(k))
    return img


def ssim(x, ref) -> float:
    """Mean SSIM of the tone-mapped luminance (the side-by-side's exposure and Reinhard + sRGB,
    so it weighs what a viewer sees), Wang et al. 2004 with an 11x11 Gaussian window."""
    exposure = 0.5 / max(float(lum(ref).mean()), 1e-6)
    a, b = lum(tone_map(x, exposure)), lum(tone_map(ref, exposure))
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    ma, mb = _gauss_blur(a), _gauss_blur(b)
    va = _gauss_blur(a * a) - ma * ma
    vb = _gauss_blur(b * b) - mb * mb
    cov = _gauss_blur(a * b) - ma * mb
    s = ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2))
    return float(s.mean())


def metrics(x, ref, masks=None) -> dict:
    x, ref = x.astype(np.float64), ref.astype(np.float64)
    m = dict(rel_mse=float(np.mean((x - ref) ** 2 / (ref ** 2 + EPS))),
             mae=float(np.mean(np.abs(x - ref))),
             bias=float(lum(x).mean() / max(lum(ref).mean(), 1e-12) - 1.0),
             ssim=ssim(x, ref))
    if masks is not None:
        black, lit = masks
        lx = lum(x)
        m["leak"] = float(lx[black].mean() / max(lx[lit].mean(), 1e-12)) if black.any() else None
    return m


def thin_masks(ref, depth):
    """(black, lit) boolean masks from the reference: black = lum < BLACK; lit = the rest
    without the background (depth pass >= 1e9 where camera rays miss)."""
    lr = lum(ref)
    background = (depth[..., 0] >= 1e9) if depth is not None else np.zeros(lr.shape, bool)
    black = (lr < BLACK) & ~background
    lit = (lr >= BLACK) & ~background
    return black, lit


def tone_map(img, exposure):
    """Reinhard per channel after exposure, then the sRGB transfer function, in [0, 1]."""
    v = np.maximum(img[..., :3].astype(np.float64) * exposure, 0.0)
    v = v / (1.0 + v)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1.0 / 2.4) - 0.055)


def side_by_side(path: Path, tiles, ref) -> str:
    """[(label, image or None)] left to right, each tone-mapped with the same exposure (mean
    luminance of the reference -> 0.5 before Reinhard); a label strip above each tile."""
    import OpenImageIO as oiio

    h, w = ref.shape[:2]
    exposure = 0.5 / max(float(lum(ref).mean()), 1e-6)
    strip = 18 if w >= 128 else 12
    canvas = np.zeros((h + strip, w * len(tiles), 3), np.float32)
    for i, (_, img) in enumerate(tiles):
        if img is None or img.shape[:2] != (h, w):
            canvas[strip:, i * w:(i + 1) * w] = (0.35, 0.05, 0.05)      # failed / unavailable
        else:
            canvas[strip:, i * w:(i + 1) * w] = tone_map(img, exposure)
    buf = oiio.ImageBuf(canvas)
    for i, (label, _) in enumerate(tiles):
        try:
            oiio.ImageBufAlgo.render_text(buf, i * w + 3, strip - 4, label, strip - 5, "",
                                          (1.0, 1.0, 1.0))
        except Exception:   # drawing text is optional (no font found)
            pass
    buf.geterror()
    out = oiio.ImageBuf()
    oiio.ImageBufAlgo.copy(out, buf, oiio.UINT8)
    if not out.write(str(path)):
        return f"PNG not written: {out.geterror()}"
    return ""


def stack_rows(path: Path, parts) -> str:
    """The scenes' side-by-side PNGs one under the other (the README's figure of every engine on
    every scene); rows narrower than the widest are padded black."""
    import OpenImageIO as oiio

    imgs = []
    for p in parts:
        if Path(p).exists():
            buf = oiio.ImageBuf(str(p))
            px = buf.get_pixels(oiio.UINT8)
            if px is not None and px.size:
                imgs.append(np.asarray(px)[..., :3])
    if not imgs:
        return "no scene images"
    width = max(i.shape[1] for i in imgs)
    canvas = np.concatenate([np.pad(i, ((0, 0), (0, width - i.shape[1]), (0, 0))) for i in imgs])
    out = oiio.ImageBuf(oiio.ImageSpec(canvas.shape[1], canvas.shape[0], 3, oiio.UINT8))
    out.set_pixels(oiio.ROI(0, canvas.shape[1], 0, canvas.shape[0], 0, 1, 0, 3),
                   np.ascontiguousarray(canvas))
    if not out.write(str(path)):
        return f"PNG not written: {out.geterror()}"
    return ""


# Main ------------------------------------------------------------------------------------------
def fmt(v, spec, none="-"):
    return none if v is None else format(v, spec)


def print_table(rows):
    head = (f"{'scene':8s} {'engine':17s} {'seconds':>8s} {'warm-up':>8s} {'bake':>7s} "
            f"{'relMSE':>9s} {'MAE':>8s} {'SSIM':>7s} {'bias':>8s} {'leak':>8s}  notes")
    say(head)
    say("-" * len(head))
    for r in rows:
        if r.get("error") or r.get("skipped"):
            state = "SKIPPED" if r.get("skipped") else "FAILED"
            say(f"{r['scene']:8s} {r['engine']:17s} {state}: {r.get('error') or r.get('skipped')}")
            continue
        leak = r.get("leak")
        say(f"{r['scene']:8s} {r['engine']:17s} {fmt(r.get('seconds'), '8.2f', '       -')} "
            f"{fmt(r.get('warmup'), '8.2f', '       -')} {fmt(r.get('bake'), '7.2f', '      -')} "
            f"{fmt(r.get('rel_mse'), '9.4f', '        -')} {fmt(r.get('mae'), '8.4f', '       -')} "
            f"{fmt(r.get('ssim'), '7.4f', '      -')} "
            f"{fmt(r.get('bias'), '+8.1%', '       -')} "
            f"{fmt(None if leak is None else leak, '8.2%', '       -')}"
            f"  {'; '.join(r.get('notes', []))}")


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--scenes", default=",".join(quality_scenes.SCENES))
    ap.add_argument("--cycles-samples", type=int, default=1024)
    ap.add_argument("--engines", default=",".join(ENGINES))
    ap.add_argument("--out", default=str(ROOT / "out" / "quality"))
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: --size 64 --cycles-samples 64 --scenes cornell")
    ap.add_argument("--verbose", action="store_true", help="Blender's render output to the terminal")
    ap.add_argument("--lumen-seed", type=int, default=0,
                    help="our engines' Seed (scene.lumen.engine.seed): rerun with others to see "
                         "how much of a relMSE change is noise")
    ap.add_argument("--keep-exr", action="store_true",
                    help="keep every engine's <out>/<scene>_<engine>.exr (for bench/ssim_map.py)")
    args = ap.parse_args(argv)
    if args.quick:
        args.size, args.cycles_samples, args.scenes = 64, 64, "cornell"
    args.scenes = [s for s in args.scenes.split(",") if s]
    args.engines = [e for e in args.engines.split(",") if e]
    for s in args.scenes:
        if s not in quality_scenes.SCENES:
            ap.error(f"unknown scene {s!r} (known: {', '.join(quality_scenes.SCENES)})")
    for e in args.engines:
        if e not in ENGINES:
            ap.error(f"unknown engine {e!r} (known: {', '.join(ENGINES)})")
    if "cycles_ref" not in args.engines:      # the metrics need it (reused from the cache if there)
        args.engines.insert(0, "cycles_ref")
    args.engines = [e for e in ENGINES if e in args.engines]
    return args


def write_results(out: Path, args, env, rows, wall) -> None:
    """results.json (after every scene too: a run stopped half-way keeps what it measured),
    written through a temporary file."""
    tmp = out / "results.json.tmp"
    tmp.write_text(json.dumps(dict(
        size=args.size, cycles_samples=args.cycles_samples, scenes=args.scenes,
        engines=args.engines, wall_seconds=wall, environment=env, rows=rows,
        metrics_doc=dict(rel_mse=f"mean((x-ref)^2/(ref^2+{EPS}))", mae="mean |x-ref|",
                         bias="mean lum(x)/mean lum(ref)-1",
                         ssim="mean SSIM of tone-mapped luminance, 11x11 Gaussian window",
                         leak=f"thin: mean lum over ref lum<{BLACK} / mean lum over lit px")),
        indent=1, default=str))
    tmp.replace(out / "results.json")


def main(argv=None):
    args = parse_args(argv)
    start = time.perf_counter()
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    log = Log(None if args.verbose else out / "blender.log")
    say(f"quality: {args.size}x{args.size}, scenes {', '.join(args.scenes)}, Cycles reference "
        f"{args.cycles_samples} spp, engines (image order, left to right): {', '.join(args.engines)}")
    say(f"output: {out} (Blender's render output: {log.path or 'terminal'})")

    import bpy
    import demo

    with log.quiet():
        demo.load_addon()
    say(f"Blender {bpy.app.version_string}; OpenImageDenoise in this build: {oidn_available()}")
    rows, env = [], dict(blender=bpy.app.version_string, oidn=oidn_available())
    for name in args.scenes:
        say(f"[{name}] building")
        try:
            with log.quiet():
                scene = quality_scenes.build(name)
        except FileNotFoundError as exc:     # a scene that needs ../shared/meshes, absent here
            say(f"[{name}] skipped: {exc}")
            continue
        common_setup(scene, args.size)
        scene.lumen.bake.cache_dir = str(out / "lumen_cache" / name)
        ctx = dict(scene=scene, out=out, log=log, samples=args.cycles_samples,
                   lumen_seed=args.lumen_seed,
                   digest=scene_digest(scene), eevee_defaults=dict(
                       use_raytracing=scene.eevee.use_raytracing))
        results = {}
        for eng in args.engines:
            ctx["path"] = out / f"{name}_{eng}.exr"
            say(f"[{name}] {eng} ...")
            t = time.perf_counter()
            try:
                res = RUNNERS[eng](ctx)
            except Skip as exc:
                res = dict(skipped=str(exc))
            except Exception as exc:
                res = dict(error=f"{type(exc).__name__}: {exc}",
                           traceback=traceback.format_exc())
            res["wall"] = time.perf_counter() - t
            results[eng] = res
            if "image" in res:
                img = res["image"]
                if not np.isfinite(img).all():
                    res["notes"] = res.get("notes", []) + [
                        f"{int((~np.isfinite(img)).any(-1).sum())} non-finite pixels set to 0"]
                    res["image"] = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
                parts = [f"render {res['seconds']:.2f} s"]
                for k in ("warmup", "bake"):
                    if res.get(k) is not None:
                        parts.append(f"{k} {res[k]:.2f} s")
                say(f"[{name}] {eng}: " + ", ".join(parts) + f" (step {res['wall']:.1f} s)")
            else:
                say(f"[{name}] {eng}: {'SKIPPED' if 'skipped' in res else 'FAILED'}: "
                    f"{res.get('skipped') or res.get('error')}")
                if "traceback" in res:
                    say(res["traceback"].rstrip())
        base, vol = results.get("eevee", {}), results.get("eevee_volume", {})
        if "image" in base and "image" in vol:      # did the baked volume change anything?
            change = lum(vol["image"]).mean() / max(lum(base["image"]).mean(), 1e-12) - 1.0
            vol.setdefault("notes", []).append(f"mean lum vs eevee {change:+.1%}")
        ref = results.get("cycles_ref", {}).get("image")
        masks = None
        if ref is not None and name == "thin":
            masks = thin_masks(ref, results["cycles_ref"].get("depth"))
            say(f"[{name}] mask: {int(masks[0].sum())} black px, {int(masks[1].sum())} lit px, "
                f"{int(masks[0].size - masks[0].sum() - masks[1].sum())} background px")
            np.save(out / "thin_mask.npy", masks[0].astype(np.uint8) + 2 * masks[1].astype(np.uint8))
        for eng in args.engines:
            res = results[eng]
            row = dict(scene=name, engine=eng)
            for k in ("seconds", "warmup", "bake", "reused", "skipped", "error", "notes",
                      "lumen_seconds"):
                if k in res:
                    row[k] = res[k]
            if eng == "cycles_ref" and "noise" in res:
                row.update(res["noise"], bias=0.0, noise_estimate=True)
                if masks is not None:
                    row["leak"] = metrics(res["image"], ref, masks)["leak"]
            elif "image" in res:
                if ref is None:
                    row.setdefault("notes", []).append("no reference: no metrics")
                else:
                    row.update(metrics(res["image"], ref, masks))
            rows.append(row)
        if ref is not None:
            tiles = [(eng, results[eng].get("image")) for eng in args.engines]
            err = side_by_side(out / f"{name}.png", tiles, ref)
            say(f"[{name}] image: {out / (name + '.png')} (left to right: "
                f"{', '.join(args.engines)}){' ' + err if err else ''}")
        for eng in args.engines:        # the per-engine EXRs are scratch (the reference is cached)
            p = out / f"{name}_{eng}.exr"
            if eng != "cycles_ref" and p.exists() and not args.keep_exr:
                p.unlink()
        write_results(out, args, env, rows, time.perf_counter() - start)
    if len(args.scenes) > 1:
        err = stack_rows(out / "all_scenes.png", [out / f"{n}.png" for n in args.scenes])
        say(f"figure: {out / 'all_scenes.png'} (a row per scene){' ' + err if err else ''}")
    wall = time.perf_counter() - start
    say("")
    print_table(rows)
    say(f"\nwall time {wall:.1f} s; seconds = the timed render call; warm-up = one {WARMUP_SIZE}x"
        f"{WARMUP_SIZE} render before it (shader compilation); bake = one-off bake (light probes / "
        f"lumen.bake); leak = mean lum over Cycles-black px / mean lum over lit px")
    write_results(out, args, env, rows, wall)
    say(f"results: {out / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
