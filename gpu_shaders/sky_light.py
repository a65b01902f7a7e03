"""The world's radiance maps on the GPU (lumen_addon.sky.SkyMaps -> one RGBA32F texture read by
glsl/sky_lib.glsl). Uploaded when the world's maps change (their content key), never per frame.
update() needs a GPU context."""
from __future__ import annotations

import numpy as np

SAMPLER = "sky_maps"


class SkyLight:
    def __init__(self):
        self.key = None
        self.texture = None
        self.maps = None
        self.uploads = 0
        # the background's alpha: 0 with Film > Transparent (the engine sets it per frame),
        # whose background shows nothing (rgb 0: Combined is premultiplied, as Cycles')
        self.film_alpha = 1.0

    @staticmethod
    def declare(info, first_slot: int) -> int:
        """Declare sky_lib.glsl's sampler; returns the next free sampler slot."""
        info.sampler(first_slot, 'FLOAT_2D', SAMPLER)
        return first_slot + 1

    def update(self, maps) -> bool:
        """Upload `maps` (sky.SkyMaps) unless the same maps are on the GPU; True if uploaded."""
        if self.texture is not None and maps.key == self.key:
            self.maps = maps
            return False
        import gpu

        from .resources import float_buffer

        atlas = maps.atlas()
        self.texture = gpu.types.GPUTexture((atlas.shape[1], atlas.shape[0]), format='RGBA32F',
                                            data=float_buffer(atlas))
        self.key, self.maps = maps.key, maps
        self.uploads += 1
        return True

    def bind(self, shader):
        shader.uniform_sampler(SAMPLER, self.texture)

    @property
    def mean(self) -> np.ndarray:
        return np.asarray(self.maps.mean if self.maps is not None else np.zeros(3), np.float64)

    def stats(self) -> dict:
        t = self.texture
        return {"sky": 0 if t is None else t.width * t.height * 16}
