"""The composite pass (glsl/composite.comp.glsl): Combined = albedo x (direct + indirect) + emission,
and the Diffuse Indirect pass (E_indirect / pi, Cycles' convention). Needs a GPU context."""
from __future__ import annotations

from . import compute

COMPOSITE = compute.Pass("composite",
                         samplers=("gbuf_position", "gbuf_albedo", "gbuf_emission", "direct",
                                   "indirect"),
                         images=("out_image", "indirect_out"),
                         push=(('MAT4', 'inv_view_proj'), ('FLOAT', 'film_alpha')))


def composite(gbuf: dict, direct_tex, indirect_tex, sky, inv_view_proj, width: int,
              height: int) -> dict:
    """{'textures': {'combined', 'indirect'}} (GPUTextures, not read back). sky: sky_light.SkyLight (the
    background pixels show its map along each camera ray)."""
    g = gbuf["textures"]
    combined = compute.texture((width, height))
    indirect = compute.texture((width, height))
    COMPOSITE.run((width, height), sky=sky, gbuf_position=g["position"], gbuf_albedo=g["albedo"],
                  gbuf_emission=g["emission"], direct=direct_tex, indirect=indirect_tex,
                  inv_view_proj=inv_view_proj, film_alpha=float(getattr(sky, "film_alpha", 1.0)),
                  out_image=combined, indirect_out=indirect)
    return {"textures": {"combined": combined, "indirect": indirect}}
