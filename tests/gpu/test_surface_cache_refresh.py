"""The viewport's answer to a changed scene (objects, lights, the sky): SurfaceCache.refresh_lighting
restarts every tile's update count (first in line again, blends from the start) and clears the
relaxation deltas, but keeps the lighting the tiles hold until they are relit, where
reset_lighting (F12, a new card atlas) zeroes it. llvmpipe, bpy in a subprocess."""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = f"""
import numpy as np
sys.path.insert(0, {str(HERE.parent / 'core')!r})
from shapes import box, matrix
from lumen_gi.lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_gi.gpu_shaders.surface_cache import SurfaceCache, _tex
from lumen_gi.gpu_shaders.resources import read_texture

bake = bake_scene([ObjectInput("Floor", *box((2.0, 2.0, 0.1)), matrix((0.0, 0.0, -0.1))),
                   ObjectInput("Box", *box((0.3, 0.3, 0.3)), matrix((0.2, 0.1, 0.3)))],
                  BakeSettings(voxel_density=10.0))
OUT = {{}}

def job():
    cache = SurfaceCache(bake.atlas, [inst.cards for inst in bake.instances])
    lw, lh = cache.packed.lighting_size
    lit = np.full((lh, lw, 4), 0.25, np.float32)
    for name in ("indirect", "final", "delta"):
        setattr(cache, name, _tex((lw, lh), 'RGBA32F', lit))
    cache.pages.commit(np.arange(len(cache.pages)), 3)
    cache.refresh_lighting()
    OUT["refresh"] = dict(final=float(read_texture(cache.final).mean()),
                          indirect=float(read_texture(cache.indirect).mean()),
                          delta=float(np.abs(read_texture(cache.delta)).max()),
                          counts=int(cache.pages.count.max()), tiles=len(cache.pages))
    cache.reset_lighting()
    OUT["reset"] = dict(final=float(np.abs(read_texture(cache.final)).max()),
                        indirect=float(np.abs(read_texture(cache.indirect)).max()))

run_in_gpu_context(job)
emit(**OUT)
"""


def test_refresh_keeps_the_light_and_restarts_the_counts(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    r = run.result
    print(r)
    assert r["refresh"]["tiles"] > 0
    assert r["refresh"]["final"] == r["refresh"]["indirect"] == 0.25      # kept
    assert r["refresh"]["delta"] == 0.0 and r["refresh"]["counts"] == 0    # restarted
    assert r["reset"]["final"] == r["reset"]["indirect"] == 0.0             # zeroed
