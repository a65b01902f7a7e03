"""GI Method LPV (gpu_shaders/lpv.py; llvmpipe through bpy) against exact answers.

- Propagation: one SH lobe per colour channel injected into one cell of an empty 32^3 grid (no
  occlusion). One GPU iteration equals this file's numpy twin of the face-based scheme (5 faces
  of each of the 6 neighbours, the paper's solid angles 0.4006696846 / 0.4234413544 scaled to
  add up to 4 pi, cosine-lobe reprojection); after 1, 8 and 15 iterations (the light still inside
  the grid) the propagated light holds the injected flux (2 sqrt(pi) c0 summed over the cells) to
  1e-5 (float32), and the
  accumulated volume (N + 1) times it: the linear operator neither gains nor loses light.
- Occlusion: a 10 cm wall (a baked box) across the whole grid between an isotropic source and
  the far half: the geometry pass's transmittance is 0 on the faces the wall crosses and 1 far
  from it, and less than 5% of the flux that reaches the far half without occlusion reaches it.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

N = 32
H = 0.1
ORIGIN = (-1.6, -1.6, -1.6)
SOURCE = (16, 16, 16)               # (x, y, z) cell of the injected light
Y0, Y1 = 0.28209479177387814, 0.4886025119029199
LOBE0, LOBE1 = 0.886226925452758, 1.02332670794649
SCALE = 4 * np.pi / (6 * (0.4006696846 + 4 * 0.4234413544))    # 1 - 1.9e-5
FRONT, SIDE = 0.4006696846 * SCALE, 0.4234413544 * SCALE


def basis(w):
    """SH basis in sh_lib.glsl's order (Y00, y, z, x) at unit directions w [..., 3]."""
    w = np.asarray(w, np.float64)
    return np.stack([np.full(w.shape[:-1], Y0), Y1 * w[..., 1], Y1 * w[..., 2], Y1 * w[..., 0]],
                    -1)


def lobe(n):
    n = np.asarray(n, np.float64)
    return np.array([LOBE0, LOBE1 * n[1], LOBE1 * n[2], LOBE1 * n[0]])


def propagate_once(src):
    """numpy twin of one lpv_propagate iteration without occlusion: src [3, nz, ny, nx, 4]."""
    out = np.zeros_like(src)
    array_axis = {0: 3, 1: 2, 2: 1}          # x, y, z -> axis of [c, z, y, x, sh]
    for a in range(3):
        for sign in (1, -1):
            dv = np.zeros(3)
            dv[a] = sign
            shifted = np.roll(src, sign, axis=array_axis[a])      # value of s = d - dir at d
            edge = [slice(None)] * 5
            edge[array_axis[a]] = 0 if sign > 0 else -1           # no neighbour beyond the grid
            shifted[tuple(edge)] = 0.0
            faces = [(dv, dv, FRONT)]
            for b in ((a + 1) % 3, (a + 2) % 3):
                for s2 in (1, -1):
                    nf = np.zeros(3)
                    nf[b] = s2
                    faces.append(((dv + 0.5 * nf) / np.sqrt(1.25), nf, SIDE))
            for w, nf, omega in faces:
                flux = shifted @ basis(w)                              # I_s(w)
                out += (omega / np.pi) * flux[..., None] * lobe(nf)
    return out


def flux(sh):
    return 2.0 * np.sqrt(np.pi) * sh[..., 0].reshape(3, -1).sum(-1)


ENGINE = """
import traceback
import gpu
from lumen_gi.gpu_shaders import lpv
from lumen_gi.gpu_shaders.resources import SceneResources, float_buffer

ERRORS, OUT = [], {}

class LPVTestEngine(bpy.types.RenderEngine):
    bl_idname = "LUMEN_LPV_TEST"
    bl_label = "LPV test"
    bl_use_gpu_context = True
    def render(self, depsgraph):
        try:
            JOB()
        except Exception:
            ERRORS.append(traceback.format_exc())
        r = self.begin_result(0, 0, 4, 4)
        self.end_result(r)

bpy.utils.register_class(LPVTestEngine)

def run_job(job):
    global JOB
    JOB = job
    scene = bpy.context.scene
    if scene.camera is None:
        cam = bpy.data.objects.new("TestCam", bpy.data.cameras.new("TestCam"))
        scene.collection.objects.link(cam)
        scene.camera = cam
    scene.render.engine = "LUMEN_LPV_TEST"
    scene.render.resolution_x = scene.render.resolution_y = 4
    scene.render.resolution_percentage = 100
    bpy.ops.render.render()
    assert not ERRORS, ERRORS[0]

def upload(sh):
    # sh [3, nz, ny, nx, 4] -> the grid's three textures
    nz, ny, nx = sh.shape[1:4]
    return {c: gpu.types.GPUTexture((nx, ny * nz), format='RGBA32F',
                                    data=float_buffer(sh[k].reshape(ny * nz, nx, 4)))
            for k, c in enumerate(lpv.GRID)}
"""

PROPAGATE = ENGINE + f"""
sys.path.insert(0, {str(HERE.parent / 'core')!r})
from shapes import box, matrix
from lumen_gi.lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_gi.lumen_addon.materials import Material

bpy.ops.wm.read_factory_settings(use_empty=True)
wall = bake_scene([ObjectInput("Wall", *box((0.05, 3.0, 3.0)), matrix((0.0, 0.0, 0.0)),
                               material_ids=np.zeros(12, int), materials=[Material("W")])],
                  BakeSettings(voxel_density=20.0))
dims = ({N}, {N}, {N})
origin = np.array({ORIGIN!r})

def job():
    sh = np.load("source.npy")
    src = upload(sh)
    free = lpv.geometry(None, origin, {H}, dims, occlusion=False)
    for n in (1, 8, 15):
        acc, last, _ = lpv.propagate(src, free, dims, n)
        np.save(f"last{{n}}.npy", lpv.read_grid(last, dims))
        np.save(f"acc{{n}}.npy", lpv.read_grid(acc, dims))
    np.save("source_back.npy", lpv.read_grid(src, dims))
    # occlusion: an isotropic source at x = -0.35 m, the wall at |x| <= 0.05 m
    iso = np.zeros_like(sh)
    iso[:, 16, 16, 12, 0] = 1.0 / (2.0 * np.sqrt(np.pi))
    src = upload(iso)
    res = SceneResources.from_bake(wall)
    wall_t = lpv.geometry(res, origin, {H}, dims)
    np.save("geometry.npy", lpv.read_grid(dict(r=wall_t, g=wall_t, b=wall_t), dims)[0])
    for name, gv in (("free", free), ("wall", wall_t)):
        acc, _, _ = lpv.propagate(src, gv, dims, 24)
        np.save(f"occ_{{name}}.npy", lpv.read_grid(acc, dims))

run_job(job)
emit(ok=True)
"""


def test_propagation_conserves_flux_and_a_wall_blocks_it(tmp_path):
    sh = np.zeros((3, N, N, N, 4), np.float32)
    x, y, z = SOURCE
    sh[0, z, y, x] = lobe(np.array([1.0, 0.0, 0.0])) / np.pi * 2.0          # Phi 2, along +x
    sh[1, z, y, x] = lobe(np.array([0.0, 0.6, -0.8])) / np.pi * 0.5         # Phi 0.5, tilted
    sh[2, z, y, x] = np.array([1.0 / (2 * np.sqrt(np.pi)), 0.0, 0.0, 0.0])  # Phi 1, isotropic
    np.save(tmp_path / "source.npy", sh)
    want = flux(sh.astype(np.float64))
    np.testing.assert_allclose(want, [2.0, 0.5, 1.0], rtol=1e-6)
    run = run_python(PROPAGATE, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    np.testing.assert_array_equal(np.load(tmp_path / "source_back.npy"), sh)

    # one GPU iteration is the face-based scheme exactly (float32 against float64)
    twin = propagate_once(sh.astype(np.float64))
    got = np.load(tmp_path / "last1.npy")
    print(f"one iteration: max |GPU - twin| {np.abs(got - twin).max():.2e} "
          f"(largest coefficient {np.abs(twin).max():.3f})")
    np.testing.assert_allclose(got, twin, atol=1e-6 * np.abs(twin).max())
    assert np.count_nonzero(np.abs(got).sum((0, -1))) == 6        # the six neighbours, nothing else

    # flux conservation: every iteration holds the injected flux, the sum (N + 1) times it
    for n in (1, 8, 15):
        last, acc = np.load(tmp_path / f"last{n}.npy"), np.load(tmp_path / f"acc{n}.npy")
        ratio = flux(last) / want
        ratio_acc = flux(acc) / (want * (n + 1))
        print(f"{n:2d} iterations: flux / injected {ratio}, accumulated / ((N + 1) injected) "
              f"{ratio_acc}")
        np.testing.assert_allclose(ratio, 1.0, atol=1e-5)
        np.testing.assert_allclose(ratio_acc, 1.0, atol=1e-5)
        lit = np.argwhere(np.abs(last).sum((0, -1)) > 0)              # (z, y, x) of lit cells
        reach = np.abs(lit - np.array(SOURCE[::-1])).sum(1).max()
        assert reach == n                                            # one cell per iteration

    # occlusion: the wall's faces are closed, the far ones open; the far half stays dark
    gv = np.load(tmp_path / "geometry.npy")[..., :3]                  # [z, y, x, (Tx, Ty, Tz)]
    assert np.all(gv[:, :, 15, 0] == 0.0) and np.all(gv[:, :, 16, 0] == 0.0)   # x crossings
    assert np.all(gv[:, :, :12, :] == 1.0) and np.all(gv[:, :, 20:, :] == 1.0)
    free, wall = np.load(tmp_path / "occ_free.npy"), np.load(tmp_path / "occ_wall.npy")
    far = (slice(None), slice(None), slice(None), slice(17, None))
    through = flux(wall[far])[2] / flux(free[far])[2]
    print(f"occlusion: far half flux with the wall / without {through:.4f} "
          f"({flux(free[far])[2]:.3f} of {flux(free)[2]:.3f} without)")
    assert flux(free[far])[2] > 0.01 * flux(free)[2]
    assert through < 0.05
