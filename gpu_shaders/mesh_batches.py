"""The G-buffer's geometry kept on the GPU between frames: one batch per unique mesh, instanced.

A render engine instance's `MeshBatches` (SceneState.mesh_batches) holds, for every unique
evaluated mesh + material set (operators.extract.ExtractionCache's keys), its corners in local
space as gpu batches, one per (albedo texture, emission texture) pair (gbuffer.scene_triangles
with an identity matrix), built when the key first appears or its MeshData was re-extracted, and
freed when no instance shows it any more. The instances' world and normal matrices live in one
RGBA32F texture (6 texels a row, rows grouped by mesh), re-uploaded only when a matrix, the set
of instances or their order changed. The G-buffer is then one `draw_instanced` per batch
(glsl/gbuffer_instanced.glsl reads row instance_base + gl_InstanceID): per-frame Python work is a
loop over the unique meshes' batches, numpy over the instances, nothing over triangles.

Instancing was chosen over one draw per instance with a matrix push constant: Blender 5.0's
`GPUBatch.draw_instanced` with a texture lookup by gl_InstanceID works on llvmpipe, and it keeps
the draw calls at the number of unique meshes (500 for the 1,000-object bench scene, not 1,000).
Material textures are uploaded once per array and kept while a drawn mesh uses them.
"""
from __future__ import annotations

import time

import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from .gbuffer import (ATTACHMENTS, ATTRIBUTES, MATERIAL_KEYS, gbuffer_program, normal_mode,
                      scene_triangles, upload_texture)
from .resources import glsl, row_texture

TEXELS = 6                      # instance table texels per row


def instanced_shader():
    """gbuffer.gbuffer_program with glsl/gbuffer_instanced.glsl's vertex stage."""
    return gbuffer_program("gbuffer_instanced", glsl("gbuffer_instanced.glsl"), instanced=True)


def drawable(matrices: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """bool [n]: camera-visible instances with an invertible, finite transform (packing.singular,
    vectorised: Blender draws nothing of an object scaled to 0)."""
    m = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    ok = np.asarray(visible, bool) & np.isfinite(m).all(axis=(1, 2))
    if ok.any():
        s = np.linalg.svd(np.where(ok[:, None, None], m, np.eye(4))[:, :3, :3], compute_uv=False)
        ok &= s.min(axis=1) > 1e-9 * np.maximum(s.max(axis=1), 1e-30)
    return ok


def table_rows(matrices: np.ndarray, holdout=None) -> np.ndarray:
    """float32 [n, 6, 4]: each matrix's rows 0..2, then its normal matrix's rows (w = 0; texel
    3's w = 1 for a holdout, gbuffer_instanced.glsl)."""
    m = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    out = np.zeros((len(m), TEXELS, 4), np.float32)
    out[:, :3] = m[:, :3]
    if len(m):
        out[:, 3:, :3] = np.linalg.inv(m[:, :3, :3]).transpose(0, 2, 1)
    if holdout is not None:
        out[:, 3, 3] = np.asarray(holdout, bool)
    return out


class _Entry:
    """A unique mesh on the GPU: its MeshData (identity says when it was re-extracted) and its
    batches [(batch, albedo texture array or None, emission texture array or None)]."""

    def __init__(self, data, groups, triangles):
        self.data, self.groups, self.triangles = data, groups, triangles


class MeshBatches:
    def __init__(self):
        self.entries = {}          # mesh key -> _Entry
        self.textures = {}         # id(array) -> (array, (GPUTexture, base height))
        self.table = None          # GPUTexture RGBA32F: a row table of 6 texels a row
        self.rows = None           # float32 [rows, 6, 4] on the GPU
        self.runs = []             # [(mesh key, first row, count)] in table order
        self.built_total = 0       # batches built over the state's life (tests)
        self.table_uploads = 0
        self.last = {}             # the last update's counts
        self.source = None         # the last update's inputs (identity: a still frame's are)
        self.generation = 0        # bumped whenever what draw() shows changed (update)
        self.shading_normals = False   # a drawn mesh has a normal map (update)
        self.drawn = None          # (key, output) of the last draw: a still redraw reuses it

    def stats(self) -> dict:
        """GPU bytes: vertex buffers (14 floats a corner) and the instance table."""
        corners = sum(e.triangles for e in self.entries.values()) * 3
        out = {"gbuffer_meshes": corners * 14 * 4}
        if self.rows is not None:
            out["gbuffer_instances"] = max(len(self.rows), 1) * TEXELS * 16
        return out

    def update(self, keys: list, meshes: dict, matrices: np.ndarray, visible,
               holdout=None) -> dict:
        """Sync with this frame's instances: `keys[i]` the mesh key of instance i, `meshes`
        {key: MeshData}, `matrices` float64 [n, 4, 4], `visible` bool [n] (camera-visible),
        `holdout` bool [n] or None (drawn as holdouts: gbuffer.glsl).
        Builds batches for new or re-extracted meshes, frees those no instance shows, and
        re-uploads the instance table when it changed. Returns counts (built, table_uploaded).
        The very same input objects as the last update (ExtractionCache's still frame: no walk)
        change nothing: no loop over the instances, no table rebuilt to compare."""
        source = (keys, meshes, matrices, visible, holdout)
        if self.source is not None and all(a is b for a, b in zip(source, self.source)):
            self.last = dict(self.last, built=0, table_uploaded=False)
            return self.last
        n = len(keys)
        mats = np.asarray(matrices, np.float64).reshape(n, 4, 4)
        ok = drawable(mats, np.asarray(visible, bool).reshape(n))
        index, ids = {}, np.empty(n, np.int64)
        for i, key in enumerate(keys):                  # key -> small int: a loop over objects
            ids[i] = index.setdefault(key, len(index))
        order = np.flatnonzero(ok)
        order = order[np.argsort(ids[order], kind="stable")]
        run_ids, starts, counts = np.unique(ids[order], return_index=True, return_counts=True)
        by_id = list(index)
        runs = [(by_id[k], int(s), int(c)) for k, s, c in zip(run_ids, starts, counts)]
        built = 0
        for key, _, _ in runs:
            data = meshes[key]
            entry = self.entries.get(key)
            if entry is None or entry.data is not data:
                self.entries[key] = self._build(data)
                built += 1
        drawn = {key for key, _, _ in runs}
        gone = [k for k in self.entries if k not in drawn]
        for key in gone:
            del self.entries[key]
        rows = table_rows(mats[order], None if holdout is None
                          else np.asarray(holdout, bool).reshape(n)[order])
        uploaded = False
        if self.rows is None or rows.shape != self.rows.shape or not np.array_equal(rows,
                                                                                    self.rows):
            data = rows if len(rows) else np.zeros((1, TEXELS, 4), np.float32)
            self.table = row_texture(data)    # 1,024 rows a line (row_table_lib.glsl)
            self.rows, uploaded = rows, True
            self.table_uploads += 1
        if built or uploaded or gone or runs != self.runs:
            self.generation += 1
        # whether a drawn mesh has a normal map: only then does the G-buffer pack shading
        # normals and do the direct light and the probes' integration read them (a viewport
        # redraw of a scene without one paid 2-4% for it: bench/frame_time.py)
        self.shading_normals = any(g["normal_tex"] is not None for key, _, _ in runs
                                   for _, g in self.entries[key].groups)
        self.runs = runs
        self.source = source
        self.built_total += built
        self.last = {"built": built, "table_uploaded": uploaded, "unique": len(runs),
                     "instances": int(len(order))}
        return self.last

    def _build(self, data) -> _Entry:
        from types import SimpleNamespace

        local = SimpleNamespace(vertices=data.vertices, triangles=data.triangles,
                                matrix_world=np.eye(4), normals=data.normals, uvs=data.uvs,
                                material_ids=data.material_ids, materials=data.materials,
                                colors=getattr(data, "colors", None),
                                tangents=getattr(data, "tangents", None), camera_visible=True)
        shader = instanced_shader()
        groups, triangles = [], 0
        for g in scene_triangles([local]):
            if not len(g["pos"]):
                continue
            triangles += len(g["pos"]) // 3
            batch = batch_for_shader(shader, 'TRIS', {name: g[name] for name in ATTRIBUTES})
            groups.append((batch, {k: g[k] for k in MATERIAL_KEYS}))
        return _Entry(data, groups, triangles)

    def draw(self, view_proj, width: int, height: int, footprint_scale: float = 1.0) -> dict:
        """The G-buffer of the synced instances for `view_proj`: gbuffer.render_gbuffer's
        output ({'textures', 'depth_texture', counts, timings}); nothing is read back.
        footprint_scale: the share of a pixel's texture footprint this G-buffer filters (one of
        n anti-aliasing samples: 1 / sqrt(n); gbuffer.glsl sample_mipmapped).
        The same view of the same instances as the last draw (a still viewport's redraws) is
        that draw's G-buffer again: nothing is drawn ('reused' True, draws 0), and what is built
        from it (the screen trace's HZB) can be kept too (its textures are the same objects).
        Nothing writes into a G-buffer once drawn."""
        import mathutils

        t0 = time.perf_counter()
        view_key = (np.asarray(view_proj, np.float64).tobytes(), int(width), int(height),
                    float(footprint_scale), self.generation)
        if footprint_scale == 1.0 and self.drawn is not None and self.drawn[0] == view_key:
            return dict(self.drawn[1], draws=0, texture_uploads=0, batches_built=0,
                        instance_table_uploaded=False, reused=True, draw_seconds=0.0,
                        seconds=time.perf_counter() - t0)
        shader = instanced_shader()
        used, uploaded, dummy = set(), 0, None

        def gpu_texture(arr):
            nonlocal uploaded
            key = id(arr)
            used.add(key)
            hit = self.textures.get(key)
            if hit is None or hit[0] is not arr:     # the array is kept alive: ids stay unique
                self.textures[key] = hit = (arr, upload_texture(arr))
                uploaded += 1
            return hit[1]

        textures = {name: gpu.types.GPUTexture((width, height), format='RGBA32F')
                    for name in ATTACHMENTS}
        depth = gpu.types.GPUTexture((width, height), format='DEPTH_COMPONENT32F')
        fb = gpu.types.GPUFrameBuffer(depth_slot=depth,
                                      color_slots=tuple(textures[n] for n in ATTACHMENTS))
        t1 = time.perf_counter()
        triangles = draws = 0
        with fb.bind():
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            gpu.state.depth_test_set('LESS_EQUAL')
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set('NONE')
            gpu.state.viewport_set(0, 0, width, height)
            shader.bind()
            shader.uniform_float("view_proj", mathutils.Matrix(
                np.asarray(view_proj, np.float64).tolist()))
            shader.uniform_sampler("instances", self.table)
            shader.uniform_float("footprint_scale", float(footprint_scale))
            shader.uniform_int("pack_shading", int(self.shading_normals))
            bound = None                  # the textures bound: set again only when they change
            for key, base, count in self.runs:
                entry = self.entries[key]
                triangles += entry.triangles * count
                for batch, g in entry.groups:
                    a_arr, e_arr, n_arr = g["albedo_tex"], g["emit_tex"], g["normal_tex"]
                    state = (id(a_arr), id(e_arr), id(n_arr), g["alpha_clip"],
                             g["normal_strength"], g["bump"], g["holdout"])
                    if state != bound:
                        if dummy is None and any(x is None for x in (a_arr, e_arr, n_arr)):
                            dummy = gpu.types.GPUTexture(
                                (1, 1), format='RGBA32F',
                                data=gpu.types.Buffer('FLOAT', 4, [1.0] * 4))
                        a_tex, a_h = gpu_texture(a_arr) if a_arr is not None else (dummy, 1)
                        e_tex, e_h = gpu_texture(e_arr) if e_arr is not None else (dummy, 1)
                        n_tex, n_h = gpu_texture(n_arr) if n_arr is not None else (dummy, 1)
                        shader.uniform_int("use_albedo_tex", int(a_arr is not None))
                        shader.uniform_int("alpha_clip", int(g["alpha_clip"]))
                        shader.uniform_int("use_emit_tex", int(e_arr is not None))
                        shader.uniform_int("albedo_base_h", int(a_h))
                        shader.uniform_int("emit_base_h", int(e_h))
                        shader.uniform_int("use_normal_tex", normal_mode(g))
                        shader.uniform_int("group_holdout", int(g["holdout"]))
                        shader.uniform_int("normal_base_h", int(n_h))
                        shader.uniform_float("normal_strength", float(g["normal_strength"]))
                        shader.uniform_sampler("albedo_tex", a_tex)
                        shader.uniform_sampler("emit_tex", e_tex)
                        shader.uniform_sampler("normal_tex", n_tex)
                        bound = state
                    shader.uniform_int("instance_base", base)
                    batch.draw_instanced(shader, instance_start=0, instance_count=count)
                    draws += 1
            gpu.state.depth_test_set('NONE')
            gpu.state.depth_mask_set(False)
        for key in [k for k in self.textures if k not in used]:
            del self.textures[key]
        out = {"textures": textures, "depth_texture": depth, "triangles": triangles,
               "draws": draws, "texture_uploads": uploaded, "textures_resident": len(self.textures),
               "batches_built": self.last.get("built", 0),
               "instance_table_uploaded": self.last.get("table_uploaded", False),
               "shading_normals": bool(self.shading_normals)}
        out["draw_seconds"] = time.perf_counter() - t1
        out["seconds"] = time.perf_counter() - t0
        out["reused"] = False
        if footprint_scale == 1.0:
            # the view's own G-buffer, kept while the anti-aliasing's jittered ones (each drawn
            # once) come and go between its redraws
            self.drawn = (view_key, out)
        return out
