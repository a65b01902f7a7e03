"""Benchmark: frame time against object count (issue 10: 1,000 objects at most twice 10).

Scene per N: a 20 x 20 m floor and N small icospheres (80 triangles) on a grid over it, half of
them unique meshes (each its own Mesh datablock, scaled differently so each bakes its own SDF),
half linked duplicates of those (obj.copy(): the same Mesh); five shared materials; a sun; a
camera above one side of the floor that sees most of them. Baked at `--density` voxels/m.
For N = 10, 100, 1000 (`--counts`) in one process, same resolution:
  viewport   the engine's own view_draw through tools/viewport_harness.py at `--size`^2, Pixel
             Size 1, viewport quality `--quality`: one warm-up redraw (first frame: everything
             extracted and uploaded) then `--still` still redraws (default 16: four cycles of
             the default Spread Over 4, whose redraws differ in work: a median of 3 took 125 or
             240 ms at 10 objects), their mean and median, the mean CPU time (llvmpipe's
             threads included: other jobs on a shared host move it less than the wall time)
             and the split of the last still frame from LAST_RENDER (extract, sync, G-buffer,
             direct, GI)
  F12        bpy.ops.render.render at `--size`^2, render_frames = bounces = 1 (one GI iteration),
             one warm-up then `--repeat` timed, median and split
  F12 default (--default-f12) one more F12 with the engine's default GI settings (render frames,
             bounces, Converge Bounces, noise threshold) after the timed ones: seconds,
             iterations, bounces (compare with EEVEE's 64 samples)
  EEVEE      (--eevee) the baseline in the same run: EEVEE's render at `--size`^2 with 1 sample
             (a viewport-like frame) and with its default 64, one warm-up then `--repeat`, median
and the ratios N=max / N=min (EEVEE's too: how much the scene itself grew for a rasteriser).
Shader compilation happens in the first N's warm-ups.
--alternate R: then R rounds that reopen each N's baked scene in turn and time its still frames
again, and the ratio N=max / N=min per round and their median (a shared host's speed drifts by
up to 2x over minutes: the two N of one round run back to back).
--move K: per N, the K redraws after one object moves 0.4 m (8 still redraws before it), and
the first one's split (with --passes, its largest passes).
--drag K: per N, K redraws while one object moves 5 cm before each (a drag): their sum and
max, and the global SDF's share.
--passes: every compute dispatch timed by shader (bench/pass_profile.py's timed_dispatches; on
llvmpipe a dispatch runs before it returns), per N the still viewport frames' means and the
last F12's sums (and the default F12's), and a table of each pass at N=min against N=max,
largest growth first: what grows with the object count.

    .venv/bin/python bench/object_scaling.py [--counts 10 100 1000] [--size 128] [--repeat 3]
                                             [--still 16] [--quality MEDIUM] [--f12-max N] [--passes] [--eevee]
                                             [--default-f12] [--alternate R] [--move K]
                                             [--drag K]
    .venv/bin/python bench/object_scaling.py --gbuffer-only [--counts ...] [--size 128]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tools"), str(ROOT / "bench")]

import pass_profile  # noqa: E402 (bench/: per-dispatch timing)

SPLIT = ("frame_seconds", "extract_seconds", "sync_seconds", "gbuffer_seconds", "direct_seconds",
         "gi_seconds")


def build_scene(n: int, size: int):
    import bmesh
    import bpy
    import mathutils
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mats = []
    for i, c in enumerate(((0.8, 0.8, 0.8), (0.8, 0.2, 0.2), (0.2, 0.7, 0.3), (0.2, 0.3, 0.8),
                           (0.8, 0.7, 0.2))):
        mat = bpy.data.materials.new(f"Mat{i}")
        mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*c, 1.0)
        mats.append(mat)
    floor_mesh = bpy.data.meshes.new("Floor")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=10.0)
    bm.to_mesh(floor_mesh)
    bm.free()
    floor_mesh.materials.append(mats[0])
    scene.collection.objects.link(bpy.data.objects.new("Floor", floor_mesh))
    base = bpy.data.meshes.new("Ico")
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=1, radius=0.25)
    bm.to_mesh(base)
    bm.free()
    unique = max(n // 2, 1)
    side = int(np.ceil(np.sqrt(n)))
    meshes = []
    for i in range(n):
        x = ((i % side) + 0.5) / side * 18.0 - 9.0
        y = ((i // side) + 0.5) / side * 18.0 - 9.0
        if i < unique:
            mesh = base.copy()
            mesh.name = f"Ico{i}"
            mesh.transform(mathutils.Matrix.Diagonal((1.0, 1.0, 1.0 + 0.5 * i / unique, 1.0)))
            mesh.materials.append(mats[1 + i % 4])
            meshes.append(mesh)
        else:
            mesh = meshes[i % unique]          # a linked duplicate
        obj = bpy.data.objects.new(f"Obj{i}", mesh)
        obj.location = (x, y, 0.3)
        scene.collection.objects.link(obj)
    bpy.data.meshes.remove(base)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.8)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    for obj in (sun, cam):
        scene.collection.objects.link(obj)
    cam.location = (0.0, -13.0, 9.0)
    cam.rotation_euler = (mathutils.Vector((0, -1.0, 0)) - cam.location).to_track_quat(
        "-Z", "Y").to_euler()
    scene.camera = cam
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.05, 0.05, 0.06)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def split(R) -> dict:
    return {k.replace("_seconds", ""): R.get(k, 0.0) * 1000 for k in SPLIT}


def measure(n: int, args, tmp: Path) -> dict:
    import bpy

    import viewport_harness
    from lumen_gi.gpu_shaders import engine

    scene = build_scene(n, args.size)
    scene.lumen.bake.cache_dir = str(tmp / f"cache{n}")
    scene.lumen.bake.voxel_density = args.density
    t = time.perf_counter()
    bpy.ops.lumen.bake()
    bake_seconds = time.perf_counter() - t
    scene.render.engine = "LUMEN_GI"
    scene.render.preview_pixel_size = "1"
    scene.lumen.engine.render_quality = scene.lumen.engine.viewport_quality = args.quality
    scene.lumen.engine.render_frames = 1
    scene.lumen.engine.bounces = 1
    scene.lumen.engine.converge_bounces = False     # exactly one GI iteration
    rows = []
    timings = defaultdict(float)          # --passes: this redraw's or render's {pass: seconds}
    per_draw = []
    undo = pass_profile.timed_dispatches(timings) if args.passes else None

    def record(i):
        R = engine.LAST_RENDER
        if "error" in R:
            raise RuntimeError(R.get("traceback", R["error"]))
        rows.append(dict(split(R), meshes_read=R.get("meshes_read", -1),
                         draws=R.get("gbuffer_draws", 0), triangles=R.get("triangles", 0),
                         sc_tiles="{}/{}".format(*R.get("gi_sc_tiles", (0, 0)))))
        per_draw.append(dict(timings))
        timings.clear()

    if args.alternate:
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp / f"scene{n}.blend"), copy=True)
    try:
        out = viewport_harness.run(scene, engine.LumenGIRenderEngine, args.size, args.size,
                                   redraws=args.still + 1, on_redraw=record)
        still = per_draw[1:] or per_draw
        view = dict(first=out["seconds"][0] * 1000,
                    median=statistics.median(out["seconds"][1:]) * 1000,
                    mean=statistics.fmean(out["seconds"][1:]) * 1000, split=rows[-1],
                    cpu=statistics.fmean(out["cpu_seconds"][1:]) * 1000,
                    first_split=rows[0],
                    passes={k: statistics.fmean(r.get(k, 0.0) for r in still) * 1000
                            for k in {k for r in still for k in r}})
        if args.move:
            view["move"], view["move_split"] = move_redraws(scene, args, n)
        if args.drag:
            view["drag"], view["drag_gsdf"] = drag_redraws(scene, args, n)
        if n > args.f12_max:
            return dict(n=n, bake=bake_seconds, view=view, f12=None,
                        eevee=eevee_times(scene, args.repeat) if args.eevee else None,
                        triangles=rows[-1]["triangles"])
        times = []
        for _ in range(args.repeat + 1):
            timings.clear()
            t = time.perf_counter()
            bpy.ops.render.render()
            times.append(time.perf_counter() - t)
            if "error" in engine.LAST_RENDER:
                raise RuntimeError(engine.LAST_RENDER.get("traceback"))
    finally:
        if undo is not None:
            undo()
    R = engine.LAST_RENDER
    f12 = dict(median=statistics.median(times[1:]) * 1000, split=split(R),
               iterations=R.get("gi_iterations", 0), meshes_read=R.get("meshes_read", -1),
               passes={k: v * 1000 for k, v in timings.items()})
    if args.default_f12:       # the defaults a user gets (the timed F12s pinned one iteration)
        d = type(scene.lumen.engine).bl_rna.properties
        for key in ("render_frames", "bounces", "converge_bounces"):
            setattr(scene.lumen.engine, key, d[key].default)
        timings.clear()
        undo = pass_profile.timed_dispatches(timings) if args.passes else None
        try:
            t = time.perf_counter()
            bpy.ops.render.render()
            seconds = time.perf_counter() - t
        finally:
            if undo is not None:
                undo()
        R = engine.LAST_RENDER
        f12["default"] = dict(seconds=seconds, iterations=R.get("gi_iterations", 0),
                              bounces=R.get("gi_bounces", 0),
                              passes={k: v * 1000 for k, v in timings.items()})
    eevee = eevee_times(scene, args.repeat) if args.eevee else None
    return dict(n=n, bake=bake_seconds, view=view, f12=f12, triangles=R.get("triangles", 0),
                eevee=eevee)


def alternate(counts, args, tmp: Path) -> dict:
    """{n: [still-frame mean ms per round]}: `args.alternate` rounds, each reopening every
    count's baked scene (saved by measure) and timing `--still` still redraws after one warm-up.
    Why: on a shared host the speed drifts by up to 2x over minutes, so two counts measured one
    after the other (measure) can differ by that much alone; a round's counts run back to back,
    and the ratio is taken per round."""
    import bpy

    import viewport_harness
    from lumen_gi.gpu_shaders import engine

    means = {n: [] for n in counts}
    for _ in range(args.alternate):
        for n in counts:
            bpy.ops.wm.open_mainfile(filepath=str(tmp / f"scene{n}.blend"))
            out = viewport_harness.run(bpy.context.scene, engine.LumenGIRenderEngine, args.size,
                                       args.size, redraws=args.still + 1)
            if "error" in engine.LAST_RENDER:
                raise RuntimeError(engine.LAST_RENDER.get("traceback"))
            means[n].append(statistics.fmean(out["seconds"][1:]) * 1000)
    return means


def move_redraws(scene, args, n: int) -> list:
    """ms of the `args.move` redraws after one object (the middle one) moves 0.4 m, following
    MOVE_WARM still redraws: what an artist dragging an object waits for (the global SDF's
    levels, the object table and grid, the voxel lighting and the surface cache follow it on
    their own frames, so the cost spreads over the next 8 redraws)."""
    import bpy

    import viewport_harness
    from lumen_gi.gpu_shaders import engine

    name = f"Obj{n // 2}"
    first = {}
    timings = defaultdict(float)      # --passes: the first redraw's dispatches by shader

    def on_redraw(i):
        R = engine.LAST_RENDER
        if i == MOVE_WARM - 1:
            bpy.data.objects[name].location.x += 0.4
        elif i == MOVE_WARM and "error" not in R:     # the first redraw after the move
            first.update(split(R), **{"gi " + k: v * 1000
                                      for k, v in (R.get("gi_timings") or {}).items()
                                      if k != "total" and isinstance(v, float)})
            top = sorted(timings.items(), key=lambda kv: -kv[1])[:8]
            first.update({"pass " + k: v * 1000 for k, v in top})
        timings.clear()

    undo = pass_profile.timed_dispatches(timings) if args.passes else (lambda: None)
    try:
        out = viewport_harness.run(scene, engine.LumenGIRenderEngine, args.size, args.size,
                                   redraws=MOVE_WARM + args.move, on_redraw=on_redraw)
    finally:
        undo()
    if "error" in engine.LAST_RENDER:
        raise RuntimeError(engine.LAST_RENDER.get("traceback", engine.LAST_RENDER["error"]))
    bpy.data.objects[name].location.x -= 0.4
    return [s * 1000 for s in out["seconds"][MOVE_WARM:]], first


MOVE_WARM = 8


def drag_redraws(scene, args, n: int) -> tuple:
    """(ms of each of `args.drag` redraws, ms of the global SDF's update in each) while one
    object (the middle one) moves 5 cm before every redraw, after MOVE_WARM still ones: an
    artist dragging it."""
    import bpy

    import viewport_harness
    from lumen_gi.gpu_shaders import engine

    name = f"Obj{n // 2}"
    gsdf = []

    def on_redraw(i):
        if i >= MOVE_WARM:
            gsdf.append((engine.LAST_RENDER.get("gi_timings") or {}).get("gsdf", 0.0) * 1000)
        if i >= MOVE_WARM - 1:
            bpy.data.objects[name].location.x += 0.05

    out = viewport_harness.run(scene, engine.LumenGIRenderEngine, args.size, args.size,
                               redraws=MOVE_WARM + args.drag, on_redraw=on_redraw)
    if "error" in engine.LAST_RENDER:
        raise RuntimeError(engine.LAST_RENDER.get("traceback", engine.LAST_RENDER["error"]))
    bpy.data.objects[name].location.x -= 0.05 * (args.drag + 1)
    return [s * 1000 for s in out["seconds"][MOVE_WARM:]], gsdf


def eevee_times(scene, repeat: int) -> dict:
    """{samples: median ms} of EEVEE's render of `scene` with 1 and 64 samples."""
    import bpy

    scene.render.engine = [i.identifier for i in
                           bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
                           if i.identifier.startswith("BLENDER_EEVEE")][0]
    out = {}
    for samples in (1, 64):
        scene.eevee.taa_render_samples = samples
        times = []
        for _ in range(repeat + 1):
            t = time.perf_counter()
            bpy.ops.render.render()
            times.append(time.perf_counter() - t)
        out[samples] = statistics.median(times[1:]) * 1000
    scene.render.engine = "LUMEN_GI"
    return out


def gbuffer_only(counts, size: int, repeat: int) -> list:
    """[(n, old ms, new ms, meshes read by a still new frame)]: extraction + G-buffer alone, in
    one GPU context, no bake: the old path (extract_scene + gbuffer.render_gbuffer: every mesh
    read, world-space corners in numpy, new batches) against a still frame of the new one
    (ExtractionCache.update + MeshBatches.update + draw), each followed by a read-back of the
    position attachment so the GPU's work is in the time."""
    import bpy

    rows = []

    def job(depsgraph, n):
        from lumen_gi.gpu_shaders import engine, gbuffer
        from lumen_gi.gpu_shaders.mesh_batches import MeshBatches
        from lumen_gi.operators.extract import ExtractionCache, extract_scene

        vp, _, _ = engine.view_projection(depsgraph, depsgraph.scene.camera, size, size)
        ext, batches = ExtractionCache(), MeshBatches()
        old, new, reads = [], [], []
        for _ in range(repeat + 1):
            t = time.perf_counter()
            objects, _ = extract_scene(depsgraph)
            g = gbuffer.render_gbuffer(objects, vp, size, size)
            gbuffer.read_texture(g["textures"]["position"], size, size)
            old.append(time.perf_counter() - t)
            t = time.perf_counter()
            _, _, keys, meshes, mats, visible, _ = ext.update(depsgraph)
            t1 = time.perf_counter()
            batches.update(keys, meshes, mats, visible)
            t2 = time.perf_counter()
            g = batches.draw(vp, size, size)
            gbuffer.read_texture(g["textures"]["position"], size, size)
            t3 = time.perf_counter()
            batches.drawn = None        # the same still frame with its G-buffer drawn again
            g = batches.draw(vp, size, size)
            gbuffer.read_texture(g["textures"]["position"], size, size)
            new.append((t3 - t, t1 - t, t2 - t1, t3 - t2, time.perf_counter() - t3))
            reads.append(ext.reads)
        parts = [statistics.median(x[k] for x in new[1:]) * 1000 for k in range(5)]
        rows.append((n, statistics.median(old[1:]) * 1000, parts[0], reads[-1], reads[0],
                     parts[1:]))

    rows_n = []
    for n in counts:
        scene = build_scene(n, size)
        rows_n.append(n)

        class GBufferBench(bpy.types.RenderEngine):
            bl_idname = "LUMEN_GBUFFER_BENCH"
            bl_label = "G-buffer bench"
            bl_use_gpu_context = True

            def render(self, depsgraph):
                try:
                    job(depsgraph, len(rows_n) and rows_n[-1])
                except Exception:
                    import traceback
                    traceback.print_exc()
                self.end_result(self.begin_result(0, 0, 4, 4))

        bpy.utils.register_class(GBufferBench)
        scene.render.engine = GBufferBench.bl_idname
        try:
            bpy.ops.render.render()
        finally:
            bpy.utils.unregister_class(GBufferBench)
    return rows


def fmt(s: dict) -> str:
    return ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in s.items())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--counts", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--still", type=int, default=16, help="still viewport redraws timed")
    ap.add_argument("--quality", default="MEDIUM", choices=("OFF", "LOW", "MEDIUM", "HIGH"))
    ap.add_argument("--density", type=float, default=8.0, help="bake voxels per metre")
    ap.add_argument("--f12-max", type=int, default=1 << 30,
                    help="skip F12 above this many objects (a GI F12 of 1,000 takes hours)")
    ap.add_argument("--default-f12", action="store_true",
                    help="one more F12 per N with the default GI settings")
    ap.add_argument("--eevee", action="store_true",
                    help="EEVEE's render with 1 and 64 samples per N: the baseline's own growth")
    ap.add_argument("--passes", action="store_true",
                    help="time every compute dispatch by pass: what grows with N")
    ap.add_argument("--alternate", type=int, default=0, metavar="R",
                    help="then R rounds reopening each count's scene in turn: the ratio per "
                         "round (robust to a shared host's drift)")
    ap.add_argument("--drag", type=int, default=0, metavar="K",
                    help="per N, K redraws while one object moves 5 cm before each")
    ap.add_argument("--move", type=int, default=0, metavar="K",
                    help="then time the K redraws after one object moves 0.4 m (8 covers "
                         "every clipmap level's frame)")
    ap.add_argument("--gbuffer-only", action="store_true",
                    help="time extraction + G-buffer alone, old path against new, no bake")
    args = ap.parse_args()

    import tempfile

    import demo

    results = []
    if args.gbuffer_only:
        demo.load_addon()
        rows = gbuffer_only(args.counts, args.size, args.repeat)
        for n, old, new, reads, first, (walk, table, draw, again) in rows:
            print(f"N={n:5d}: extraction + G-buffer, every mesh read (old) {old:8.1f} ms, still "
                  f"frame (new) {new:7.1f} ms (instance walk {walk:.1f}, instance table "
                  f"{table:.1f}, the last G-buffer again + read-back {draw:.1f}, drawn again "
                  f"+ read-back {again:.1f}; {reads} meshes read, {first} on the first)")
        print(f"ratio N={rows[-1][0]} / N={rows[0][0]}: old {rows[-1][1] / rows[0][1]:.2f}, "
              f"new {rows[-1][2] / rows[0][2]:.2f}")
        return
    with tempfile.TemporaryDirectory() as tmp:
        demo.load_addon()
        for n in args.counts:
            r = measure(n, args, Path(tmp))
            results.append(r)
            v, f = r["view"], r["f12"]
            print(f"N={n:5d} ({r['triangles']} triangles, bake {r['bake']:.1f} s)", flush=True)
            print(f"  viewport {args.size}x{args.size}: first {v['first']:.1f} ms, still mean "
                  f"{v['mean']:.1f} ms (median {v['median']:.1f}, CPU mean {v['cpu']:.1f}); "
                  f"last still split ms: "
                  f"{fmt(v['split'])}", flush=True)
            print(f"    first-frame split ms: {fmt(v['first_split'])}", flush=True)
            if "move" in v:
                m = v["move"]
                print(f"  after one object moved: {len(m)} redraws ms " +
                      ", ".join(f"{x:.0f}" for x in m) +
                      f" (sum {sum(m):.0f}, max {max(m):.0f}; still mean {v['mean']:.0f})",
                      flush=True)
                print(f"    its first redraw's split ms: {fmt(v['move_split'])}", flush=True)
            if "drag" in v:
                d, g = v["drag"], v["drag_gsdf"]
                print(f"  dragged (5 cm a redraw): {len(d)} redraws, sum {sum(d):.0f} ms, max "
                      f"{max(d):.0f} ms; global SDF sum {sum(g):.0f} ms, max {max(g):.0f} ms",
                      flush=True)
            if f is not None:
                print(f"  F12 (1 GI iteration): median {f['median']:.1f} ms; split ms: "
                      f"{fmt(f['split'])}, meshes read {f['meshes_read']}", flush=True)
            if f is not None and "default" in f:
                dd = f["default"]
                print(f"  F12 default settings: {dd['seconds']:.1f} s, {dd['iterations']} "
                      f"iterations, {dd['bounces']} bounces", flush=True)
            if r.get("eevee"):
                print(f"  EEVEE render: 1 sample {r['eevee'][1]:.1f} ms, 64 samples "
                      f"{r['eevee'][64]:.1f} ms", flush=True)
            if args.passes:
                for label, d in (("viewport still", v["passes"]),
                                 ("F12", f["passes"] if f is not None else {}),
                                 ("F12 default", f.get("default", {}).get("passes", {})
                                  if f is not None else {})):
                    top = sorted(d.items(), key=lambda kv: -kv[1])
                    if top:
                        print(f"  {label} passes ms: " + ", ".join(
                            f"{k} {ms:.1f}" for k, ms in top if ms >= 0.5), flush=True)
        if args.alternate:
            means = alternate(args.counts, args, Path(tmp))
            a, b = args.counts[0], args.counts[-1]
            ratios = [y / x for x, y in zip(means[a], means[b])]
            for n in args.counts:
                print(f"alternating: N={n:5d} still-frame means ms " +
                      ", ".join(f"{m:.1f}" for m in means[n]))
            print(f"alternating: ratio N={b} / N={a} per round " +
                  ", ".join(f"{r:.2f}" for r in ratios) +
                  f"; median {statistics.median(ratios):.2f}", flush=True)
    lo, hi = results[0], results[-1]
    f12 = [r for r in results if r["f12"] is not None]
    print(f"ratio N={hi['n']} / N={lo['n']}: viewport still frame (mean of {args.still}) "
          f"{hi['view']['mean'] / lo['view']['mean']:.2f} (medians "
          f"{hi['view']['median'] / lo['view']['median']:.2f}; CPU means "
          f"{hi['view']['cpu'] / lo['view']['cpu']:.2f})" + (
              f", F12 N={f12[-1]['n']} / N={lo['n']} "
              f"{f12[-1]['f12']['median'] / lo['f12']['median']:.2f}" if len(f12) > 1 else ""))
    if len(f12) > 1 and "default" in f12[0]["f12"] and "default" in f12[-1]["f12"]:
        a, b = f12[0]["f12"]["default"]["seconds"], f12[-1]["f12"]["default"]["seconds"]
        print(f"ratio N={f12[-1]['n']} / N={lo['n']}: F12 default settings {b / a:.2f} "
              f"({a:.1f} -> {b:.1f} s)")
    if lo.get("eevee") and hi.get("eevee"):
        print(f"ratio N={hi['n']} / N={lo['n']}: EEVEE 1 sample "
              f"{hi['eevee'][1] / lo['eevee'][1]:.2f}, 64 samples "
              f"{hi['eevee'][64] / lo['eevee'][64]:.2f}")
    for key in ("extract", "sync", "gbuffer", "direct", "gi"):
        a, b = lo["view"]["split"][key], hi["view"]["split"][key]
        print(f"  viewport last still {key:8s} {a:8.1f} -> {b:8.1f} ms")
    if args.passes:
        print_passes("viewport still frame (mean)", lo["view"]["passes"], hi["view"]["passes"],
                     lo["n"], hi["n"])
        if len(f12) > 1:
            print_passes("F12 (1 GI iteration)", f12[0]["f12"]["passes"],
                         f12[-1]["f12"]["passes"], f12[0]["n"], f12[-1]["n"])
            if "default" in f12[0]["f12"] and "default" in f12[-1]["f12"]:
                print_passes("F12 default settings", f12[0]["f12"]["default"]["passes"],
                             f12[-1]["f12"]["default"]["passes"], f12[0]["n"], f12[-1]["n"])


def print_passes(title: str, a: dict, b: dict, n_a: int, n_b: int):
    """Each pass's ms at N=n_a and N=n_b, largest growth first (passes under 0.5 ms skipped)."""
    print(f"{title}, per pass ms: N={n_a} -> N={n_b} (growth)")
    keys = sorted(set(a) | set(b), key=lambda k: -(b.get(k, 0.0) - a.get(k, 0.0)))
    for k in keys:
        x, y = a.get(k, 0.0), b.get(k, 0.0)
        if max(x, y) >= 0.5:
            print(f"  {k:40s} {x:9.1f} -> {y:9.1f} ({y - x:+9.1f})")


if __name__ == "__main__":
    main()
