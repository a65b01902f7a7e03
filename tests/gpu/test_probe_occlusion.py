"""Screen probes' occlusion maps (glsl/screen_probe_occlusion.comp.glsl), on the GPU.

A floor (a 10 m slab, its top at z = 0) and a wall 2 cm thick (thinner than the 10 cm voxel)
standing on it across y at x = 0.6. Three probes on the floor at x = 0 in a column along y
(1.5 m apart: the middle one's reach is 1.05 x 1.5 m + a voxel), normals up. The middle probe's
map: the azimuth towards +x (k = 12: u = +y, v = -x from probe_occ_basis) stops at the wall,
before its far face and at most a voxel and the thin-wall shell short of its near face (0.59 m
here); the azimuth
towards -x (k = 4) and along the wall (k = 0, 8) see the whole reach; texel 4 holds the floor's
voxel, the field at the lifted end (1.5 voxels up, nothing nearer: 0.15 m within a voxel) and
the reach. A probe outside the uniform grid and an empty slot get no map (w = 0).
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = f"""
sys.path.insert(0, {str(HERE.parent / 'core')!r})
from shapes import box, matrix
from lumen_gi.lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_gi.gpu_shaders import compute, screen_probes
from lumen_gi.gpu_shaders.resources import SceneResources, float_buffer
import gpu

inputs = [ObjectInput("Floor", *box((5.0, 5.0, 0.1)), matrix((0.0, 0.0, -0.1))),
          ObjectInput("Wall", *box((0.01, 3.0, 1.0)), matrix((0.6, 0.0, 1.0)))]
bake = bake_scene(inputs, BakeSettings(voxel_density=10.0))

def job():
    res = SceneResources.from_bake(bake)
    # a 2 x 4 atlas: column 0 the uniform grid (1 x 3), column 1 and row 3 outside it
    info = np.zeros((4, 2, 4), np.float32)
    normal = np.zeros((4, 2, 4), np.float32)
    normal[..., 2] = 1.0
    for j, y in enumerate((-1.5, 0.0, 1.5)):
        info[j, 0] = (0.0, y, 0.0, 5.0)
    info[1, 1] = (0.0, 0.5, 0.0, 5.0)          # a probe outside the grid: no map
    tex_info = gpu.types.GPUTexture((2, 4), format='RGBA32F', data=float_buffer(info))
    tex_normal = gpu.types.GPUTexture((2, 4), format='RGBA32F', data=float_buffer(normal))
    out = compute.texture((2 * screen_probes.OCC_TEXELS, 4))
    screen_probes.OCCLUSION.run((2 * screen_probes.OCC_TEXELS, 4), scene=res,
                                uniform_grid=(1, 3), probe_info=tex_info,
                                probe_normal=tex_normal, out_image=out)
    np.save("occ.npy", compute.read(out))

run_in_gpu_context(job)
emit(done=True)
"""


def test_probe_occlusion_map_stops_at_a_thin_wall(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    assert run.result["done"]
    occ = np.load(tmp_path / "occ.npy")            # [4 rows, 2 x 5 texels, 4]
    mid = occ[1, 0:5]                               # the middle probe: 16 azimuths + meta
    free = mid[:4].reshape(16)
    voxel, field, reach, flag = mid[4]
    assert flag == 1.0
    assert abs(voxel - 0.1) < 1e-4, voxel
    assert abs(reach - (1.05 * 1.5 + voxel)) < 1e-3, reach
    assert abs(field - 0.15) < 0.1, field          # 1.5 voxels above the floor
    # towards +x the wall: the ray stops before its far face (a pixel beyond it is refused),
    # at most a voxel and the shell short of its near face
    assert 0.6 - 0.01 - 0.15 <= free[12] <= 0.6 + 0.01, free[12]
    # the other way and along the wall: the whole reach
    for k in (4, 0, 8):
        assert abs(free[k] - reach) < 1e-4, (k, free[k], reach)
    # the azimuths either side of +x see the wall farther off (1 / cos 22.5 degrees)
    assert free[11] > free[12] and free[13] > free[12]
    # no map outside the uniform grid, nor for an empty slot
    assert occ[1, 5:10, :].max() == 0.0
    assert occ[3, 0:5, :].max() == 0.0
