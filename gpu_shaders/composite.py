"""The composite pass (glsl/composite.comp.glsl): Combined = albedo x (direct + indirect) + emission,
and the Diffuse Indirect pass (E_indirect / pi, Cycles' convention). Needs a GPU context."""
from __future__ import annotations

from . import compute


def composite(gbuf: dict, direct_tex, indirect_tex, sky, width: int, height: int) -> dict:
    """{'combined', 'indirect'}: float32 [h, w, 4] read back."""
    g = gbuf["textures"]
    combined = compute.texture((width, height))
    indirect = compute.texture((width, height))
    sh = compute.shader("composite", samplers=("gbuf_position", "gbuf_albedo", "gbuf_emission",
                                               "direct", "indirect"),
                        images=("out_image", "indirect_out"), push=(('VEC3', 'sky'),))
    sh.uniform_sampler("gbuf_position", g["position"])
    sh.uniform_sampler("gbuf_albedo", g["albedo"])
    sh.uniform_sampler("gbuf_emission", g["emission"])
    sh.uniform_sampler("direct", direct_tex)
    sh.uniform_sampler("indirect", indirect_tex)
    sh.uniform_float("sky", compute.vec(sky))
    sh.image("out_image", combined)
    sh.image("indirect_out", indirect)
    compute.dispatch(sh, width, height)
    return {"combined": compute.read(combined), "indirect": compute.read(indirect),
            "textures": {"combined": combined, "indirect": indirect}}
