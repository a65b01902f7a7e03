"""A render engine instance's GPU inputs and what a change re-uploads (engine.py: a viewport's
engine instance keeps one for its lifetime, an F12 render makes its own, as Cycles' sessions do).

`SceneState.sync(bake, matrices, lights)` compares a new extraction with what is on the GPU:
    bake         the scene's bake (lumen_addon.bake.SceneBake): which meshes (by content hash)
                 are baked, and the instances (name, mesh hash, matrix at bake time)
    matrices     {instance name: world 4x4} of the current scene (extract_scene names); an
                 instance whose name is absent (deleted, hidden, in an excluded collection) is
                 parked as a scale-0 one is: it leaves the SDF scene at once, and its row keeps
                 its index (the surface cache's rows stay valid); it comes back if it returns
    lights       operators.lights.light_table rows (float32 [n, 16])
and re-uploads only what changed:
    atlas + indirection (+ objects)   the set of baked mesh hashes changed (a re-bake that changed
                                      some mesh); a re-bake with the same meshes uploads nothing
    objects (+ object grid)           an instance moved / appeared / vanished (transform edits)
    lights                            the light rows changed (rows and their RGBA32F texture)
    cards                             the instances' card hashes or the card atlas layout changed
                                      (surface_cache.SurfaceCache: card layers, tables, lighting)
It also holds the frame's G-buffer inputs, synced by engine.frame: `extraction`
(operators.extract.ExtractionCache: MeshData re-read only for what the depsgraph reported) and
`mesh_batches` (mesh_batches.MeshBatches: a batch per unique mesh, the instance matrix table).
`plan()` is the decision alone (numpy only, no gpu); `sync()` plans and uploads (needs a GPU
context). `uploads` counts uploads per resource, `last_changes` is the set of the last sync.
"""
from __future__ import annotations

import numpy as np

from .packing import instance_row, singular_many
from .sky_light import SkyLight

try:                                   # inside the extension package
    from ..lumen_addon.staleness import StaleCheck
except ImportError:                    # gpu_shaders imported on its own (tests, scripts)
    from lumen_addon.staleness import StaleCheck

RESOURCES = ("atlas", "indirection", "objects", "lights", "cards")

GONE = np.zeros((4, 4))    # the matrix of an instance the scene no longer has: a parked row


def instance_table(bake, matrices: dict):
    """(names, mesh hashes, float64 [n, 4, 4] world matrices) of the bake's instances, placed
    where the current scene has them; those it does not have get GONE (packing parks them)."""
    names, keys, mats = [], [], []
    for inst in bake.instances:
        names.append(inst.name)
        keys.append(inst.mesh)
        m = matrices.get(inst.name)
        mats.append(np.asarray(GONE if m is None else m, np.float64))
    arr = np.stack(mats) if mats else np.zeros((0, 4, 4))
    return names, keys, arr


def card_key(bake) -> tuple:
    """What the surface cache's layout depends on: each instance's cards hash and the card
    atlas rectangles (a re-bake with the same cards and layout keeps the lighting)."""
    table = bake.atlas.table if getattr(bake, "atlas", None) is not None else []
    return (tuple(inst.cards for inst in bake.instances),
            tuple((e["mesh"], e["index"], tuple(e["rect"])) for e in table))


class SceneState:
    def __init__(self):
        self.uploads = {name: 0 for name in RESOURCES}
        self.syncs = 0
        self.last_changes = set()
        self.mesh_keys = None        # frozenset of baked mesh hashes on the GPU
        self.names = None            # instance names of the object table on the GPU
        self.matrices = None         # their matrices
        self.matrices_source = None  # the dict they came from (sync's still-frame check)
        self.shadow_pass = {}        # {instance name: (share its shadow lets pass, share its
                                     # GI rays pass)}: the rows' texel 9 y, z (a cut-out's holes;
                                     # shadow 1: casts none)
        self._pass_arrays = None     # (shadow_pass, its names sorted, their shares) for rows
        self.left_out = []           # instances with a singular transform (parked rows)
        self.gone = []               # baked instances the scene no longer has (parked rows)
        self.stale = StaleCheck()    # objects added or edited since the bake (engine.frame)
        self.lights = None           # light rows last synced
        self.resources = None        # resources.SceneResources (atlas, indirection, objects)
        self.light_texture = None    # RGBA32F, 4 texels per light row (at least one row)
        self.cards_key = None        # card_key() of the surface cache on the GPU
        self.surface_cache = None    # surface_cache.SurfaceCache
        self.global_sdf = None       # global_sdf.GlobalSDF (gi.py makes it for the resources)
        self.voxel_lighting = None   # voxel_lighting.VoxelLighting (gi.py, the clipmaps' voxels)
        self.probes = None           # screen_probes.ScreenProbes (gi.py, per image size)
        self.radiance_cache = None   # radiance_cache.RadianceCache (gi.py, when it is on)
        self.screen_trace = None     # screen_trace.ScreenTrace of the last GI frame (gi.py)
        self.camera_hidden = frozenset()  # instance names the camera does not see (no G-buffer
                                          # pixel, still traced): the screen trace's blind spots
        self._hidden_rows = (None, None, np.zeros(0, np.int32))
        self._row_cache = None      # (packed, bake, keys, matrices, rows) of the last upload
        self._hidden_source = None   # the visibility array camera_hidden was made from
        self.gi_frame = 0            # frames of GI run (jitter sequences, clipmap cadence)
        self.gi_view_key = None      # camera + size of the probes' history
        self.gi_sky = None           # key of the sky maps the GI history was made with
        self.sky = SkyLight()        # the world's maps on the GPU (uploaded when they change)
        from .direct_light import Progressive   # (imports gpu: here, so plan() stays numpy-only)

        self.direct = Progressive()  # the viewport's direct light, spread over redraws
        from .antialias import Progressive as ProgressiveAA
        self.aa = ProgressiveAA()    # the viewport's anti-aliasing once a still view converged
        self.refine_seconds = 0.0    # the last refining viewport redraw's seconds: the AA's
                                     # time per redraw (antialias.Progressive)
        self.epoch = 0               # depsgraph updates seen (engine.view_update) and syncs
                                     # with changes: what the progressive direct light keys on
        self.unsettled = 0           # viewport frames whose GI or direct light still refined
                                     # (engine.frame: the anti-aliasing's key)
        self.direct_epoch = 0        # the same without the updates that only move objects: the
                                     # direct light restarts the pixels a move reaches itself
        self.still = None            # engine.view_draw: (key, Combined, stale) of a converged
                                     # viewport frame, drawn again until the key changes
        self.bake = None
        self.extraction = None       # operators.extract.ExtractionCache (engine.frame makes it)
        self.mesh_batches = None     # mesh_batches.MeshBatches: the G-buffer's meshes and
                                     # instance table on the GPU

    def plan(self, bake, matrices: dict, lights, table=None, shadow_pass=None) -> set:
        """The resources a sync with these inputs would upload (no side effects); `table`:
        instance_table(bake, matrices) when the caller has it."""
        names, keys, mats = table if table is not None else instance_table(bake, matrices)
        rows = np.asarray(lights, np.float32).reshape(-1, 16)
        changes = set()
        if self.mesh_keys is None or frozenset(keys) != self.mesh_keys:
            changes |= {"atlas", "indirection", "objects"}
        elif names != self.names or mats.shape != self.matrices.shape \
                or not np.array_equal(mats, self.matrices) \
                or (shadow_pass is not None and shadow_pass is not self.shadow_pass
                    and shadow_pass != self.shadow_pass):
            changes.add("objects")
        if self.lights is None or rows.shape != self.lights.shape \
                or not np.array_equal(rows, self.lights):
            changes.add("lights")
        if card_key(bake) != self.cards_key:
            changes.add("cards")
        return changes

    def sync(self, bake, matrices: dict, lights, shadow_pass=None) -> set:
        """Upload what changed; returns the set of re-uploaded resources. The same bake, the
        same `matrices` dict object (ExtractionCache.matrices: no walk since the last sync) and
        equal light rows change nothing: no loop over the instances. `shadow_pass`: {instance
        name: (share of light its shadow lets pass, share its GI rays pass)} (shadow 1: casts
        none; a cut-out's holes: less) for the instances that let some pass, their rows' texel 9
        y and z (sdf_lib.glsl sdf_shadow_rays, gi_trace_lib.glsl gi_radiance_from)."""
        rows = np.asarray(lights, np.float32).reshape(-1, 16)
        # the caller's dict, not a copy (ExtractionCache makes a new one per walk and never
        # edits it): a still frame compares it by identity, not entry by entry
        shadow_pass = shadow_pass if shadow_pass is not None else {}
        if bake is self.bake and matrices is self.matrices_source and self.lights is not None \
                and rows.shape == self.lights.shape and np.array_equal(rows, self.lights) \
                and (shadow_pass is self.shadow_pass or shadow_pass == self.shadow_pass):
            self.syncs += 1
            self.last_changes = set()
            return set()
        table = instance_table(bake, matrices)          # a loop over the bake's instances
        changes = self.plan(bake, matrices, lights, table, shadow_pass)
        names, keys, mats = table
        self.shadow_pass = shadow_pass
        if "atlas" in changes:
            self._upload_all(bake, names, keys, mats)
        elif "objects" in changes:
            self._upload_objects(bake, names, keys, mats)
        if "lights" in changes:
            self.lights = np.asarray(lights, np.float32).reshape(-1, 16).copy()
            self._upload_lights()
        if "cards" in changes:
            from .surface_cache import SurfaceCache
            self.surface_cache = SurfaceCache(bake.atlas, [inst.cards for inst in bake.instances])
            self.cards_key = card_key(bake)
        self.names, self.matrices, self.bake = names, mats, bake
        self.matrices_source = matrices
        self.mesh_keys = frozenset(keys)
        # instances whose transform cannot be inverted (scale 0): parked, named in the notes
        self.gone = [n for n in names if n not in matrices]
        cut = singular_many(mats) if len(names) else np.zeros(0, bool)
        self.left_out = [names[i] for i in np.flatnonzero(cut) if names[i] in matrices]
        for name in changes:
            self.uploads[name] += 1
        self.syncs += 1
        self.last_changes = changes
        return changes

    # -- uploads (GPU context needed) --------------------------------------------------------
    def _upload_all(self, bake, names, keys, mats):
        from types import SimpleNamespace

        from .packing import pack_scene
        from .resources import SceneResources

        placed = [SimpleNamespace(name=n, mesh=k, matrix_world=m)
                  for n, k, m in zip(names, keys, mats)]
        packed = pack_scene(bake.meshes, placed, 0)
        self._shadow_flags(packed.objects, names)
        self.resources = SceneResources(packed)
        # pack_scene's rows are instance_row's: the next object upload recomputes only changes
        packed = self.resources.packed
        self._row_cache = (packed, bake, list(keys),
                           np.asarray(mats, np.float64).reshape(len(keys), 4, 4), packed.objects)

    def _upload_lights(self):
        import gpu

        from .resources import float_buffer

        rows = self.lights if len(self.lights) else np.zeros((1, 16), np.float32)
        self.light_texture = gpu.types.GPUTexture((4, len(rows)), format='RGBA32F',
                                                  data=float_buffer(rows))

    def _shadow_flags(self, rows, names):
        """Texel 9 y and z of each row: the shares of light its shadow and its GI rays let pass
        (shadow_pass), matched by name in numpy (a drag re-uploads the rows every frame)."""
        rows[:, 9, 1:3] = 0.0
        if not self.shadow_pass or not len(names):
            return
        if self._pass_arrays is None or self._pass_arrays[0] is not self.shadow_pass:
            keys = np.array(list(self.shadow_pass.keys()))
            order = np.argsort(keys)
            values = np.array(list(self.shadow_pass.values()), np.float32).reshape(-1, 2)
            self._pass_arrays = (self.shadow_pass, keys[order], values[order])
        _, keys, values = self._pass_arrays
        names = np.asarray(names)
        at = np.minimum(np.searchsorted(keys, names), len(keys) - 1)
        hit = keys[at] == names
        rows[hit, 9, 1:3] = values[at[hit]]

    def _upload_objects(self, bake, names, keys, mats):
        """Rebuild only the object table texture (and its object grid) from the packed offsets
        already on the GPU."""
        packed = self.resources.packed
        if not len(keys):
            raise ValueError("the bake has no objects to trace")
        m = np.asarray(mats, np.float64).reshape(len(keys), 4, 4)
        prev = self._row_cache
        if prev is not None and prev[0] is packed and prev[1] is bake and prev[2] == list(keys):
            # the same instances: only the rows whose matrix changed (one object dragged among
            # 1,000: 1 row, not 1,000, each an SVD and an inverse)
            rows = prev[4].copy()
            for i in np.flatnonzero((m != prev[3]).reshape(len(keys), -1).any(axis=1)):
                rows[i] = instance_row(bake.meshes[keys[i]], m[i], packed.indirection_offset[keys[i]])
        else:
            rows = np.stack([instance_row(bake.meshes[key], mw, packed.indirection_offset[key])
                             for key, mw in zip(keys, m)])
        self._shadow_flags(rows, names)
        self._row_cache = (packed, bake, list(keys), m, rows)
        self.resources.set_objects(rows)     # and the object grid built from them

    def set_camera_hidden(self, objects, visible):
        """Remember which extracted instances the camera does not see (ObjectInputs and their
        camera-visibility flags, as ExtractionCache.update returns them; recomputed only when that
        array is a new one, i.e. after a walk)."""
        if visible is self._hidden_source:
            return
        self._hidden_source = visible
        vis = np.asarray(visible, bool).reshape(-1)
        self.camera_hidden = frozenset(objects[i].name for i in np.flatnonzero(~vis))

    def hidden_rows(self) -> np.ndarray:
        """int32 object-table rows of the camera-hidden instances (cached per table and set)."""
        names, hidden, rows = self._hidden_rows
        if names is not self.names or hidden is not self.camera_hidden:
            rows = np.zeros(0, np.int32)
            if self.camera_hidden and self.names:
                rows = np.flatnonzero(np.isin(np.asarray(self.names, object),
                                              list(self.camera_hidden))).astype(np.int32)
            self._hidden_rows = (self.names, self.camera_hidden, rows)
        return rows

    def stats(self) -> dict:
        """GPU bytes per resource (resources.stats() plus the light rows)."""
        out = dict(self.resources.stats()) if self.resources is not None else {}
        if self.lights is not None:
            out["lights"] = max(len(self.lights), 1) * 4 * 16     # RGBA32F, 4 texels per light
        if self.surface_cache is not None:
            out.update(self.surface_cache.stats())
        if self.global_sdf is not None:
            out.update({"global_sdf_" + k: v for k, v in self.global_sdf.stats().items()
                        if k != "total"})
        if self.probes is not None:
            out.update(self.probes.stats())
        if self.voxel_lighting is not None:
            out.update(self.voxel_lighting.stats())
        if self.mesh_batches is not None:
            out.update(self.mesh_batches.stats())
        if self.direct is not None:
            out.update(self.direct.stats())
        if self.radiance_cache is not None:
            out.update(self.radiance_cache.stats())
        if self.screen_trace is not None:
            out.update(self.screen_trace.stats())
        out.update(self.sky.stats())
        return out
