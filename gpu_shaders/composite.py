"""The composite pass (glsl/composite.comp.glsl): Combined = albedo x (direct + indirect) + emission,
and the Diffuse Indirect pass (E_indirect / pi, Cycles' convention). Needs a GPU context."""
from __future__ import annotations

import mathutils
import numpy as np

from . import compute


def composite(gbuf: dict, direct_tex, indirect_tex, sky, inv_view_proj, width: int,
              height: int) -> dict:
    """{'textures': {'combined', 'indirect'}} (GPUTextures, not read back). sky: sky_light.SkyLight (the
    background pixels show its map along each camera ray)."""
    g = gbuf["textures"]
    combined = compute.texture((width, height))
    indirect = compute.texture((width, height))
    sh = compute.shader("composite", samplers=("gbuf_position", "gbuf_albedo", "gbuf_emission",
                                               "direct", "indirect"),
                        images=("out_image", "indirect_out"), push=(('MAT4', 'inv_view_proj'),))
    sh.uniform_sampler("gbuf_position", g["position"])
    sh.uniform_sampler("gbuf_albedo", g["albedo"])
    sh.uniform_sampler("gbuf_emission", g["emission"])
    sh.uniform_sampler("direct", direct_tex)
    sh.uniform_sampler("indirect", indirect_tex)
    sky.bind(sh)
    sh.uniform_float("inv_view_proj",
                     mathutils.Matrix(np.asarray(inv_view_proj, np.float64).tolist()))
    sh.image("out_image", combined)
    sh.image("indirect_out", indirect)
    compute.dispatch(sh, width, height)
    return {"textures": {"combined": combined, "indirect": indirect}}
