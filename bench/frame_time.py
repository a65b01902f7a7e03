"""Benchmark: frame time of the Lumen GI preview engine vs EEVEE, same scene, same resolution,
same process, on this machine's GPU (Mesa llvmpipe headless).

Scene: a 6 x 6 m floor, a cube, a UV sphere, a cylinder and a monkey, a sun and a point light,
baked with bpy.ops.lumen.bake. Each engine renders `--size` x `--size` with bpy.ops.render.render:
one warm-up render (shader compilation, first uploads), then `--repeat` timed renders; the median
is printed. EEVEE keeps its default settings except 1 render sample (a viewport-like frame).
Our engine's steady state re-uploads nothing (scene_state.SceneState) and runs one frame of
everything a viewport redraw runs: G-buffer, direct light with SDF shadows and one GI iteration
(surface cache direct + radiosity probes + screen probes; `--quality`, render_frames = bounces = 1,
so F12 does exactly one GI frame). A converged F12 render is render_frames + bounces - 1 of those.

With `--trace` it also times the GI tracer alone (glsl/gi_trace_lib.glsl, one ray per pixel from
the scene camera, read back so the time is the GPU's), its global-SDF hits read from voxel
lighting and, in the same process, refined on every mesh SDF as before voxel lighting; and one
update of all four voxel-lighting levels (the per-object cost that voxel lighting moves there).

With `--compare` it also renders LUMEN_GI with voxel lighting off and on, alternately (`--repeat`
each, same process: what the shared machine's load does to one does to the other), and prints
both medians with their screen-probe and surface-cache times. Off: every global-SDF hit is
refined on the mesh SDFs, as before voxel lighting (GISettings.voxel_lighting, set by patching
gi_settings.from_scene for the bench: the scene has no property for it).

With `--viewport W H` it also times the viewport path: the engine's own view_draw at W x H
(tools/viewport_harness.py: offscreen, duck-typed context, one GI iteration per redraw) at viewport
Pixel Size 1 and 2, against EEVEE's 1-sample render at W x H: Progressive.FRAMES + --repeat redraws
of a still camera, the median of all but the first and apart, of those while the progressive
direct light still adds a part and of those after it.

With `--radiance-cache` it also renders with the world radiance cache (radiance_cache.py) off
and on: F12 one-GI-frame renders alternately (an F12 render starts with an empty cache: the
first frame) and `--repeat` + 1 view_draw redraws of the still camera at --size (the cache kept,
rc_budget probes re-traced per redraw), printing frame, GI and screen-probe medians and ratios.
`--screen-trace` does the same with Lumen's first trace on the screen (screen_trace.py) off and
on.

    ./lumen bench frame_time [--size 256] [--repeat 5] [--extra-objects N] [--trace] [--compare]
                             [--viewport 640 360] [--radiance-cache] [--screen-trace]
"""
from __future__ import annotations

import argparse
import statistics

import numpy as np
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))


def build_scene(tmp: Path, size: int, extra: int = 0):
    import bpy
    import mathutils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    def material(name, base):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*base, 1.0)
        return mat

    ops = bpy.ops.mesh
    ops.primitive_plane_add(size=6.0, location=(0, 0, 0))
    ops.primitive_cube_add(size=1.0, location=(-1.2, 0.3, 0.5))
    ops.primitive_uv_sphere_add(radius=0.6, location=(0.4, -0.4, 0.6))
    ops.primitive_cylinder_add(radius=0.35, depth=1.4, location=(1.5, 0.9, 0.7))
    ops.primitive_monkey_add(size=0.9, location=(-0.2, 1.4, 0.6))
    colours = ((0.8, 0.8, 0.8), (0.8, 0.2, 0.2), (0.2, 0.7, 0.3), (0.2, 0.3, 0.8), (0.8, 0.7, 0.2))
    for obj, c in zip(list(scene.objects), colours):
        obj.data.materials.append(material(obj.name + "Mat", c))
    side = max(int(np.ceil(np.sqrt(extra))), 1)
    for i in range(extra):      # unique meshes (own cards) on a grid around the floor, to 20 m
        x, y = (i % side) / max(side - 1, 1) * 40.0 - 20.0, (i // side) / max(side - 1, 1) * 40.0 - 20.0
        if abs(x) < 4.0 and abs(y) < 4.0:
            x += 8.0
        ops.primitive_cube_add(size=0.8, location=(x, y, 0.4))
        bpy.context.object.data.materials.append(material(f"Extra{i}", colours[i % 5]))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.8)
    point = bpy.data.objects.new("Point", bpy.data.lights.new("Point", "POINT"))
    point.data.energy = 400.0
    point.location = (1.0, -1.5, 2.5)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    for obj in (sun, point, cam):
        scene.collection.objects.link(obj)
    cam.location = (3.5, -5.0, 3.5)
    cam.rotation_euler = (mathutils.Vector((0, 0, 0.4)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    scene.camera = cam
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.05, 0.05, 0.06)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def time_renders(repeat: int) -> list:
    import bpy

    times = []
    for _ in range(repeat + 1):
        t = time.perf_counter()
        bpy.ops.render.render()
        times.append(time.perf_counter() - t)
    return times


def compare_voxel_lighting(repeat: int) -> dict:
    """{True: [(seconds, gi_timings)], False: [...]}: renders with voxel lighting on / off,
    alternately (see the module docstring, --compare)."""
    import dataclasses

    import bpy
    from lumen_gi.gpu_shaders import engine, gi_settings

    original = gi_settings.from_scene
    runs = {False: [], True: []}
    try:
        for _ in range(repeat):
            for on in (False, True):
                gi_settings.from_scene = (lambda s, viewport=False, on=on: dataclasses.replace(
                    original(s, viewport), voxel_lighting=on))
                t = time.perf_counter()
                bpy.ops.render.render()
                runs[on].append((time.perf_counter() - t, dict(engine.LAST_RENDER["gi_timings"])))
    finally:
        gi_settings.from_scene = original
    return runs


def compare_setting(scene, size: int, repeat: int, field: str) -> dict:
    """A GISettings bool off / on (`field`: radiance_cache, screen_trace; patched into
    gi_settings.from_scene as --compare does): F12 one-GI-frame renders alternately (with the
    radiance cache, each starts with an empty cache: the first frame, every probe it needs
    traced) and view_draw at size x size (tools/viewport_harness.py: a still camera, `repeat` + 1
    redraws; the radiance cache kept across them and rc_budget probes re-traced per redraw).
    Returns {on: {'f12': [(s, gi_timings)], 'view': [(s, gi_timings)]}}."""
    import dataclasses

    import bpy
    import viewport_harness
    from lumen_gi.gpu_shaders import engine, gi_settings

    original = gi_settings.from_scene
    runs = {False: {"f12": [], "view": []}, True: {"f12": [], "view": []}}
    try:
        for _ in range(repeat):
            for on in (False, True):
                gi_settings.from_scene = (lambda s, viewport=False, on=on: dataclasses.replace(
                    original(s, viewport), **{field: on}))
                t = time.perf_counter()
                bpy.ops.render.render()
                runs[on]["f12"].append((time.perf_counter() - t,
                                        dict(engine.LAST_RENDER["gi_timings"])))
        scene.lumen.engine.viewport_quality = scene.lumen.engine.render_quality
        for on in (False, True):
            gi_settings.from_scene = (lambda s, viewport=False, on=on: dataclasses.replace(
                original(s, viewport), **{field: on}))
            out = viewport_harness.run(
                scene, engine.LumenGIRenderEngine, size, size, redraws=repeat + 1,
                on_redraw=lambda i: dict(engine.LAST_RENDER.get("gi_timings", {})))
            runs[on]["view"] = list(zip(out["seconds"], out["after"]))
    finally:
        gi_settings.from_scene = original
    return runs


def trace_bench(scene, size: int, repeat: int, quality: str) -> dict:
    """See the module docstring (--trace). Runs inside a tiny RenderEngine (a GPU context)."""
    import bpy

    out = {}

    def job(depsgraph):
        from lumen_gi.gpu_shaders import engine, gi_settings
        from lumen_gi.gpu_shaders.global_sdf import GlobalSDF
        from lumen_gi.gpu_shaders.resources import SceneResources, float_buffer
        from lumen_gi.gpu_shaders.screen_probes import trace_view
        from lumen_gi.gpu_shaders.sky_light import SkyLight
        from lumen_gi.gpu_shaders.surface_cache import SurfaceCache
        from lumen_gi.gpu_shaders.voxel_lighting import VoxelLighting
        from lumen_gi.lumen_addon import sky as sky_maps
        import gpu

        bake, _ = engine.scene_bake(scene)
        preset = gi_settings.PRESETS[quality if quality != "OFF" else "MEDIUM"]
        res = SceneResources.from_bake(bake)
        cache = SurfaceCache(bake.atlas, [i.cards for i in bake.instances])
        lights = gpu.types.GPUTexture((4, 1), format='RGBA32F', data=float_buffer([0.0] * 16))
        cache.light_direct(res, lights, 0)
        cache.combine(res)
        vp, cam, _ = engine.view_projection(depsgraph, scene.camera, size, size)
        inv = np.linalg.inv(vp)
        gsdf = GlobalSDF(res, n=preset["gsdf_n"], base_voxel=preset["gsdf_voxel"])
        gsdf.update(cam, 0)
        voxels = VoxelLighting(gsdf.n)
        sky = SkyLight()
        sky.update(sky_maps.constant(tuple(scene.world.color)))
        updates = []
        for _ in range(repeat + 1):
            t = time.perf_counter()
            voxels.update(res, gsdf, cache, 0, everything=True)
            voxels.read_count()                              # waits for the GPU
            updates.append(time.perf_counter() - t)
        for name, v in (("voxel", voxels), ("refined", None)):
            times = []
            for _ in range(repeat + 1):                      # the first compiles
                t = time.perf_counter()
                o = trace_view(res, gsdf, cache, sky, inv, size, size, 100.0, voxels=v)
                times.append(time.perf_counter() - t)
            out[name] = statistics.median(times[1:])
            if v is not None:
                out["global"] = float(o["global"].mean())
                out["served"] = float(o["voxel"][o["global"]].mean()) if o["global"].any() else 1.0
        out["update"] = statistics.median(updates[1:])

    class TraceBench(bpy.types.RenderEngine):
        bl_idname = "LUMEN_TRACE_BENCH"
        bl_label = "gi_trace bench"
        bl_use_gpu_context = True

        def render(self, depsgraph):
            import traceback
            try:
                job(depsgraph)
            except Exception:
                out["error"] = traceback.format_exc()
            result = self.begin_result(0, 0, 4, 4)
            self.end_result(result)

    bpy.utils.register_class(TraceBench)
    before = (scene.render.engine, scene.render.resolution_x, scene.render.resolution_y)
    scene.render.engine = TraceBench.bl_idname
    scene.render.resolution_x = scene.render.resolution_y = 4
    try:
        bpy.ops.render.render()
    finally:
        scene.render.engine, scene.render.resolution_x, scene.render.resolution_y = before
        bpy.utils.unregister_class(TraceBench)
    if "error" in out:
        raise SystemExit(out["error"])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quality", default="MEDIUM", choices=("OFF", "LOW", "MEDIUM", "HIGH"))
    ap.add_argument("--extra-objects", type=int, default=0,
                    help="unique cubes added on a 40 m grid (more cards: the surface-cache budget)")
    ap.add_argument("--compare", action="store_true",
                    help="also render with voxel lighting off and on, alternately")
    ap.add_argument("--radiance-cache", action="store_true",
                    help="also render with the world radiance cache off and on: F12 (first "
                    "frame) alternately, and still-camera view_draw redraws")
    ap.add_argument("--screen-trace", action="store_true",
                    help="also render with Lumen's screen trace off and on, as --radiance-cache")
    ap.add_argument("--trace", action="store_true",
                    help="also time gi_trace per camera ray: voxel lighting vs mesh refinement")
    ap.add_argument("--viewport", type=int, nargs=2, metavar=("W", "H"),
                    help="also time view_draw at W x H (Pixel Size 1 and 2) against EEVEE at W x H")
    args = ap.parse_args()

    import tempfile

    import bpy
    import demo

    with tempfile.TemporaryDirectory() as tmp:
        demo.load_addon()
        scene = build_scene(Path(tmp), args.size, args.extra_objects)
        scene.lumen.bake.cache_dir = str(Path(tmp) / "cache")
        scene.lumen.bake.voxel_density = 16.0
        t = time.perf_counter()
        bpy.ops.lumen.bake()
        bake_seconds = time.perf_counter() - t
        from lumen_gi.gpu_shaders import engine

        scene.render.engine = "LUMEN_GI"
        scene.lumen.engine.render_quality = args.quality
        scene.lumen.engine.render_frames = 1
        scene.lumen.engine.bounces = 1
        scene.lumen.engine.converge_bounces = False     # exactly one GI iteration
        ours = time_renders(args.repeat)
        R = engine.LAST_RENDER
        if "error" in R:
            raise SystemExit(R.get("traceback", R["error"]))
        breakdown = {k: round(R[k] * 1000, 1) for k in ("extract_seconds", "sync_seconds",
                                                         "gbuffer_seconds", "direct_seconds")
                     if k in R}
        if "gi_timings" in R:
            breakdown.update({"gi_" + k: round(v * 1000, 1) for k, v in R["gi_timings"].items()})
        trace = trace_bench(scene, args.size, args.repeat, args.quality) if args.trace else None
        compare = compare_voxel_lighting(args.repeat) if args.compare else None
        toggles = {}
        for field in ("radiance_cache", "screen_trace"):
            if getattr(args, field):
                toggles[field] = compare_setting(scene, args.size, args.repeat, field)
        viewport = {}
        if args.viewport:
            import viewport_harness
            vw, vh = args.viewport
            scene.lumen.engine.viewport_quality = args.quality
            def gi_state(i):
                R = engine.LAST_RENDER
                t = R.get("gi_timings", {})
                return (t.get("sc_indirect", 0.0), R.get("gi_sc_tiles", (0, 0)),
                        R.get("direct_part") is not None)
            from lumen_gi.gpu_shaders import direct_light
            for label, ps, texels in (("Pixel Size 1", "1", 0), ("Pixel Size 2", "2", 0),
                                      ("Pixel Size 2, no cache budget", "2", 1 << 30)):
                scene.render.preview_pixel_size = ps
                scene.lumen.engine.cache_texels_per_frame = texels
                # enough redraws for the progressive direct light to finish, then `repeat` more
                out = viewport_harness.run(
                    scene, engine.LumenGIRenderEngine, vw, vh,
                    redraws=direct_light.Progressive.FRAMES + args.repeat, on_redraw=gi_state)
                viewport[label] = (out["seconds"], out["after"])
            scene.lumen.engine.cache_texels_per_frame = 0
        eevee_id = [i.identifier for i in
                    bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
                    if i.identifier.startswith("BLENDER_EEVEE")][0]
        scene.render.engine = eevee_id
        scene.eevee.taa_render_samples = 1
        eevee = time_renders(args.repeat)
        if args.viewport:
            scene.render.resolution_x, scene.render.resolution_y = args.viewport
            eevee_view = time_renders(args.repeat)

    m_ours, m_eevee = statistics.median(ours[1:]), statistics.median(eevee[1:])
    print(f"scene: {len(scene.objects)} objects, {R['triangles']} triangles, bake "
          f"{bake_seconds:.2f} s, {args.size}x{args.size}, {args.repeat} timed renders each")
    print(f"LUMEN_GI       warm-up {ours[0] * 1000:8.1f} ms, median {m_ours * 1000:8.1f} ms "
          f"(last frame ms: {breakdown}, uploads {R['uploads']})")
    print(f"{eevee_id:14s} warm-up {eevee[0] * 1000:8.1f} ms, median {m_eevee * 1000:8.1f} ms "
          f"(1 render sample)")
    print(f"ratio LUMEN_GI / {eevee_id} = {m_ours / m_eevee:.3f}")
    if "voxel_lighting" in R.get("gpu_bytes", {}):
        print(f"voxel lighting GPU memory: {R['gpu_bytes']['voxel_lighting'] / 2 ** 20:.1f} MiB "
              f"(+ {R['gpu_bytes']['voxel_lighting_tiles'] / 2 ** 20:.2f} MiB tile lists)")
    if compare:
        def med(on, key=None):
            return statistics.median(r[0] if key is None else r[1][key] for r in compare[on]) * 1000
        print(f"voxel lighting off / on, alternately, {args.repeat} each: frame {med(False):.1f} / "
              f"{med(True):.1f} ms (x{med(False) / med(True):.2f}), screen probes "
              f"{med(False, 'probes'):.1f} / {med(True, 'probes'):.1f} ms, surface-cache "
              f"radiosity {med(False, 'sc_indirect'):.1f} / {med(True, 'sc_indirect'):.1f} ms, "
              f"voxel update - / {med(True, 'voxel_lighting'):.1f} ms; each run's frame ms: "
              f"off {[round(r[0] * 1000) for r in compare[False]]}, "
              f"on {[round(r[0] * 1000) for r in compare[True]]}")
    for field, rcache in toggles.items():
        name = field.replace("_", " ")

        def rc_med(on, kind, key=None, first=False):
            rows = rcache[on][kind]
            rows = rows[:1] if first else (rows[1:] if kind == "view" else rows)
            return statistics.median(r[0] if key is None else r[1].get(key, 0.0)
                                     for r in rows) * 1000
        for kind, label in (("f12", "F12, one GI frame, empty cache (first frame)"),
                            ("view", f"view_draw {args.size}x{args.size}, still camera, "
                                     f"redraws 2..{args.repeat + 1}")):
            print(f"{name} off / on, {label}: frame {rc_med(False, kind):.1f} / "
                  f"{rc_med(True, kind):.1f} ms (x{rc_med(False, kind) / rc_med(True, kind):.2f}),"
                  f" GI {rc_med(False, kind, 'total'):.1f} / {rc_med(True, kind, 'total'):.1f} ms,"
                  f" screen probes {rc_med(False, kind, 'probes'):.1f} / "
                  f"{rc_med(True, kind, 'probes'):.1f} ms "
                  f"(x{rc_med(False, kind, 'probes') / rc_med(True, kind, 'probes'):.2f})")
        print(f"{name} view_draw first redraw off / on: {rc_med(False, 'view', first=True):.1f}"
              f" / {rc_med(True, 'view', first=True):.1f} ms, screen probes "
              f"{rc_med(False, 'view', 'probes', True):.1f} / "
              f"{rc_med(True, 'view', 'probes', True):.1f} ms")
    if trace:
        print(f"gi_trace {args.size}x{args.size} camera rays: voxel lighting "
              f"{trace['voxel'] * 1000:.1f} ms ({trace['global'] * 100:.0f}% global-SDF hits, "
              f"{trace['served'] * 100:.1f}% of them served by voxels), refined on the mesh SDFs "
              f"{trace['refined'] * 1000:.1f} ms (x{trace['refined'] / trace['voxel']:.2f}); "
              f"voxel lighting update, all 4 levels: {trace['update'] * 1000:.1f} ms")
    if args.viewport:
        m_ev = statistics.median(eevee_view[1:])
        vw, vh = args.viewport
        print(f"viewport {vw}x{vh}: {eevee_id} 1 sample median {m_ev * 1000:.1f} ms")
        for label, (times, gi) in viewport.items():
            m = statistics.median(times[1:])
            sc = statistics.median(g[0] for g in gi[1:]) * 1000
            tiles = gi[-1][1]
            # still redraws while the direct light refines (a part per redraw) and after it
            refining = [t for t, g in zip(times[1:], gi[1:]) if g[2]] or [float("nan")]
            still = [t for t, g in zip(times[1:], gi[1:]) if not g[2]] or [float("nan")]
            m_r, m_s = statistics.median(refining), statistics.median(still)
            print(f"  LUMEN_GI view_draw, {label}: first {times[0] * 1000:.1f} ms, median "
                  f"{m * 1000:.1f} ms (surface-cache radiosity {sc:.1f} ms, {tiles[0]} of "
                  f"{tiles[1]} tiles), ratio to EEVEE {m / m_ev:.3f}; while the direct light "
                  f"refines {m_r * 1000:.1f} ms ({m_r / m_ev:.3f}), after {m_s * 1000:.1f} ms "
                  f"({m_s / m_ev:.3f})")


if __name__ == "__main__":
    main()
