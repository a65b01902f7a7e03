"""`lumen.bake`: extract the scene, bake every mesh SDF and its mesh cards, write the cache folder.

In the UI the bake runs in a worker thread (numpy and Embree only; bpy is touched on the main
thread alone) while a timer polls it, so Blender stays responsive and Esc cancels. In background
mode and from scripts `execute` runs the same steps synchronously. Every failure becomes an
ERROR report and {'CANCELLED'}: nothing is written and the previous cache stays as it was.
Extraction warnings (materials that fall back to a colour, missing images, missing UVs) are
reported as WARNINGs and counted in the status line.
"""
import os
import tempfile
import threading
import traceback
from pathlib import Path

import bpy

from ..lumen_addon.bake import BakeCancelled, BakeSettings, SceneBakeError, bake_scene
from ..lumen_addon.cache import SCENE_TOKEN, CacheError, folder_name, read_cache, write_cache
from ..lumen_addon.estimate import MeshSize, estimate
from .extract import extract_scene, mesh_instances
from .material_nodes import material_emits
from .properties import DEFAULT_CACHE_DIR, INT_MAX

# Last successful bake per scene name: reused by the next bake (unchanged meshes are not baked
# again) and written by `lumen.export_cache`. Kept in memory only; the cache folder is the record.
LAST_BAKES = {}
# Scenes with a modal bake under way -> its job, so a second bake or an export waits for it.
RUNNING = {}

POLL_SECONDS = 0.1


def cancels(event) -> bool:
    """Esc pressed: the running bake stops. Only Esc: a right-click is the artist working in
    another editor (context menus) while the bake runs, never a request to stop it."""
    return event.type == 'ESC' and event.value == 'PRESS'


def settings_from(scene) -> BakeSettings:
    s = scene.lumen.bake
    return BakeSettings(voxel_density=float(s.voxel_density), max_resolution=int(s.max_resolution),
                        texel_density=float(s.texel_density), texel_budget=int(s.texel_budget),
                        min_card_size=float(s.min_card_size))


def mesh_sizes(depsgraph, min_card_size: float = 0.0) -> list:
    """MeshSize of every unique evaluated mesh the bake would extract, from counts and bounds
    alone (no vertex is read): cheap enough for the N-panel. Whether a mesh emits (an emitter
    keeps its cards under Min Card Size) is read only for instances smaller than
    `min_card_size` (0, the default setting: never)."""
    import numpy as np

    sizes, emitting = {}, {}      # emitting: material pointer -> material_emits (read once)

    def emits_any(obj):
        for slot in obj.material_slots:
            mat = slot.material
            if mat is not None:
                key = mat.as_pointer()
                if key not in emitting:
                    emitting[key] = material_emits(mat)
                if emitting[key]:
                    return True
        return False

    for inst, _name in mesh_instances(depsgraph):
        obj = inst.object
        mesh = obj.data
        key = mesh.as_pointer() if mesh is not None else obj.as_pointer()
        m = np.array(inst.matrix_world)[:3, :3]
        scale = float(np.linalg.norm(m, axis=0).max())
        old = sizes.get(key)
        if old is not None and (old.emits or not min_card_size > 0):
            sizes[key] = MeshSize(old.triangles, old.extent, old.resolution_scale,
                                  max(old.world_scale, scale), old.instances + 1, old.emits)
            continue
        extent = (np.asarray(old.extent) if old is not None else
                  np.ptp(np.array([c[:] for c in obj.bound_box], np.float64), axis=0))
        small = min((extent * scale).max(), (np.abs(m) @ extent).max()) < min_card_size
        emits = bool(min_card_size > 0 and small and emits_any(obj))
        if old is not None:
            sizes[key] = MeshSize(old.triangles, old.extent, old.resolution_scale,
                                  max(old.world_scale, scale), old.instances + 1, emits)
            continue
        props = getattr(obj.original, "lumen", None)
        sizes[key] = MeshSize(len(mesh.loop_triangles) if mesh is not None else 0,
                              tuple(extent),
                              float(props.resolution_scale) if props is not None else 1.0, scale,
                              emits=emits)
    return list(sizes.values())


def bake_estimate(scene, depsgraph):
    """lumen_addon.estimate.Estimate of baking the scene from scratch with its settings."""
    settings = settings_from(scene)
    return estimate(mesh_sizes(depsgraph, settings.min_card_size), settings)


_ESTIMATES = {}     # scene name -> (time, settings, Estimate): the N-panel redraws often


def cached_estimate(scene, depsgraph, max_age: float = 1.0):
    """bake_estimate, recomputed at most every `max_age` seconds or when a setting changes."""
    import time

    now, key = time.monotonic(), settings_from(scene)
    hit = _ESTIMATES.get(scene.name)
    if hit is None or hit[1] != key or now - hit[0] > max_age:
        hit = _ESTIMATES[scene.name] = (now, key, bake_estimate(scene, depsgraph))
    return hit[2]


def resolve_folder(path: str, default_name: str = "lumen_cache") -> Path:
    """Absolute folder for a (possibly `//`-relative) path setting.

    An unsaved .blend has no folder for `//` to mean, so such paths go under the system temp
    folder (not `bpy.app.tempdir`, which Blender deletes on exit).
    """
    raw = (path or "").strip() or f"//{default_name}"
    if raw.startswith("~"):
        raw = os.path.expanduser(raw)      # "~/x" is the home folder, not a folder named "~"
    if raw.startswith("//") and not bpy.data.filepath:
        rel = raw[2:].strip("/\\") or default_name
        return Path(tempfile.gettempdir()) / "lumen_gi" / rel
    return Path(bpy.path.abspath(raw))


def scene_cache_folder(scene) -> Path:
    """The scene's cache folder: its Cache Folder setting (empty: the default
    //lumen_cache/{scene}) with {scene} standing for the scene's name made safe for a folder,
    resolved as resolve_folder does (an unsaved file's // goes under the system temp folder).
    A path without {scene} is the user's and is kept as it is."""
    raw = (scene.lumen.bake.cache_dir or "").strip() or DEFAULT_CACHE_DIR
    return resolve_folder(raw.replace(SCENE_TOKEN, folder_name(scene.name)))


def human_bytes(n: int) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.2f} {unit}"
        n /= 1000.0
    return f"{n:.2f} GB"


def failure_message(exc: BaseException) -> str:
    """Readable one-line reason; SceneBakeError and CacheError already name the object/file."""
    if isinstance(exc, (SceneBakeError, CacheError)):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


def record_bake(scene, bake, status: str):
    """Store `bake` as the scene's last bake and copy its stats into `scene.lumen.last_bake`."""
    stats = bake.stats()
    s = scene.lumen.last_bake
    s.objects = min(stats["objects"], INT_MAX)
    s.unique_meshes = min(stats["unique_meshes"], INT_MAX)
    s.bricks = min(stats["bricks"], INT_MAX)
    s.bytes = min(stats["bytes"], INT_MAX)
    s.reused = min(stats["reused"], INT_MAX)
    s.cards = min(int(stats["cards"]), INT_MAX)
    s.texels = min(int(stats["texels"]), INT_MAX)
    s.coverage = min(max(float(stats["coverage"]), 0.0), 1.0)
    s.seconds = float(stats["seconds"])
    s.status = status
    LAST_BAKES[scene.name] = bake


def previous_bake(scene):
    """What the next bake may reuse: the last bake in memory, else the scene's cache on disk
    (a reopened file re-bakes only what changed). Reuse is by content hash, so a stale or
    foreign cache can only cost time, never a wrong result; an unreadable one is ignored."""
    bake = LAST_BAKES.get(scene.name)
    if bake is None:
        try:
            bake = read_cache(scene_cache_folder(scene))
        except Exception:
            bake = None
    return bake


def bake_now(context, scene):
    """Extract and bake synchronously: (SceneBake, extraction warnings [(object, message)]).
    Raises SceneBakeError and friends."""
    objects, warnings = extract_scene(context.evaluated_depsgraph_get())
    return bake_scene(objects, settings_from(scene), previous=previous_bake(scene)), warnings


def report_warnings(op, warnings):
    for name, message in warnings:
        op.report({'WARNING'}, f"{name}: {message}")


def warning_summary(extracted, baked) -> str:
    """Short status suffix, e.g. ' (2 material warnings, 1 bake warning; see the Info log)'."""
    parts = [f"{n} {what} warning{'s' if n != 1 else ''}"
             for n, what in ((len(extracted), "material"), (len(baked), "bake")) if n]
    return f" ({', '.join(parts)}; see the Info log)" if parts else ""


class _Job:
    """One bake of extracted arrays; `thread` runs it in the background, `run()` in place.

    Only plain arrays reach the worker, never bpy data, so the thread cannot race Blender.
    """

    def __init__(self, scene_name, objects, settings, previous, warnings=()):
        self.scene_name = scene_name
        self.warnings = list(warnings)       # from extraction, reported when the job concludes
        self.cancel = threading.Event()
        self.fraction, self.current = 0.0, ""
        self.result, self.error = None, None
        self._inputs = (objects, settings, previous)
        self.thread = threading.Thread(target=self.run, name="lumen-bake", daemon=True)

    def _progress(self, fraction, name):
        self.fraction, self.current = float(fraction), name or self.current
        if self.cancel.is_set():
            raise BakeCancelled()

    def run(self):
        objects, settings, previous = self._inputs
        self._inputs = None   # the arrays are not needed once the bake has them
        try:
            self.result = bake_scene(objects, settings, previous=previous, progress=self._progress)
        except BaseException as exc:   # reported on the main thread
            self.error = exc


class LUMEN_OT_bake(bpy.types.Operator):
    """Bake the signed distance fields of every visible mesh and write the Lumen GI cache"""

    bl_idname = "lumen.bake"
    bl_label = "Bake Lumen GI"
    bl_options = {'REGISTER'}

    confirmed: bpy.props.BoolProperty(
        name="Confirmed", description="The user accepted a large bake's estimate (set by the "
        "confirmation dialog; scripts need not)", default=False,
        options={'HIDDEN', 'SKIP_SAVE'})

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    # -- shared steps ---------------------------------------------------------------------------

    def _fail(self, scene, exc):
        msg = failure_message(exc)
        if not isinstance(exc, (SceneBakeError, CacheError, BakeCancelled)):
            traceback.print_exception(exc)   # unexpected: keep the trace for bug reports
        if scene is not None:
            scene.lumen.last_bake.status = f"Bake failed: {msg}"
        self.report({'ERROR'}, f"Lumen bake failed: {msg}")
        return {'CANCELLED'}

    def _unexpected(self, exc):
        """Last line of defence: no exception ever escapes into Blender."""
        traceback.print_exception(exc)
        self.report({'ERROR'}, f"Lumen bake failed: unexpected {type(exc).__name__}: {exc}")
        return {'CANCELLED'}

    def _finish(self, scene, bake, warnings=()):
        """Write the cache, then record stats: a bake that cannot be written changes nothing."""
        try:
            folder = scene_cache_folder(scene)
            write_cache(folder, bake)
        except Exception as exc:
            return self._fail(scene, exc)
        stats = bake.stats()
        status = (f"Baked {stats['objects']} objects, {stats['unique_meshes']} meshes "
                  f"({stats['reused']} reused), {stats['cards']} cards, "
                  f"{human_bytes(stats['bytes'])} in {stats['seconds']:.2f} s to {folder}"
                  + warning_summary(warnings, bake.warnings))
        record_bake(scene, bake, status)
        report_warnings(self, warnings)
        report_warnings(self, bake.warnings)
        self.report({'INFO'}, status)
        return {'FINISHED'}

    def _start(self, context):
        """Extract on the main thread; returns a _Job ready to run (or None after a report)."""
        scene = context.scene
        if scene.name in RUNNING:
            self.report({'ERROR'}, f"A Lumen bake of scene '{scene.name}' is already running")
            return None
        try:
            objects, warnings = extract_scene(context.evaluated_depsgraph_get())
            settings = settings_from(scene)
        except Exception as exc:
            self._fail(scene, exc)
            return None
        return _Job(scene.name, objects, settings, previous_bake(scene), warnings)

    def _conclude(self, job):
        """Turn a finished job into the cache, stats and reports (both execute and modal)."""
        scene = bpy.data.scenes.get(job.scene_name)
        if scene is None:
            self.report({'ERROR'}, f"Lumen bake: scene '{job.scene_name}' no longer exists")
            return {'CANCELLED'}
        if isinstance(job.error, BakeCancelled):
            scene.lumen.last_bake.status = "Bake cancelled"
            self.report({'WARNING'}, "Lumen bake cancelled; the cache was not changed")
            return {'CANCELLED'}
        if job.error is not None:
            report_warnings(self, job.warnings)   # may explain the failure (e.g. a bad material)
            return self._fail(scene, job.error)
        return self._finish(scene, job.result, job.warnings)

    # -- synchronous (background mode, scripts) -------------------------------------------------

    def execute(self, context):
        try:
            return self._execute(context)
        except Exception as exc:
            self._abandon(context)
            return self._unexpected(exc)

    def _execute(self, context):
        if self.confirmed and not bpy.app.background and context.window is not None:
            # the user accepted the large bake's estimate: bake in the background as invoke does
            self.confirmed = False
            return self._invoke(context)
        try:
            est = bake_estimate(context.scene, context.evaluated_depsgraph_get())
        except Exception:                 # an estimate must never stop a bake
            est = None
        if est is not None and est.large:
            self.report({'WARNING'}, f"Large bake: {est.text()} estimated "
                        f"({est.triangles:,} triangles)")
        job = self._start(context)
        if job is None:
            return {'CANCELLED'}
        job.run()
        return self._conclude(job)

    # -- modal (interactive) --------------------------------------------------------------------

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            est = bake_estimate(context.scene, context.evaluated_depsgraph_get())
        except Exception:                 # an estimate must never stop a bake
            est = None
        if est is not None and est.large and not self.confirmed:
            self.confirmed = True         # execute() then starts the background bake
            return context.window_manager.invoke_confirm(
                self, event, title="Large Lumen GI bake",
                message=f"This bake needs {est.text()} ({est.triangles:,} triangles). Bake?",
                confirm_text="Bake")
        try:
            return self._invoke(context)
        except Exception as exc:
            self._abandon(context)
            return self._unexpected(exc)

    def modal(self, context, event):
        try:
            return self._modal(context, event)
        except Exception as exc:
            self._abandon(context)
            return self._unexpected(exc)

    def _invoke(self, context):
        self._job, self._timer = None, None
        job = self._start(context)
        if job is None:
            return {'CANCELLED'}
        self._job = job
        RUNNING[job.scene_name] = job
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_SECONDS, window=context.window)
        wm.progress_begin(0.0, 1.0)
        wm.modal_handler_add(self)
        job.thread.start()
        self._show(context, "starting")
        return {'RUNNING_MODAL'}

    def _modal(self, context, event):
        job = self._job
        if cancels(event):
            job.cancel.set()
            self._show(context, "cancelling")
            return {'RUNNING_MODAL'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        if job.thread.is_alive():
            context.window_manager.progress_update(job.fraction)
            self._show(context, "cancelling" if job.cancel.is_set() else job.current)
            return {'PASS_THROUGH'}
        self._cleanup(context)
        return self._conclude(job)

    def cancel(self, context):
        """Blender is cancelling the operator (file load, quit): stop the worker, write nothing."""
        self._abandon(context)

    def _abandon(self, context):
        """Stop a running worker and release the timer, progress and status text."""
        job = getattr(self, "_job", None)
        if job is None:
            return
        job.cancel.set()
        if job.thread.is_alive():
            job.thread.join(timeout=10.0)
        try:
            self._cleanup(context)
        except Exception:
            traceback.print_exc()

    def _show(self, context, what):
        text = f"Lumen GI: baking {self._job.fraction:.0%}"
        if what:
            text += f" ({what})"
        context.workspace.status_text_set(text + " - Esc to cancel")
        for area in context.screen.areas if context.screen else ():
            if area.type == 'VIEW_3D':
                area.tag_redraw()

    def _cleanup(self, context):
        if RUNNING.get(self._job.scene_name) is self._job:
            del RUNNING[self._job.scene_name]
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
            wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        for area in context.screen.areas if context.screen else ():
            if area.type == 'VIEW_3D':
                area.tag_redraw()


@bpy.app.handlers.persistent
def _forget_bakes(*_args):
    """Another file is loaded: its scenes may share names with the old ones, so the last bakes
    (which export writes) no longer belong to anything."""
    LAST_BAKES.clear()


def register():
    bpy.utils.register_class(LUMEN_OT_bake)
    bpy.app.handlers.load_post.append(_forget_bakes)


def unregister():
    for job in list(RUNNING.values()):
        job.cancel.set()
    if _forget_bakes in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_forget_bakes)
    bpy.utils.unregister_class(LUMEN_OT_bake)
    LAST_BAKES.clear()
