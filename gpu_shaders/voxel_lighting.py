"""Voxel lighting (lecture 21, "Voxel Clipmap for Radiance Caching of the Whole Scene"): the light
of the scene's surfaces in the global SDF's clipmap voxels, 6 axis directions per voxel, so that a
global-SDF hit reads its light from a few voxels: it is found among its tile's objects only and
needs no surface-cache lookup, whose cost grew with the number of objects (gi_trace_lib.glsl).

Design choice: the voxels ARE the global SDF's (global_sdf.py): the same 4 levels, N^3 voxels per
level, voxel size and toroidal texel addressing, so a hit found in level k reads level k's voxels
at the hit's own texel coordinates (no second clipmap to place or scroll, and a level's voxels
follow its distances). The lecture's 64^3 x 4 at 0.78 m (50 m) is the HIGH preset's 64^3 at
0.1-0.8 m here; MEDIUM is 48^3 at 0.125-1 m.

Per level update, two passes (glsl/voxel_lighting_*.comp.glsl):
    voxel_lighting_tiles   per 4x4x4 voxels: the 32 objects whose bounding spheres come nearest
                           within reach (the lecture's per-tile object filter; gi_trace searches
                           these too), every voxel cleared, the voxels near a surface (the global
                           SDF's own texel) and not inside a solid appended to a list (the
                           lecture's "compact")
    voxel_lighting_update  per listed voxel: 6 short rays along the axes through the tile's
                           objects only, the surface cache's final light at each hit
A level's list and its faces' hits (object, local point and normal) depend on the geometry only,
so they are kept per level: while the level's global SDF has not been built or scrolled again and
no object changed (`update(geometry=True)` says one did), an update skips the tiles pass and the rays and samples
the surface cache at the kept hits (vl_trace 0). Why: an F12 render relights every level after
each of its 10-20 iterations, the same rays every time (bench/pass_profile.py --f12 --scene
window: voxel_lighting_update 11% of the render). Memory: 12 RGBA32F texels per list entry.
Why a list: llvmpipe runs every invocation through all of a shader's code (divergent branches
are masked, not skipped): measured on the 48^3 levels of bench/frame_time.py's scene, the heavy
shader over every voxel took 230-290 ms per level, ~30 ms of it with every invocation returning
at once. The list holds `capacity` voxels per level update (default N^3 / 4, the budget; the
heavy pass always runs that many invocations, those past the end return at once): voxels past a
full list stay empty, and their hits read the surface cache (`read_count` tells, for tests).

Texture: one RGBA16F 2D texture, 24 N x N^2 (all levels, 6 faces each: rgb radiance, a = how far
along the face's ray a surface was met, signed by whether the surface cache lit it; 0: none), one
sampler; the tiles' object lists another (SAMPLERS, for the passes that trace). The lookup
(voxel_lighting_lib.glsl) leaves out the faces without a lit surface and the voxels that may not
light the ray (inside a solid, behind the hit surface, across a thin wall).
Cadence (`update`, twice per GI iteration in gi.py): before the rays, the levels whose clipmap
moved (all after a reset); after the combine, level k every 2^k frames as the global SDF, every
level on F12 and after a hard reset (`everything`), so the rays read the last combine's light at
voxel hits as at mesh hits. After the viewport's soft refresh (objects, lights or the sky
changed: the surface cache keeps its light) each level re-traces on its own frame instead:
`geometry=True` marks every level's hits stale (the redraw after one sphere moved among 1,000
spent 215 ms re-tracing all four at once). Needs a GPU context.
"""
from __future__ import annotations

import time

from . import compute
from .global_sdf_ref import LEVELS

FACES = 6
TILE = 4                 # voxels per tile side (voxel_lighting_tiles.comp.glsl's VL_TILE)
TILE_OBJECTS = 32        # objects kept per tile (VL_TILE_OBJECTS)
LIST_WIDTH = 256         # VL_LIST_WIDTH
FORMAT = 'RGBA16F'
BYTES = {'RGBA16F': 8, 'R32F': 4}
SAMPLER = "vl_radiance"
TILES = "vl_tiles"
SAMPLERS = (SAMPLER, TILES)   # voxel_lighting_lib.glsl's and voxel_lighting_trace_lib.glsl's
# voxel_lighting_tiles appends to the list with an atomic add on an R32I image
TILES_PASS = compute.Pass("voxel_lighting_tiles",
                          images=(("out_image", 'R32F'), ("vl_faces_out", FORMAT),
                                  ("vl_list_out", 'R32F'),
                                  ("vl_counter", 'R32I', {'READ', 'WRITE'})),
                          push=(('INT', 'vl_level'), ('FLOAT', 'vl_reach'),
                                ('INT', 'vl_capacity')))
UPDATE = compute.Pass("voxel_lighting_update", samplers=("vl_tiles", "vl_list"),
                      images=(("out_image", FORMAT), ("vl_hits", 'RGBA32F', {'READ', 'WRITE'})),
                      push=(('INT', 'vl_level'), ('INT', 'vl_trace')))
HIT_TEXELS = 2 * FACES   # vl_hits texels per list entry
VIEW = compute.Pass("voxel_lighting_view", samplers=("gbuf_position", "gbuf_normal"),
                    push=(('VEC3', 'cam_pos'),))


def _placeholder():
    """A 1x1 texture: bound where a pass traces without voxel lighting (vl_enabled() is false:
    every global-SDF hit is searched on every mesh SDF, as before). Callers hold it until the
    dispatch."""
    return compute.texture((1, 1), FORMAT)


def declare_radiance(info, slot: int) -> int:
    """voxel_lighting_lib.glsl's sampler (compute.Pass: its includer's `voxels=`)."""
    info.sampler(slot, 'FLOAT_2D', SAMPLER)
    return slot + 1


def declare_tiles(info, slot: int) -> int:
    """voxel_lighting_trace_lib.glsl's sampler: the tiles' object lists."""
    info.sampler(slot, 'FLOAT_2D', TILES)
    return slot + 1


def bind_radiance(shader, voxel_lighting):
    """SAMPLER to `voxel_lighting`, or a placeholder when None (returned: hold it until the
    dispatch; vl_enabled() is false)."""
    if voxel_lighting is not None:
        voxel_lighting.bind(shader)
        return None
    tex = _placeholder()
    shader.uniform_sampler(SAMPLER, tex)
    return tex


def bind_tiles(shader, voxel_lighting):
    """TILES to `voxel_lighting`'s, or a placeholder when None (returned, as bind_radiance)."""
    tex = voxel_lighting.tiles if voxel_lighting is not None else _placeholder()
    shader.uniform_sampler(TILES, tex)
    return None if voxel_lighting is not None else tex


def bind(shader, voxel_lighting):
    """Bind SAMPLERS to `voxel_lighting` (or, when None, to a placeholder: returned, keep it
    until the dispatch)."""
    if voxel_lighting is not None:
        voxel_lighting.bind(shader)
        shader.uniform_sampler(TILES, voxel_lighting.tiles)
        return voxel_lighting.texture
    tex = _placeholder()
    shader.uniform_sampler(SAMPLER, tex)
    shader.uniform_sampler(TILES, tex)
    return tex


class VoxelLighting:
    """The voxel lighting of one global SDF's clipmaps (see the module docstring)."""

    def __init__(self, n: int, capacity: int = 0):
        n = int(n)
        if n % TILE:
            raise ValueError(f"voxel lighting needs N divisible by {TILE} (got {n})")
        self.n = n
        self.capacity = -(-(int(capacity) or n ** 3 // 4) // LIST_WIDTH) * LIST_WIDTH
        self.texture = compute.texture((LEVELS * FACES * n, n * n), FORMAT)
        tn = n // TILE
        self.tiles = compute.texture((TILE_OBJECTS * tn, LEVELS * tn * tn), 'R32F')
        rows = self.capacity // LIST_WIDTH
        self.lists = [compute.texture((LIST_WIDTH, rows), 'R32F') for _ in range(LEVELS)]
        self.hits = [None] * LEVELS           # per level, made at its first traced update
        self.list = self.lists[0]             # the last updated level's list (read_count)
        self.traced = [None] * LEVELS         # (origin, global-SDF build, epoch) of the hits
        self.epoch = 0                        # counts update(geometry=True)
        self.counter = compute.texture((1, 1), 'R32I')
        self.gsdf = None                      # the GlobalSDF the levels were made for
        self.origins = [None] * LEVELS        # that clipmap's origin at each level's last update
        self.last_update = [None] * LEVELS
        self.log = []                         # (frame, level, seconds)
        self.retrace_frame = None             # the frame of the last level re-traced

    def update(self, resources, gsdf, cache, frame: int, everything: bool = False,
               aligned_only: bool = False, geometry: bool = False) -> list:
        """Relight levels from the surface cache's final light (after gsdf.update of the same
        frame: the levels read its origins and texels); returns the levels updated.
        aligned_only (before a frame's rays): only the levels whose clipmap moved or that were
        never built, so that every voxel sits where its global-SDF texel does. Otherwise (after
        the frame's combine, so this combine's light is what the rays read next, at voxel hits
        as at mesh hits): the levels due this frame (level k every 2^k frames, unless already
        done this frame), or all of them with `everything`.
        geometry: the objects may have changed since the last update (every level's rays are
        traced again; otherwise a level whose clipmap stayed reuses its hits).
        Without `everything`, one level a frame re-traces for the objects (the finest due
        first): another level due that frame whose clipmap stayed relights at its old hits and
        re-traces on a later turn. Why: on a frame when all four are due, the redraw after one
        sphere moved among 1,000 spent 217 of its 527 ms re-tracing them (bench/object_scaling.py
        --move); while an object is dragged, the coarse levels, whose voxels are metres across,
        keep its light from a few frames back. A clipmap that moved re-traces at once (its
        voxels are other voxels)."""
        if gsdf.n != self.n:
            raise ValueError("voxel lighting and global SDF differ in N")
        if gsdf is not self.gsdf:
            self.gsdf, self.origins = gsdf, [None] * LEVELS
            geometry = True
        if geometry:
            self.epoch += 1
        if not cache.has_cards:
            return []
        done = []
        for k in range(LEVELS):
            origin = gsdf.origins[k]
            moved = self.origins[k] is None or origin != self.origins[k]
            due = moved or (not aligned_only and (everything or (
                int(frame) % (1 << k) == 0 and self.last_update[k] != int(frame))))
            if not due:
                continue
            t0 = time.perf_counter()
            stale = self.traced[k] != self._trace_key(k, gsdf)
            later = (stale and not moved and not everything and self.hits[k] is not None
                     and self.retrace_frame == int(frame))
            self._dispatch(k, resources, gsdf, cache, light_only=later)
            if stale and not later:
                self.retrace_frame = int(frame)
            self.origins[k], self.last_update[k] = origin, int(frame)
            self.log.append((int(frame), k, time.perf_counter() - t0))
            done.append(k)
        del self.log[:-64]
        return done

    def _trace_key(self, level: int, gsdf):
        """What a level's list and hits were made for: the level's global-SDF build (its list
        reads that field) and the objects (its rays)."""
        return (gsdf.origins[level], gsdf.last_update[level], self.epoch)

    def _dispatch(self, level: int, resources, gsdf, cache, light_only: bool = False):
        tn = self.n // TILE
        v = gsdf.voxels[level]
        self.list = self.lists[level]
        key = self._trace_key(level, gsdf)
        if self.traced[level] == key or light_only:    # the kept list and hits: new light only
            UPDATE.run((LIST_WIDTH, self.capacity // LIST_WIDTH), scene=resources, cache=cache,
                       gsdf=gsdf, vl_tiles=self.tiles, vl_list=self.list, vl_level=level,
                       vl_trace=0, out_image=self.texture, vl_hits=self.hits[level])
            return
        if self.hits[level] is None:
            self.hits[level] = compute.texture(
                (LIST_WIDTH * HIT_TEXELS, self.capacity // LIST_WIDTH), 'RGBA32F')
        self.list.clear(format='FLOAT', value=(-1.0,))
        self.counter.clear(format='INT', value=(0,))
        # a face ray reaches one voxel past its voxel, plus the thin-wall hit shell
        TILES_PASS.run((tn, tn * tn), scene=resources, gsdf=gsdf, vl_level=level,
                       vl_reach=float(1.5 * v + 2.0 * gsdf.thin_margin()),
                       vl_capacity=self.capacity, out_image=self.tiles,
                       vl_faces_out=self.texture, vl_list_out=self.list,
                       vl_counter=self.counter)
        UPDATE.run((LIST_WIDTH, self.capacity // LIST_WIDTH), scene=resources, cache=cache,
                   gsdf=gsdf, vl_tiles=self.tiles, vl_list=self.list, vl_level=level,
                   vl_trace=1, out_image=self.texture, vl_hits=self.hits[level])
        self.traced[level] = key

    def read_count(self) -> int:
        """Voxels the last level update listed (== capacity: the list was full, voxels may have
        been left out). A read-back: tests and debugging only."""
        return int((compute.read(self.list)[..., 0] >= 0).sum())

    # --- reading from other passes ------------------------------------------------------------
    def bind(self, shader):
        """Set voxel_lighting_lib.glsl's sampler (a compute.Pass including it: voxels=)."""
        shader.uniform_sampler(SAMPLER, self.texture)

    def view(self, gsdf, gbuf: dict, cam_pos, width: int, height: int):
        """glsl/voxel_lighting_view.comp.glsl (the VOXEL_LIGHTING debug view): float32 [h, w, 4],
        per pixel what a global-SDF hit there reads (w = level + 1; magenta, w = 0: no voxel face;
        background w = -1)."""
        g = gbuf["textures"]
        out = compute.texture((width, height))
        VIEW.run((width, height), gsdf=gsdf, voxels=self, gbuf_position=g["position"],
                 gbuf_normal=g["normal"], cam_pos=compute.vec(cam_pos), out_image=out)
        return compute.read(out)

    def read(self):
        """float32 [LEVELS, 6, n, n, n, 4] ([level, face, z, y, x, rgba]) in texel order: texel t
        of level k holds world cell origin + ((t - origin) mod n) (global_sdf_ref.texel_cells)."""
        n = self.n
        data = compute.read(self.texture)                  # [n*n (z, y), 24 n (level, face, x), 4]
        data = data.reshape(n, n, LEVELS, FACES, n, 4)     # z, y, level, face, x, c
        return data.transpose(2, 3, 0, 1, 4, 5).copy()

    def stats(self) -> dict:
        """GPU bytes of the radiance texture, the tiles' object lists and the update list."""
        return {"voxel_lighting": self.texture.width * self.texture.height * BYTES[FORMAT],
                "voxel_lighting_tiles": (self.tiles.width * self.tiles.height
                                         + self.list.width * self.list.height * LEVELS + 1) * 4,
                "voxel_lighting_hits": sum(h.width * h.height * 16 for h in self.hits
                                           if h is not None)}
