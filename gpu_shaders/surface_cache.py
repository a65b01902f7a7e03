"""The surface cache on the GPU: the bake's card atlas, the per-instance lighting atlas and its passes.

Textures (card_packing.py has the layouts):
    card atlas (the bake's, shared by the instances of a mesh):
        sc_albedo   RGBA16F  albedo.rgb, opacity
        sc_normal   RGBA32F  local normal.xyz, depth (32 bit: depths are metres along the card)
        sc_emissive RGBA16F  emissive.rgb
    tables: sc_cards RGBA32F (4 texels per (instance, card) row), sc_instances RGBA32F (card range
        per object-table row), texel_card R32F (lighting texel -> card row)
    lighting atlas (one rectangle per (instance, card)), RGBA32F:
        direct    E_direct, irradiance from the lights with SDF shadows (W/m^2), plus the
                  emitters nearer than the GI rays reach (sc_near_emission)
        indirect  E_indirect, irradiance from rays into the scene, read from `final` (next file)
        final     (E_direct + E_indirect) * albedo / pi + emissive: the radiance rays read at hits
The passes, one GLSL file each, run by this class's methods: surface_cache_direct (lights, near emitters),
surface_cache_probe_place / _probe_trace / _probe_sh / _indirect (radiosity probes: a site per 4x4
texels, 16 rays each
through gi_trace_lib.glsl, filtered, two-band SH, interpolated per texel), surface_cache_combine
(final), and for
the debug views surface_cache_layer / surface_cache_view. Reading last frame's `final` in the
indirect pass is what makes light bounce again every frame (the lecture's multi-bounce).
Needs a GPU context.
"""
from __future__ import annotations

import time

import gpu
import numpy as np

from . import compute
from .card_packing import CARD_TEXELS, PROBE_BLOCK, PackedCards, pack_cards
from .packing import row_table
from .resources import SceneResources, float_buffer
from .surface_cache_pages import TILE, TILE_PROBES, PageSchedule, tile_area, tile_geometry

GROUP = 8
RW = {'READ', 'WRITE'}
PAGES = ("sc_pages", "sc_tile_frame")


def _pass(name, samplers=(), push=(), images=("out_image",)):
    """A surface-cache pass: `texel_card` (texel -> card) first among its samplers."""
    return compute.Pass(name, samplers=("texel_card",) + tuple(samplers), images=images,
                        push=push)


DIRECT = _pass("surface_cache_direct", ("lights", "sc_pages"),
               (('INT', 'light_count'), ('INT', 'light_samples')))
PROBE_PLACE = _pass("surface_cache_probe_place", PAGES, (('INT', 'frame'),),
                    ("out_image", "probe_pos_out", "probe_room_out"))
# the rays to trace (the probes with a site, the rows the ray LOD keeps) listed and counted (read
# back), then traced one invocation each: surface_cache_probe_list.comp.glsl says why
PROBE_LIST = _pass("surface_cache_probe_list", ("sc_probes", "sc_probe_pos") + PAGES,
                   (('INT', 'frame'), ('VEC3', 'cam_pos'), ('FLOAT', 'lod_focal'),
                    ('FLOAT', 'lod_rays')),
                   ("out_image", ("ray_rows", 'RGBA32F'), ("row_counter", 'R32I', RW)))
RAY_GROUP = 64
PROBE_TRACE = compute.Pass("surface_cache_probe_trace",
                           samplers=("texel_card", "sc_probes", "sc_probe_pos", "ray_rows")
                           + PAGES,
                           push=(('INT', 'frame'), ('FLOAT', 't_max'), ('INT', 'row_count')),
                           group=(RAY_GROUP, 1, 1))
PROBE_SH = _pass("surface_cache_probe_sh",
                 ("sc_rays", "sc_probes", "sc_probe_pos", "sc_probe_room") + PAGES,
                 images=("out_image", "irradiance_out"))
INDIRECT = _pass("surface_cache_indirect",
                 ("sc_probes", "sc_probe_sh", "sc_probe_irradiance", "sc_probe_pos",
                  "sc_probe_room") + PAGES,
                 images=(("out_image", 'RGBA32F', RW), ("delta_image", 'RGBA32F', RW)))
COMBINE = _pass("surface_cache_combine", ("sc_direct", "sc_indirect", "sc_pages"))
LAYER = _pass("surface_cache_layer", ("sc_direct", "sc_indirect", "sc_tile_age"),
              (('INT', 'layer_mode'),))
VIEW = _pass("surface_cache_view", ("gbuf_position", "gbuf_normal"), (('VEC3', 'cam_pos'),))


def _tex(size, fmt, data=None):
    if data is None:
        return compute.texture(size, fmt)
    return gpu.types.GPUTexture(size, format=fmt, data=float_buffer(data))


def mark_emissive_cards(cards: np.ndarray, emissive: np.ndarray, instances=None) -> None:
    """cards[:, 3, 2] = how many emissive texels each card's card-atlas rectangle holds (a
    summed-area table, no loop over cards): sc_near_emission (surface_cache_lib.glsl) visits
    only cards with emission; and instances[:, 0, 2] (card_packing's (first row, count) rows)
    = how many of each instance's cards have any, so it skips the instances without (their
    matrices and card rows were 44% of surface_cache_direct among 1,000 unlit spheres)."""
    lit = np.asarray(emissive).max(axis=-1) > 0.0
    sat = np.zeros((lit.shape[0] + 1, lit.shape[1] + 1), np.float64)
    sat[1:, 1:] = lit.cumsum(0).cumsum(1)
    x, y, w, h = (cards[:, 1, k].astype(np.int64) for k in range(4))
    x1, y1 = np.minimum(x + w, lit.shape[1]), np.minimum(y + h, lit.shape[0])
    x0, y0 = np.minimum(x, x1), np.minimum(y, y1)
    cards[:, 3, 2] = sat[y1, x1] - sat[y0, x1] - sat[y1, x0] + sat[y0, x0]
    if instances is not None and len(instances):
        lit_rows = np.concatenate([[0], np.cumsum(cards[:, 3, 2] > 0)])
        first = instances[:, 0, 0].astype(np.int64)
        end = np.minimum(first + instances[:, 0, 1].astype(np.int64), len(cards))
        instances[:, 0, 2] = lit_rows[end] - lit_rows[np.minimum(first, end)]


class SurfaceCache:
    """Card and lighting textures of one scene state (see the module docstring)."""

    BYTES = {"RGBA16F": 8, "RGBA32F": 16, "R32F": 4, "R32I": 4}

    def __init__(self, atlas, instance_cards):
        t0 = time.perf_counter()
        self.packed: PackedCards = pack_cards(atlas, instance_cards)
        self.atlas = atlas
        self._alloc = {}
        aw, ah = self.packed.card_atlas_size
        if atlas is not None and atlas.table:
            layers = atlas.layers
        else:
            layers = {"albedo": np.zeros((ah, aw, 3)), "opacity": np.zeros((ah, aw, 1)),
                      "normal": np.zeros((ah, aw, 3)), "depth": np.zeros((ah, aw, 1)),
                      "emissive": np.zeros((ah, aw, 3))}
        rgba = np.empty((ah, aw, 4), np.float32)
        rgba[..., :3], rgba[..., 3] = layers["albedo"], layers["opacity"][..., 0]
        self.albedo = self._make("albedo", (aw, ah), 'RGBA16F', rgba)
        rgba[..., :3], rgba[..., 3] = layers["normal"], layers["depth"][..., 0]
        self.normal = self._make("normal", (aw, ah), 'RGBA32F', rgba)
        rgba[..., :3], rgba[..., 3] = layers["emissive"], 0.0
        self.emissive = self._make("emissive", (aw, ah), 'RGBA16F', rgba)
        mark_emissive_cards(self.packed.cards, layers["emissive"], self.packed.instances)
        # row tables (packing.row_table: 1,024 rows a line; row_table_lib.glsl)
        cards = row_table(np.asarray(self.packed.cards, np.float32).reshape(-1, CARD_TEXELS, 4))
        self.cards = self._make("cards", (cards.shape[1], cards.shape[0]), 'RGBA32F', cards)
        inst = row_table(np.asarray(self.packed.instances, np.float32).reshape(-1, 1, 4)
                         if len(self.packed.instances) else np.zeros((1, 1, 4), np.float32))
        self.instances = self._make("instances", (inst.shape[1], inst.shape[0]), 'RGBA32F', inst)
        lw, lh = self.packed.lighting_size
        self.texel_card = self._make("texel_card", (lw, lh), 'R32F', self.packed.texel_card)
        zero = np.zeros((lh, lw, 4), np.float32)
        self.direct = self._make("direct", (lw, lh), 'RGBA32F', zero)
        self.indirect = self._make("indirect", (lw, lh), 'RGBA32F', zero)
        self.delta = self._make("indirect_delta", (lw, lh), 'RGBA32F', zero)  # last updates
        self.final = self._make("final", (lw, lh), 'RGBA32F', zero)
        # Radiosity probes, kept across frames: a frame relights only some tiles (pages), the
        # others keep their last rays, probes and SH for the filter and the interpolation.
        gw, gh = -(-lw // 4), -(-lh // 4)
        self.probe_textures = {
            "rays": self._make("probe_rays", (gw * 4, gh * 4), 'RGBA32F', None),
            "probes": self._make("probes", (gw, gh), 'RGBA32F', None),
            "positions": self._make("probe_positions", (gw, gh), 'RGBA32F', None),
            "room": self._make("probe_room", (gw, gh), 'RGBA32F', None),
            "sh": self._make("probe_sh", (gw * 2, gh * 2), 'RGBA32F', None),
            "irradiance": self._make("probe_irradiance", (gw, gh), 'RGBA32F', None)}
        # this frame's rows of probe rays to trace (surface_cache_probe_list), at most 4 a probe
        self.ray_rows = self._make("probe_ray_rows", (gw * 4, gh), 'RGBA32F', None)
        self.row_counter = self._make("probe_row_counter", (1, 1), 'R32I', None)
        self.pages = PageSchedule(self.packed.texel_card, self.packed.cards[:, 0, 0]
                                  if self.packed.rows else np.zeros(0))
        tw, th = self.pages.grid
        self.tile_frame = self._make("tile_frame", (tw, th), 'R32F', self.pages.tile_frame)
        self.upload_seconds = time.perf_counter() - t0

    def _make(self, name, size, fmt, data):
        self._alloc[name] = (int(size[0]) * int(size[1]), fmt)
        return _tex(size, fmt, data)

    @property
    def has_cards(self) -> bool:
        return self.packed.texels > 0

    def reset_lighting(self):
        """Forget accumulated indirect light (the scene changed under it): every tile is then
        first in line, and no stale probe is filtered or interpolated (cleared: 'no probe')."""
        lw, lh = self.packed.lighting_size
        zero = np.zeros((lh, lw, 4), np.float32)
        self.indirect = _tex((lw, lh), 'RGBA32F', zero)
        self.delta = _tex((lw, lh), 'RGBA32F', zero)   # each texel's last update (relaxation)
        self.final = _tex((lw, lh), 'RGBA32F', zero)
        for tex in self.probe_textures.values():
            tex.clear(format='FLOAT', value=(0.0, 0.0, 0.0, 0.0))
        self.pages.reset()

    def refresh_lighting(self):
        """The viewport's answer to objects, lights or the sky changing: every tile is first in
        line again and restarts its blends (its update count reset, as reset_lighting), but keeps
        its light until it is relit, as Lumen's surface cache does. Why: reset_lighting zeroed
        the whole atlas, so moving one sphere among 1,000 left every tile not yet relit showing
        its emission alone (all the bounce light gone) for the ~160 redraws the budget takes to
        relight 1,299 tiles. The relaxation deltas are cleared (no over-relaxation from a step
        taken under the old scene)."""
        lw, lh = self.packed.lighting_size
        self.delta = _tex((lw, lh), 'RGBA32F', np.zeros((lh, lw, 4), np.float32))
        self.pages.reset()

    # --- binding for other passes ------------------------------------------------------------
    @staticmethod
    def declare(info, first_slot: int) -> int:
        """Declare surface_cache_lib.glsl's samplers; returns the next free slot."""
        for k, name in enumerate(("sc_cards", "sc_instances", "sc_albedo", "sc_normal",
                                  "sc_emissive", "sc_final")):
            info.sampler(first_slot + k, 'FLOAT_2D', name)
        return first_slot + 6

    def bind(self, shader):
        shader.uniform_sampler("sc_cards", self.cards)
        shader.uniform_sampler("sc_instances", self.instances)
        shader.uniform_sampler("sc_albedo", self.albedo)
        shader.uniform_sampler("sc_normal", self.normal)
        shader.uniform_sampler("sc_emissive", self.emissive)
        shader.uniform_sampler("sc_final", self.final)

    def stats(self) -> dict:
        """GPU bytes per texture, from the sizes and formats allocated."""
        return {"cards_" + k: n * self.BYTES[fmt] for k, (n, fmt) in self._alloc.items()}

    # --- passes --------------------------------------------------------------------------------
    def plan(self, frame: int, blend: float = 1.0, budget: int = 0, history: int = 1,
             where=None, fraction: float = 1.0, objects=None, cap: int = 0) -> tuple:
        """This frame's tiles and their blends, committed as relit at `frame`.
        budget <= 0 (F12): every tile, all with `blend`, or with fraction < 1 that fraction of
        them by PageSchedule.render_priority (`where`: view_proj, cam_pos; `objects`: the
        object table, for the tiles' world geometry); every tile on the first call after a
        reset. budget > 0 (viewport): at most `budget`
        tiles by priority (surface_cache_pages.py; `where`: instance_spheres, view_proj,
        cam_pos), blends by each tile's update count (PageSchedule.choose: `blend` for the
        bounces, then 1 / `history`). cap > 0 (F12): at most that many tiles once every tile
        is lit (PageSchedule.choose_render)."""
        if budget > 0:
            idx, blends = self.pages.choose(budget, frame, blend, history, **(where or {}))
        elif fraction < 1.0 or 0 < cap < len(self.pages):
            if objects is not None:
                self.ensure_geometry(objects)
            idx = self.pages.choose_render(fraction, frame, cap=cap, **(where or {}))
            blends = np.full(len(idx), float(blend))
        else:
            idx, blends = self._all_tiles(blend)
        self.pages.commit(idx, frame)
        tw, th = self.pages.grid
        self.tile_frame = _tex((tw, th), 'R32F', self.pages.tile_frame)
        return idx, blends

    def ensure_geometry(self, objects):
        """The tiles' world geometry and areas (tile_geometry, tile_area) for `seen` and the
        render priority, from the object table `objects`; kept until pages.set_geometry(None)
        (objects moved)."""
        if self.pages.geometry is None:
            tc, cards = self.packed.texel_card, self.packed.cards
            self.pages.set_geometry(tile_geometry(self.pages, tc, cards, objects),
                                    tile_area(self.pages, tc, cards, objects))

    def _all_tiles(self, blend: float = 1.0) -> tuple:
        return np.arange(len(self.pages)), np.full(len(self.pages), float(blend))

    def _page_table(self, tiles):
        idx, blends = tiles
        return _tex((max(len(idx), 1), 1), 'RGBA32F', self.pages.page_table(idx, blends))

    def light_direct(self, resources: SceneResources, light_tex, light_count: int,
                     light_samples: int = 8, tiles=None):
        """surface_cache_direct: E_direct of the lighting texels of `tiles` (plan(); None: all)."""
        tiles = tiles if tiles is not None else self._all_tiles()
        if not len(tiles[0]):
            return
        pages = self._page_table(tiles)       # held until the dispatch: a freed texture reads 0
        DIRECT.run_groups((len(tiles[0]) * TILE // GROUP, TILE // GROUP), scene=resources,
                          cache=self, texel_card=self.texel_card, lights=light_tex,
                          sc_pages=pages, light_count=int(light_count),
                          light_samples=int(light_samples), out_image=self.direct)

    def light_indirect(self, resources: SceneResources, gsdf, sky, frame: int, t_max: float,
                       tiles, voxels=None, lod=None) -> int:
        """E_indirect = mix(last E_indirect, this frame's probes, blend) on `tiles` (plan(): the
        tile indices and a blend each), in four passes over those tiles only:
        surface_cache_probe_place (each probe's site this frame, once for its rays),
        surface_cache_probe_trace (16 rays per probe of 4x4 texels, surface cache at hits),
        surface_cache_probe_sh (3x3 probe filter, two-band SH), surface_cache_indirect (per
        texel: 2x2 probes' SH irradiance at the texel's normal, temporal blend, in place).
        voxels: voxel_lighting.VoxelLighting, read at the rays' global-SDF hits (None: those are
        refined on the mesh SDFs). lod: (camera position, pixels per metre at 1 m, rays per
        pixel) for the trace's ray LOD (a probe far from the camera traces fewer rays; None: all
        16). Returns the number of tiles relit."""
        idx = tiles[0]
        if not len(idx):
            return 0
        pages = self._page_table(tiles)
        t = self.probe_textures
        k = len(idx)
        common = dict(scene=resources, cache=self, texel_card=self.texel_card, sc_pages=pages,
                      sc_tile_frame=self.tile_frame)
        PROBE_PLACE.run_groups((k * TILE_PROBES // GROUP, TILE_PROBES // GROUP), **common,
                               frame=int(frame), out_image=t["probes"],   # one per probe
                               probe_pos_out=t["positions"], probe_room_out=t["room"])
        self.row_counter.clear(format='INT', value=(0,))
        PROBE_LIST.run_groups((k * TILE_PROBES // GROUP, TILE_PROBES // GROUP), **common,
                              frame=int(frame),                          # one per probe
                              cam_pos=compute.vec(lod[0] if lod else (0.0, 0.0, 0.0)),
                              lod_focal=float(lod[1]) if lod else 0.0,
                              lod_rays=float(lod[2]) if lod else 0.0,
                              sc_probes=t["probes"], sc_probe_pos=t["positions"],
                              out_image=t["rays"], ray_rows=self.ray_rows,
                              row_counter=self.row_counter)
        listed = compute.read_counter(self.row_counter)
        if listed:
            PROBE_TRACE.run(listed * PROBE_BLOCK, **common, gsdf=gsdf, sky=sky,  # one per ray
                            voxels=voxels,
                            frame=int(frame), t_max=float(t_max), row_count=listed,
                            sc_probes=t["probes"], sc_probe_pos=t["positions"],
                            ray_rows=self.ray_rows, out_image=t["rays"])
        PROBE_SH.run_groups((k * TILE_PROBES // GROUP, TILE_PROBES // GROUP), **common,
                            sc_rays=t["rays"], sc_probes=t["probes"],   # one per probe
                            sc_probe_pos=t["positions"], sc_probe_room=t["room"],
                            out_image=t["sh"],
                            irradiance_out=t["irradiance"])
        INDIRECT.run_groups((k * TILE // GROUP, TILE // GROUP), **common,        # one per texel
                            sc_probes=t["probes"], sc_probe_sh=t["sh"],
                            sc_probe_irradiance=t["irradiance"], sc_probe_pos=t["positions"],
                            sc_probe_room=t["room"], out_image=self.indirect, delta_image=self.delta)  # in place: blend
        return k

    def indirect_total(self) -> float:
        """Sum of E_indirect (rgb) over the lighting atlas: F12's bounce convergence
        (gi_settings.bounces_converged), read back once per warm-up iteration."""
        return float(compute.read(self.indirect)[..., :3].sum(dtype=np.float64))

    def combine(self, resources: SceneResources, tiles=None):
        """surface_cache_combine: final = (direct + indirect) * albedo / pi + emissive on the
        texels of `tiles` (plan(); None: all), in place: the others keep their final light, so
        a viewport frame's combine costs its budget of tiles, not the whole atlas (1,000 small
        objects: 38-58 ms a frame at 128 px)."""
        tiles = tiles if tiles is not None else self._all_tiles()
        if not len(tiles[0]):
            return
        pages = self._page_table(tiles)
        COMBINE.run_groups((len(tiles[0]) * TILE // GROUP, TILE // GROUP), scene=resources,
                           cache=_Showing(self, self.direct),   # sc_final: not the one written
                           texel_card=self.texel_card, sc_direct=self.direct,
                           sc_indirect=self.indirect, sc_pages=pages, out_image=self.final)

    LAYERS = {"albedo": 0, "normal": 1, "direct": 2, "indirect": 3, "position": 4, "cards": 5,
              "updates": 7,
              "final": 6}

    def layer(self, resources: SceneResources, name: str):
        """surface_cache_layer: an RGBA32F lighting-atlas texture of one LAYERS view."""
        tw, th = self.pages.grid
        ages = _tex((tw, th), 'R32F', self.pages.ages())     # held until the dispatch
        out = _tex(self.packed.lighting_size, 'RGBA32F')
        LAYER.run(self.packed.lighting_size, scene=resources, cache=self,
                  texel_card=self.texel_card, sc_direct=self.direct, sc_indirect=self.indirect,
                  sc_tile_age=ages, layer_mode=self.LAYERS[name], out_image=out)
        return out

    def view(self, resources: SceneResources, gbuf: dict, cam_pos, width: int, height: int,
             name: str = "final") -> np.ndarray:
        """surface_cache_view: float32 [h, w, 4], the surface cache's `name` layer sampled at every
        G-buffer pixel through the cards (w: card weight, 0 where no card sees the pixel)."""
        source = self.final if name == "final" else self.layer(resources, name)
        out = _tex((width, height), 'RGBA32F')
        VIEW.run((width, height), scene=resources, cache=_Showing(self, source),
                 texel_card=self.texel_card, gbuf_position=gbuf["textures"]["position"],
                 gbuf_normal=gbuf["textures"]["normal"], cam_pos=compute.vec(cam_pos),
                 out_image=out)
        return compute.read(out)

    def read_layer(self, resources: SceneResources, name: str) -> np.ndarray:
        """float32 [h, w, 4] of a LAYERS view of the lighting atlas."""
        return compute.read(self.layer(resources, name))

    def read(self, name: str) -> np.ndarray:
        """float32 [h, w, 4] of a lighting texture ('direct', 'indirect', 'final')."""
        return compute.read(getattr(self, name))


class _Showing:
    """The cache bound with `final` in place of its final light (the view pass's layers)."""

    def __init__(self, cache, final):
        self.cache, self.final = cache, final

    def bind(self, shader):
        self.cache.bind(shader)
        shader.uniform_sampler("sc_final", self.final)
