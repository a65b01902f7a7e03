"""Lumen's screen trace ray by ray on a synthetic G-buffer (glsl/screen_trace_lib.glsl through a
test compute pass; llvmpipe through bpy), against exact answers.

The camera at the origin looks down +z (32 x 32 px); a far wall fills the view at z = 10 and a
thin strip (a card) at z = 5 covers the columns with NDC x in [-0.3, 0]; both face the camera.
- A ray from in front of the far wall that passes behind the strip (1.5 m and more behind it: no
  thickness covers that) and comes out in front of the far wall to its left: walking on behind
  the strip (stop_behind false, SSGI) it hits the far wall at t = 4 sqrt 2, a surface the screen
  cannot know is the ray's first (behind the strip may be anything: `thin` leaked 1.98% so);
  Lumen's trace (stop_behind true) ends SCREEN_BEHIND there, with t_free (where the SDFs go on)
  at most where the ray enters the pixel beside the strip (t = 0.33): the ray is behind the
  strip's plane, and that pixel's neighbours' bound (screen_trace.neighbour_bounds) is it.
- A ray that meets the far wall in the open hits it at t = 4 sqrt 2 either way.
- With free_only (Lumen's walk that only wants t_free, and ends where the screen stops vouching)
  both rays give the same results, t_free bit for bit (the first one's hit_px: the pixel where it
  stopped).
- screen_cone, the colour a hit reads: the far wall noisy (its colour A plus seeded noise), the
  strip another colour B. A hit beside the strip with a wide cone averages only far-wall taps:
  its mean over hits is A within the noise's mean (no B: edge-aware), its spread over hits at
  most 0.45 of one pixel's (3x3 taps: 1/3 for independent noise); a cone under a pixel reads
  exactly the hit pixel's colour.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SNIPPET = """
import gpu
from lumen_gi.gpu_shaders import compute, hzb, screen_trace
from lumen_gi.gpu_shaders.resources import float_buffer, glsl

W = H = 32
f, n, fa = 1.0 / np.tan(0.6), 0.1, 100.0
proj = np.array([[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)],
                 [0, 0, -1, 0]])
vp = proj @ np.diag([1.0, 1.0, -1.0, 1.0])          # camera at the origin looking down +z
ndc = (np.arange(W) + 0.5) / W * 2 - 1
NX, NY = np.meshgrid(ndc, ndc)                      # row j = pixel y
strip = (NX >= -0.3) & (NX <= 0.0)
z = np.where(strip, 5.0, 10.0)
pos = np.zeros((H, W, 4), np.float32)
pos[..., 0], pos[..., 1], pos[..., 2], pos[..., 3] = NX / f * z, NY / f * z, z, 1.0
nrm = np.zeros((H, W, 4), np.float32)
nrm[..., 2], nrm[..., 3] = -1.0, 1.0
rng = np.random.default_rng(3)
A, B = np.array([1.0, 0.5, 0.25]), np.array([0.0, 0.0, 1.0])
col = np.zeros((H, W, 4), np.float32)
col[..., :3] = np.where(strip[..., None], B, A + rng.normal(0.0, 0.2, (H, W, 3)))
col[..., 3] = 1.0

rays = []                 # (o, dir, t_max, cone_tan, stop_behind)
s2 = np.sqrt(0.5)
for stop in (0.0, 1.0):
    rays.append(((0.5, 0.0, 6.0), (-s2, 0.0, s2), 20.0, 0.0, stop))    # behind the strip
    rays.append(((0.5, 0.0, 6.0), (s2, 0.0, s2), 20.0, 0.0, stop))     # the far wall in the open
# hits on the far wall left of the strip: rays straight at it from 1 m in front, wide cones
cone = []
for j in range(4, 28):
    for i in range(2, 8):
        p = pos[j, i, :3]
        for tan in (0.5, 0.0):
            cone.append((len(rays), j, i, tan))
            rays.append((tuple(p - np.array([0.0, 0.0, 1.0])), (0.0, 0.0, 1.0), 3.0, tan, 1.0))
# the two Lumen rays again with free_only (the walk that ends where the screen stops vouching)
FREE = len(rays)
rays += [rays[2][:4] + (2.0,), rays[3][:4] + (2.0,)]
R = np.zeros((1, len(rays), 4), np.float32)
D = np.zeros((1, len(rays), 4), np.float32)
for k, (o, d, tm, tan, stop) in enumerate(rays):
    R[0, k] = (*o, tm)
    D[0, k] = (*d, tan)
    D[0, k, 3] = tan + 10.0 * stop

SRC = '''
void main()
{
  int k = int(gl_GlobalInvocationID.x);
  if (k >= textureSize(rays, 0).x || gl_GlobalInvocationID.y > 0u) {
    return;
  }
  vec4 r = texelFetch(rays, ivec2(k, 0), 0);
  vec4 d = texelFetch(dirs, ivec2(k, 0), 0);
  bool stop = d.w >= 5.0;
  bool free_only = d.w >= 15.0;
  float cone_tan = d.w - (free_only ? 20.0 : (stop ? 10.0 : 0.0));
  float t_free;
  ivec2 hit_px;
  float t = screen_trace(view_proj, cam.xyz, r.xyz, d.xyz, r.w, 50, cam.w, 0.0, stop, free_only,
                         t_free, hit_px);
  vec3 c = vec3(0.0);
  if (t >= 0.0) {
    c = screen_cone(colour, view_proj, cam.xyz, cone_tan, r.xyz + d.xyz * t, t, hit_px);
  }
  imageStore(out_image, ivec2(k, 0), vec4(t, t_free, vec2(hit_px)));
  imageStore(colour_out, ivec2(k, 0), vec4(c, 1.0));
}
'''
OUT = {}

def job():
    tex = lambda a: gpu.types.GPUTexture((a.shape[1], a.shape[0]), format='RGBA32F',
                                         data=float_buffer(a))
    ptex, ntex, ctex = tex(pos), tex(nrm), tex(col)
    rtex, dtex = tex(R), tex(D)
    gbuf = {"textures": {"position": ptex, "normal": ntex}}
    h = hzb.depth_pyramid(gbuf, vp, W, H)
    bounds = screen_trace.neighbour_bounds(gbuf, vp, W, H)
    info = compute.new_info()
    for slot, name in enumerate(("gbuf_position", "gbuf_normal", "hzb", "screen_bounds",
                                 "colour", "rays", "dirs")):
        info.sampler(slot, 'FLOAT_2D', name)
    info.image(0, 'RGBA32F', 'FLOAT_2D', "out_image", qualifiers={'WRITE'})
    info.image(1, 'RGBA32F', 'FLOAT_2D', "colour_out", qualifiers={'WRITE'})
    info.push_constant('MAT4', "view_proj")
    info.push_constant('VEC4', "cam")
    src = ("#define SCREEN_BOUNDS\\n"
           + glsl(("mip_lib.glsl", "gbuffer_lib.glsl", "screen_trace_lib.glsl")) + SRC)
    sh = compute.create(info, src)
    sh.uniform_sampler("gbuf_position", ptex)
    sh.uniform_sampler("gbuf_normal", ntex)
    sh.uniform_sampler("hzb", h)
    sh.uniform_sampler("screen_bounds", bounds)
    sh.uniform_sampler("colour", ctex)
    sh.uniform_sampler("rays", rtex)
    sh.uniform_sampler("dirs", dtex)
    import mathutils
    sh.uniform_float("view_proj", mathutils.Matrix(vp.tolist()))
    sh.uniform_float("cam", [0.0, 0.0, 0.0, 0.1])
    out = compute.texture((len(rays), 1))
    cout = compute.texture((len(rays), 1))
    sh.image("out_image", out)
    sh.image("colour_out", cout)
    compute.dispatch(sh, len(rays), 1)
    OUT["trace"] = compute.read(out)[0]
    OUT["colour"] = compute.read(cout)[0]

run_in_gpu_context(job)
np.savez("rays.npz", col=col, cone=np.array(cone), free=FREE, **OUT)
emit(ok=True)
"""


def test_screen_trace_rays(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=300)
    assert run.returncode == 0, run.explain()
    d = np.load(tmp_path / "rays.npz")
    tr, colour, col, cone = d["trace"], d["colour"], d["col"], d["cone"]
    far = 4.0 * np.sqrt(2.0)
    print("walk on:", tr[0], tr[1], "stop behind:", tr[2], tr[3])
    # walking on behind the strip finds the far wall; Lumen's trace stops behind the strip
    assert abs(tr[0, 0] - far) < 0.1
    assert tr[2, 0] == -3.0                                    # SCREEN_BEHIND
    assert 0.0 <= tr[2, 1] <= 0.34                             # t_free: not beside the strip
    for k in (1, 3):                                           # in the open: the same hit
        assert abs(tr[k, 0] - far) < 0.1
    # free_only ends the walk where it stops vouching: the same results, t_free bit for bit; its
    # hit_px is the pixel where it stopped (column 16, beside the strip), not the strip's
    free = int(d["free"])
    print("free only:", tr[free], tr[free + 1])
    np.testing.assert_array_equal(tr[free, :2], tr[2, :2])
    assert tr[free, 2] == 16.0
    np.testing.assert_array_equal(tr[free + 1], tr[3])
    wide = np.array([int(k) for k, j, i, tan in cone if tan > 0])
    narrow = np.array([(k, j, i) for k, j, i, tan in cone if tan == 0]).astype(int)
    assert (tr[wide, 0] > 0).all() and (tr[narrow[:, 0], 0] > 0).all()
    # a cone within a pixel: exactly the hit pixel's colour
    np.testing.assert_array_equal(colour[narrow[:, 0], :3], col[narrow[:, 1], narrow[:, 2], :3])
    # a wide cone beside the strip: far-wall taps only, averaged
    A = np.array([1.0, 0.5, 0.25])
    wide_c, px_c = colour[wide, :3], col[narrow[:, 1], narrow[:, 2], :3]
    print("cone mean", wide_c.mean(0), "spread cone / pixel", wide_c.std(0) / px_c.std(0))
    assert np.abs(wide_c.mean(0) - A).max() < 0.05            # no strip colour (B = blue)
    assert (wide_c[:, 2] < 0.25 + 0.5).all()
    assert (wide_c.std(0) <= 0.45 * px_c.std(0)).all()
