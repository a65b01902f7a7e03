"""How much memory and time a bake will take, from sizes alone (no mesh is read or hashed).

A bake of 2 million triangles takes about half a minute and close to 2 GB, so the user is told
before it starts (the N-panel shows the estimate, the bake operator asks for confirmation when
it is large). The estimate needs, per unique mesh, its triangle count and local bounds size:
    SDF     Max Resolution and the voxel density decide the grid (sdf.plan_resolution); the bake
            keeps dense grids of the mip-0 samples, and its triangle pairs grow with triangles
    cards   texels: the six faces of the bounds at the texel density (capped by the texel budget)
    inputs  every mesh's extracted arrays stay in memory for the whole bake
Coefficients are least-squares fits to real bakes (bench/bake_estimate.py). Seconds are CPU
seconds of one core (the bake's numpy and Embree work runs on up to all cores, so an idle machine
takes about this long or less; a busy one longer); bytes are the peak above Blender's own.
Meshes the last bake can reuse are not subtracted (that needs their content hashes): the
estimate is for a bake from scratch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bake import sdf_scale
from .sdf import plan_resolution


def _sdf_scale(world_scale: float) -> float:
    """bake.sdf_scale of an object whose largest axis scale is world_scale."""
    return sdf_scale(np.diag([world_scale, world_scale, world_scale, 1.0]))


# Least-squares fits (relative error) to 15 bakes of bench/bake_estimate.py: 5.9k to 1.6M
# triangles at 64, 126 and 252 voxels; largest error 24% (memory) and 26% (CPU seconds).
SECONDS_PER_MESH = 0.04
SECONDS_PER_TRIANGLE = 1.5e-5
SECONDS_PER_SAMPLE = 3.5e-7          # per mip-0 grid sample
SECONDS_PER_TEXEL = 4.4e-6
BYTES_PER_INPUT_TRIANGLE = 135.0     # every mesh's extracted arrays, held for the whole bake
BYTES_PER_ROOT_TRIANGLE = 1.0e6      # x sqrt(triangles) of the mesh being baked: its triangle
                                     # pairs and ray batches (measured to grow as about T^0.56)
BYTES_PER_SAMPLE = 63.0              # dense grids of the mesh being baked
# GPU bytes per atlas texel while rendering (gpu_shaders/surface_cache.py stats(): the card
# layers albedo/emissive RGBA16F and normal RGBA32F, the lighting atlas's direct, indirect, final
# and probe-ray RGBA32F images, probe SH and tables; measured 2.61 MB for 25k texels)
GPU_BYTES_PER_TEXEL = 105.0


def texel_budget_text(budget: int) -> str:
    """What a texel budget means: the square atlas it fills and its GPU memory."""
    side = int(max(budget, 0) ** 0.5)
    mb = budget * GPU_BYTES_PER_TEXEL / 2 ** 20
    return f"= {side} x {side} atlas, ~{mb:,.0f} MB of GPU memory"


BYTES_PER_TEXEL = 100.0              # atlas layers (11 float channels) and the cards' own copies
                                     # (not fitted: one mesh's cards are too few to tell)

LARGE_BYTES = 1e9                    # the bake operator asks before a bake above either
LARGE_SECONDS = 20.0


@dataclass(frozen=True)
class MeshSize:
    triangles: int
    extent: tuple                    # local bounds size (x, y, z), metres
    resolution_scale: float = 1.0
    world_scale: float = 1.0         # largest axis scale of the object (voxels, card texels)
    instances: int = 1
    emits: bool = False              # a material emits: cards even under Min Card Size


@dataclass(frozen=True)
class Estimate:
    bytes: float
    seconds: float
    triangles: int
    samples: int                     # mip-0 SDF grid samples of all unique meshes
    texels: int

    @property
    def large(self) -> bool:
        return self.bytes > LARGE_BYTES or self.seconds > LARGE_SECONDS

    def text(self) -> str:
        """'~2.1 GB, ~25 s'."""
        b = self.bytes
        size = f"{b / 1e9:.1f} GB" if b >= 1e9 else f"{max(b / 1e6, 1):.0f} MB"
        s = self.seconds
        when = f"~{s / 60:.1f} min" if s >= 120 else f"~{s:.0f} s" if s >= 1 else "<1 s"
        return f"~{size}, {when}"


def estimate(meshes, settings) -> Estimate:
    """Estimate of a bake of `meshes` (MeshSize per unique mesh) with BakeSettings `settings`."""
    meshes = list(meshes)
    if not meshes:
        return Estimate(0.0, 0.0, 0, 0, 0)
    tris = np.array([max(int(m.triangles), 0) for m in meshes], np.float64)
    samples = np.zeros(len(meshes))
    texels = 0.0
    for i, m in enumerate(meshes):           # a loop over meshes, not their elements
        ext = np.maximum(np.nan_to_num(np.asarray(m.extent, np.float64), nan=0.0), 0.0)
        try:
            _, res, _ = plan_resolution(ext, settings.voxel_density * _sdf_scale(m.world_scale),
                                        m.resolution_scale, settings.max_resolution)
        except Exception:                    # the bake reports a bad request with its reason
            continue
        samples[i] = float(np.prod(np.asarray(res, np.float64) + 1))
        if not m.emits and (ext * max(m.world_scale, 0.0)).max() < settings.min_card_size:
            continue                         # no cards (bake.too_small_for_cards)
        side = ext * settings.texel_density * max(m.world_scale, 0.0)
        texels += 2.0 * (side[0] * side[1] + side[1] * side[2] + side[2] * side[0])
    texels = min(texels, float(settings.texel_budget))
    seconds = (SECONDS_PER_MESH * len(meshes) + SECONDS_PER_TRIANGLE * tris.sum()
               + SECONDS_PER_SAMPLE * samples.sum() + SECONDS_PER_TEXEL * texels)
    work = BYTES_PER_ROOT_TRIANGLE * np.sqrt(tris) + BYTES_PER_SAMPLE * samples
    nbytes = BYTES_PER_INPUT_TRIANGLE * tris.sum() + work.max() + BYTES_PER_TEXEL * texels
    return Estimate(float(nbytes), float(seconds), int(tris.sum()), int(samples.sum()), int(texels))
