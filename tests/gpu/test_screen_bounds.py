"""Lumen's neighbours' bounds (gpu_shaders/screen_trace.py: neighbour_bounds,
glsl/screen_bounds.comp.glsl; llvmpipe through bpy) on a synthetic G-buffer, 37 x 23 pixels of
random points and normals (rows 0-5 one plane), against a numpy twin built another way (each
pixel corner's view ray crossed with each neighbour's plane in world space, where the shader
uses clip-space planes) and against brute force: every point of a pixel's column in front of its
bound is in front of each neighbour's plane that sets one, and the bound is not loose."""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import gpu
from lumen_gi.gpu_shaders import compute, screen_trace
from lumen_gi.gpu_shaders.resources import float_buffer

W, H = 37, 23
rng = np.random.default_rng(7)
pos = np.zeros((H, W, 4), np.float32)
pos[..., :3] = rng.uniform([-3, -3, 1.0], [3, 3, 40.0], (H, W, 3))
pos[..., 3] = (rng.random((H, W)) > 0.15).astype(np.float32)
nrm = np.zeros((H, W, 4), np.float32)
nrm[..., :3] = rng.normal(size=(H, W, 3))
# rows 0-5: one plane (z = 10 + 0.3 x - 0.2 y), its normal given either way round: coplanar
# neighbours set no bound
pos[:6, :, 2] = 10.0 + 0.3 * pos[:6, :, 0] - 0.2 * pos[:6, :, 1]
nrm[:6, :, :3] = np.array([0.3, -0.2, -1.0]) * np.where(rng.random((6, W, 1)) > 0.5, 1.0, -1.0)
f, n, fa = 1.0 / np.tan(0.6), 0.1, 100.0
proj = np.array([[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)],
                 [0, 0, -1, 0]])
vp = proj @ np.diag([1.0, 1.0, -1.0, 1.0])          # camera at the origin looking down +z
OUT = {}

def job():
    tex = lambda a: gpu.types.GPUTexture((W, H), format='RGBA32F', data=float_buffer(a))
    gbuf = {"textures": {"position": tex(pos), "normal": tex(nrm)}}
    OUT["bounds"] = compute.read(screen_trace.neighbour_bounds(gbuf, vp, W, H))

run_in_gpu_context(job)
np.savez("bounds.npz", pos=pos, nrm=nrm, vp=vp, **OUT)
emit(ok=True)
"""


SIDES = ((0, 1), (0, -1), (1, 0), (-1, 0))      # (dy, dx) of the 4 neighbours


def _unproject(vp, x, y, z, w, h):
    """World points [..., 3] at window positions (pixels x, y; depth z) of a w x h image."""
    ndc = np.stack(np.broadcast_arrays(x / w * 2 - 1, y / h * 2 - 1, z * 2 - 1, 1.0), -1)
    q = ndc @ np.linalg.inv(vp).T
    return q[..., :3] / q[..., 3:]


def _neighbour_planes(pos, nrm, cam):
    """Per side: (whether neighbour q of each pixel sets a bound (screen_bounds.comp.glsl: both show
    a surface, q off p's plane), q's point, q's normal turned to the camera)."""
    H, W = pos.shape[:2]
    shown = pos[..., 3] >= 0.5
    n = nrm[..., :3] / np.linalg.norm(nrm[..., :3], axis=-1, keepdims=True)
    p = pos[..., :3]
    out = []
    for dy, dx in SIDES:
        qy, qx = np.arange(H)[:, None] + dy, np.arange(W)[None, :] + dx
        inside = (qy >= 0) & (qy < H) & (qx >= 0) & (qx < W)
        qy, qx = np.clip(qy, 0, H - 1), np.clip(qx, 0, W - 1)
        pq, nq = p[qy, qx], n[qy, qx]
        off = (inside & shown & shown[qy, qx]
               & ((np.abs((n * nq).sum(-1)) < 0.9998) | (np.abs(((pq - p) * n).sum(-1)) > 1e-3)))
        nq = np.where(((cam - pq) * nq).sum(-1, keepdims=True) < 0, -nq, nq)
        out.append((off, pq, nq))
    return out


def neighbour_bounds(pos, nrm, vp, cam):
    """numpy twin of screen_bounds.comp.glsl's neighbours' bound: per pixel the least window
    depth at which a corner's view ray (near to far plane) crosses an off-plane neighbour's plane
    (0 if its near end is behind it), 2.0 for none."""
    H, W = pos.shape[:2]
    ys, xs = np.mgrid[0:H + 1, 0:W + 1].astype(np.float64)
    A, B = _unproject(vp, xs, ys, 0.0, W, H), _unproject(vp, xs, ys, 1.0, W, H)
    bound = np.full((H, W), 2.0)
    for off, pq, nq in _neighbour_planes(pos, nrm, cam):
        for cy, cx in ((0, 0), (0, 1), (1, 0), (1, 1)):
            a, b = A[cy:cy + H, cx:cx + W], B[cy:cy + H, cx:cx + W]
            fa, fb = ((a - pq) * nq).sum(-1), ((b - pq) * nq).sum(-1)
            x = a + (b - a) * (fa / np.where(fb < 0, fa - fb, 1.0))[..., None]
            hx = x @ vp[:3, :3].T + vp[:3, 3]
            wx = x @ vp[3, :3] + vp[3, 3]
            z = np.clip(hx[..., 2] / wx * 0.5 + 0.5, 0, 1)
            cand = np.where(fa < 0, 0.0, np.where(fb < 0, z, 2.0))
            bound = np.where(off, np.minimum(bound, cand), bound)
    return bound


def test_neighbour_bounds(tmp_path):
    """The shader's bounds are numpy's twin's (1e-5 of window depth); 2.0 inside the plane of
    rows 0-5 (its neighbours coplanar, normals either way round); 0 on the background; every
    point of a column in front of its bound is in front of each neighbour plane that sets one
    (64 random points a pixel); and just behind the bound (1e-3) some neighbour's plane is met
    in most columns."""
    run = run_python(SNIPPET, tmp_path, timeout=120)
    assert run.returncode == 0, run.explain()
    d = np.load(tmp_path / "bounds.npz")
    pos, nrm, vp = d["pos"].astype(np.float64), d["nrm"].astype(np.float64), d["vp"]
    H, W = pos.shape[:2]
    cam = np.zeros(3)
    gpu = d["bounds"][..., 0]
    want = neighbour_bounds(pos, nrm, vp, cam)
    shown = pos[..., 3] >= 0.5
    assert np.all(gpu[~shown] == 0.0)
    want[~shown] = 0.0
    plane = np.zeros_like(shown)
    plane[1:5, 1:-1] = True
    assert np.all(gpu[plane & shown] == 2.0) and np.all(want[plane & shown] == 2.0)
    finite = want <= 1.0
    print(f"bounds set {finite.mean():.2f} of the pixels, 0: {(want == 0).mean():.2f}, "
          f"|gpu - numpy| max {np.abs(gpu - want)[finite].max():.2e}")
    assert 0.3 < finite.mean() and np.array_equal(gpu <= 1.0, finite)
    assert np.abs(gpu - want)[finite].max() < 1e-5
    # brute force: random points of each pixel's column in front of its bound
    rng = np.random.default_rng(3)
    k = 64
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    sx = xs[..., None] + rng.random((H, W, k))
    sy = ys[..., None] + rng.random((H, W, k))
    sz = rng.random((H, W, k)) * np.minimum(want, 1.0)[..., None]
    X = _unproject(vp, sx, sy, sz, W, H)
    for off, pq, nq in _neighbour_planes(pos, nrm, cam):
        dist = ((X - pq[:, :, None]) * nq[:, :, None]).sum(-1)
        some = off & (want > 0)                  # 0: no point of the column is vouched for
        assert dist[some].min() >= -1e-9 * (1 + np.abs(X[some]).max())
    # and not loose: a neighbour's plane is met just behind the bound (1e-3 of window depth)
    behind = _unproject(vp, sx, sy, np.minimum(want[..., None] + 1e-3, 1.0), W, H)
    met = np.zeros((H, W), bool)
    for off, pq, nq in _neighbour_planes(pos, nrm, cam):
        met |= off & (((behind - pq[:, :, None]) * nq[:, :, None]).sum(-1) < 0).any(-1)
    assert met[(want > 0) & finite].mean() > 0.5
