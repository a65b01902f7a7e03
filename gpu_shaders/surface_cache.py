"""The surface cache on the GPU: the bake's card atlas, the per-instance lighting atlas and its passes.

Textures (card_packing.py has the layouts):
    card atlas (the bake's, shared by the instances of a mesh):
        sc_albedo   RGBA16F  albedo.rgb, opacity
        sc_normal   RGBA32F  local normal.xyz, depth (32 bit: depths are metres along the card)
        sc_emissive RGBA16F  emissive.rgb
    tables: sc_cards RGBA32F (4 texels per (instance, card) row), sc_instances RGBA32F (card range
        per object-table row), texel_card R32F (lighting texel -> card row)
    lighting atlas (one rectangle per (instance, card)), RGBA32F:
        direct    E_direct, irradiance from the lights with SDF shadows (W/m^2)
        indirect  E_indirect, irradiance from rays into the scene, read from `final` (next file)
        final     (E_direct + E_indirect) * albedo / pi + emissive: the radiance rays read at hits
The passes, one GLSL file each, run by this class's methods: surface_cache_direct (lights),
surface_cache_probe_trace / _probe_sh / _indirect (radiosity probes: 16 rays per 4x4 texels
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
from .card_packing import CARD_TEXELS, PackedCards, pack_cards
from .resources import SceneResources, float_buffer

GROUP = 8


def _tex(size, fmt, data=None):
    if data is None:
        return compute.texture(size, fmt)
    return gpu.types.GPUTexture(size, format=fmt, data=float_buffer(data))


class SurfaceCache:
    """Card and lighting textures of one scene state (see the module docstring)."""

    BYTES = {"RGBA16F": 8, "RGBA32F": 16, "R32F": 4}

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
        self.cards = self._make("cards", (CARD_TEXELS, self.packed.rows), 'RGBA32F', self.packed.cards)
        self.instances = self._make("instances", (1, max(len(self.packed.instances), 1)), 'RGBA32F',
                                    self.packed.instances if len(self.packed.instances)
                                    else np.zeros((1, 1, 4), np.float32))
        lw, lh = self.packed.lighting_size
        self.texel_card = self._make("texel_card", (lw, lh), 'R32F', self.packed.texel_card)
        zero = np.zeros((lh, lw, 4), np.float32)
        self.direct = self._make("direct", (lw, lh), 'RGBA32F', zero)
        self.indirect = self._make("indirect", (lw, lh), 'RGBA32F', zero)
        self.final = self._make("final", (lw, lh), 'RGBA32F', zero)
        self.frames = 0                # indirect passes accumulated since the last reset
        self.probe_textures = {}       # the last indirect pass's probe rays, probes and SH
        self.upload_seconds = time.perf_counter() - t0

    def _make(self, name, size, fmt, data):
        self._alloc[name] = (int(size[0]) * int(size[1]), fmt)
        return _tex(size, fmt, data)

    @property
    def has_cards(self) -> bool:
        return self.packed.texels > 0

    def reset_lighting(self):
        """Forget accumulated indirect light (the scene changed under it)."""
        lw, lh = self.packed.lighting_size
        zero = np.zeros((lh, lw, 4), np.float32)
        self.indirect = _tex((lw, lh), 'RGBA32F', zero)
        self.final = _tex((lw, lh), 'RGBA32F', zero)
        self.frames = 0

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
    def light_direct(self, resources: SceneResources, light_tex, light_count: int,
                     light_samples: int = 8):
        """surface_cache_direct: E_direct of every lighting texel."""
        sh = pass_shader("surface_cache_direct", ("light_lib.glsl",), ("lights",),
                         (('INT', 'light_count'), ('INT', 'light_samples')))
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("lights", light_tex)
        sh.uniform_int("light_count", int(light_count))
        sh.uniform_int("light_samples", int(light_samples))
        sh.image("out_image", self.direct)
        self._dispatch(sh)

    def light_indirect(self, resources: SceneResources, gsdf, sky, frame: int, blend: float,
                       t_max: float):
        """E_indirect = mix(last E_indirect, this frame's probes, blend), in three passes:
        surface_cache_probe_trace (16 rays per probe of 4x4 texels, surface cache at hits),
        surface_cache_probe_sh (3x3 probe filter, two-band SH), surface_cache_indirect (per
        texel: 2x2 probes' SH irradiance at the texel's normal, temporal blend)."""
        lw, lh = self.packed.lighting_size
        gw, gh = -(-lw // 4), -(-lh // 4)
        probe_libs = ("sampling_lib.glsl", "sh_lib.glsl", "surface_cache_probe_lib.glsl")
        rays, probes = _tex((gw * 4, gh * 4), 'RGBA32F'), _tex((gw, gh), 'RGBA32F')
        probe_pos = _tex((gw, gh), 'RGBA32F')
        sh = pass_shader("surface_cache_probe_trace",
                         probe_libs + ("gi_trace_lib.glsl",), (),
                         (('VEC3', 'sky'), ('INT', 'frame'), ('FLOAT', 't_max')),
                         images=("probe_out", "probe_pos_out"), gsdf=True)
        resources.bind(sh)
        self.bind(sh)
        gsdf.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_float("sky", [float(c) for c in np.asarray(sky, np.float64)[:3]])
        sh.uniform_int("frame", int(frame))
        sh.uniform_float("t_max", float(t_max))
        sh.image("out_image", rays)
        sh.image("probe_out", probes)
        sh.image("probe_pos_out", probe_pos)
        compute.run(sh, -(-gw * 4 // GROUP), -(-gh * 4 // GROUP), 1)

        coeffs = _tex((gw * 2, gh * 2), 'RGBA32F')
        irradiance = _tex((gw, gh), 'RGBA32F')
        sh = pass_shader("surface_cache_probe_sh", probe_libs, ("sc_rays", "sc_probes", "sc_probe_pos"),
                         (('INT', 'frame'),), images=("irradiance_out",))
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("sc_rays", rays)
        sh.uniform_sampler("sc_probes", probes)
        sh.uniform_sampler("sc_probe_pos", probe_pos)
        sh.uniform_int("frame", int(frame))
        sh.image("out_image", coeffs)
        sh.image("irradiance_out", irradiance)
        compute.run(sh, -(-gw // GROUP), -(-gh // GROUP), 1)

        sh = pass_shader("surface_cache_indirect", probe_libs,
                         ("sc_probes", "sc_probe_sh", "sc_probe_irradiance", "sc_probe_pos",
                          "sc_indirect_prev"), (('FLOAT', 'blend'),))
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("sc_probes", probes)
        sh.uniform_sampler("sc_probe_sh", coeffs)
        sh.uniform_sampler("sc_probe_irradiance", irradiance)
        sh.uniform_sampler("sc_probe_pos", probe_pos)
        sh.uniform_sampler("sc_indirect_prev", self.indirect)
        sh.uniform_float("blend", float(blend))
        out = _tex(self.packed.lighting_size, 'RGBA32F')
        sh.image("out_image", out)
        self._dispatch(sh)
        self.indirect = out
        self.probe_textures = {"rays": rays, "probes": probes, "sh": coeffs,
                               "irradiance": irradiance, "positions": probe_pos}
        self.frames += 1

    def combine(self, resources: SceneResources):
        """surface_cache_combine: final = (direct + indirect) * albedo / pi + emissive."""
        sh = pass_shader("surface_cache_combine", (), ("sc_direct", "sc_indirect"))
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("sc_direct", self.direct)
        sh.uniform_sampler("sc_indirect", self.indirect)
        out = _tex(self.packed.lighting_size, 'RGBA32F')
        sh.image("out_image", out)
        self._dispatch(sh)
        self.final = out

    LAYERS = {"albedo": 0, "normal": 1, "direct": 2, "indirect": 3, "position": 4, "cards": 5,
              "final": 6}

    def layer(self, resources: SceneResources, name: str):
        """surface_cache_layer: an RGBA32F lighting-atlas texture of one LAYERS view."""
        sh = pass_shader("surface_cache_layer", (), ("sc_direct", "sc_indirect"),
                         (('INT', 'layer_mode'),))
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("sc_direct", self.direct)
        sh.uniform_sampler("sc_indirect", self.indirect)
        sh.uniform_int("layer_mode", self.LAYERS[name])
        out = _tex(self.packed.lighting_size, 'RGBA32F')
        sh.image("out_image", out)
        self._dispatch(sh)
        return out

    def view(self, resources: SceneResources, gbuf: dict, cam_pos, width: int, height: int,
             name: str = "final") -> np.ndarray:
        """surface_cache_view: float32 [h, w, 4], the surface cache's `name` layer sampled at every
        G-buffer pixel through the cards (w: card weight, 0 where no card sees the pixel)."""
        sh = pass_shader("surface_cache_view", ("gbuffer_lib.glsl",),
                         ("gbuf_position", "gbuf_normal"),
                         (('VEC3', 'cam_pos'),))
        source = self.final if name == "final" else self.layer(resources, name)
        resources.bind(sh)
        self.bind(sh)
        sh.uniform_sampler("sc_final", source)
        sh.uniform_sampler("texel_card", self.texel_card)
        sh.uniform_sampler("gbuf_position", gbuf["textures"]["position"])
        sh.uniform_sampler("gbuf_normal", gbuf["textures"]["normal"])
        sh.uniform_float("cam_pos", [float(c) for c in np.asarray(cam_pos, np.float64)[:3]])
        out = _tex((width, height), 'RGBA32F')
        sh.image("out_image", out)
        compute.run(sh, -(-width // GROUP), -(-height // GROUP), 1)
        return compute.read(out)

    def read_layer(self, resources: SceneResources, name: str) -> np.ndarray:
        """float32 [h, w, 4] of a LAYERS view of the lighting atlas."""
        return compute.read(self.layer(resources, name))

    def _dispatch(self, sh):
        lw, lh = self.packed.lighting_size
        compute.run(sh, -(-lw // GROUP), -(-lh // GROUP), 1)

    def read(self, name: str) -> np.ndarray:
        """float32 [h, w, 4] of a lighting texture ('direct', 'indirect', 'final')."""
        return compute.read(getattr(self, name))


def pass_shader(name: str, libs=(), samplers=(), push=(), images=(), gsdf=False):
    """compute.shader for a surface-cache pass: the SDF and surface-cache samplers, `texel_card`
    and the extra 2D `samplers`, an RGBA32F `out_image` and more write-only `images`, `push`
    constants ((type, name)), with gsdf the global SDF's; surface_cache_texel_lib.glsl and `libs`
    before glsl/<name>.comp.glsl."""
    return compute.shader(name, samplers=("texel_card",) + tuple(samplers),
                          images=("out_image",) + tuple(images), push=push,
                          libs=("surface_cache_texel_lib.glsl",) + tuple(libs), scene=True,
                          surface_cache=True, global_sdf=gsdf)
