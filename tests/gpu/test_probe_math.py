"""The probe maths libraries (gpu_shaders/glsl/{octahedral,sh,sampling,probe_interp}_lib.glsl)
against their numpy twins (gpu_shaders/probe_math.py): fast numpy tests of the maths itself, then
one bpy subprocess (a tiny test RenderEngine with bl_use_gpu_context, Mesa llvmpipe) running a
compute shader built from the four libraries and comparing it with the twins.

Tolerances. The twins run in float64, the GPU in float32: directions and SH values are compared
within 1e-5 (a few float32 ulps of O(1) values, after a few dozen operations); the bit functions
(vdc, Hammersley, pcg_hash) must match exactly. Probe weights match within 1e-6 on the lecture's
cases and on random axis-aligned planes; on random general planes float32 cancellation in the
plane distance n.P - w (~2e-7 for O(1) positions), times the steep exp2(-10000 r^2) and the
division by max(sum, 0.01), moves weights by up to a few 1e-6 (3.7e-6 measured), so those are held
to a derived per-weight float32 bound (float32_weight_error; measured error <= 0.2 x bound).
SH quadrature uses a 128 x 128 octahedral grid (texel centres x exact texel solid angles, 16k samples): the midpoint rule's error
on degree <= 4 products is <= 2e-4 here (7e-4 at 64 x 64), so 1e-3 is a safe bound. The clamped
cosine max(0, z) has coefficients A_l Y_l0(z) (Funk-Hecke), so its band-2 irradiance at n = z is
sum_{l<=2} A_l^2 (2l + 1) / 4pi = 127 pi / 192, exactly pi / 192 = 0.01636 (1/128 relative) below
the true 2 pi / 3: that truncation plus the quadrature bound 1e-3 is the tolerance derived here.
"""
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

from gpu_shaders import probe_math as pm  # noqa: E402

TWO_PI_3 = 2.0 * np.pi / 3.0
SH_L2_CLAMPED_COSINE = 127.0 * np.pi / 192.0     # the band <= 2 truncation of 2 pi / 3


def random_dirs(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def special_dirs(seed=1):
    """Poles, axes, the z = 0 fold, the lower-hemisphere seams x = 0 / y = 0 and near-fold z."""
    rng = np.random.default_rng(seed)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    phi = rng.uniform(0, 2 * np.pi, 64)
    equator = np.stack([np.cos(phi), np.sin(phi), np.zeros(64)], 1)
    near = np.stack([np.cos(phi), np.sin(phi), rng.choice([-1e-7, 1e-7], 64)], 1)
    z = -rng.uniform(0.0, 1.0, 32)
    seam_x = np.stack([np.zeros(32), rng.choice([-1, 1], 32) * np.sqrt(1 - z * z), z], 1)
    seam_y = np.stack([rng.choice([-1, 1], 32) * np.sqrt(1 - z * z), np.zeros(32), z], 1)
    diag = np.array([[1, 1, 0], [-1, 1, 0], [1, -1, -1], [-1, -1, -1], [1, 1, 1]], float)
    d = np.concatenate([axes, equator, near, seam_x, seam_y, diag])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def oct_test_dirs(n=10000):
    s = special_dirs()
    return np.concatenate([s, random_dirs(n - len(s))])


def quadrature(res=128):
    return pm.oct_texel_dirs(res).reshape(-1, 3), pm.oct_texel_solid_angles(res).reshape(-1)


# --- octahedral ----------------------------------------------------------------------------

def test_oct_round_trip_including_poles_and_fold():
    d = oct_test_dirs()
    uv = pm.oct_encode(d)
    assert uv.min() >= 0.0 and uv.max() <= 1.0
    np.testing.assert_allclose(pm.oct_decode(uv), d, atol=1e-5, rtol=0)
    assert np.abs(pm.oct_decode(uv) - d).max() < 1e-12
    np.testing.assert_array_equal(pm.oct_encode([[0, 0, 1.0], [0, 0, -1.0]]), [[0.5, 0.5], [1, 1]])
    # non-unit input: the map only depends on the direction
    np.testing.assert_allclose(pm.oct_encode(d * 3.7), uv, atol=1e-12)


def test_oct_texels_centres_jitter_and_solid_angles():
    rng = np.random.default_rng(3)
    for res in (2, 8, 16, 64):
        grid = np.stack(np.meshgrid(np.arange(res), np.arange(res)), -1)       # [y, x, (x, y)]
        np.testing.assert_array_equal(pm.oct_texel(pm.oct_texel_dirs(res), res), grid)
        jitter = rng.uniform(0.01, 0.99, grid.shape)
        np.testing.assert_array_equal(pm.oct_texel(pm.oct_texel_dir(grid, res, jitter), res), grid)
        sa = pm.oct_texel_solid_angles(res)
        assert abs(sa.sum() / (4 * np.pi) - 1) < 1e-3
        assert abs(sa.sum() / (4 * np.pi) - 1) < 1e-12
        assert sa.min() > 0
    # exact, not just normalised: a res-8 texel is the sum of its 64 x 64 texels at res 512
    fine = pm.oct_texel_solid_angles(512).reshape(8, 64, 8, 64).sum(axis=(1, 3))
    np.testing.assert_allclose(pm.oct_texel_solid_angles(8), fine, rtol=1e-10)
    # and an independent check: the share of uniform random directions falling into each texel
    d = random_dirs(400_000, seed=5)
    t = pm.oct_texel(d, 8)
    counts = np.bincount(t[:, 1] * 8 + t[:, 0], minlength=64).reshape(8, 8)
    expect = pm.oct_texel_solid_angles(8) / (4 * np.pi) * len(d)
    assert np.all(np.abs(counts - expect) < 5 * np.sqrt(expect))


# --- spherical harmonics -------------------------------------------------------------------

def test_sh_basis_constants_and_order():
    d = random_dirs(100)
    b = pm.sh9_basis(d)
    x, y, z = d.T
    np.testing.assert_allclose(b[:, 0], 0.282095, atol=1e-6)
    np.testing.assert_allclose(b[:, 1:4], 0.488603 * np.stack([y, z, x], 1), atol=1e-6)
    np.testing.assert_allclose(b[:, 4], 1.092548 * x * y, atol=1e-6)
    np.testing.assert_allclose(b[:, 5], 1.092548 * y * z, atol=1e-6)
    np.testing.assert_allclose(b[:, 6], 0.315392 * (3 * z * z - 1), atol=1e-6)
    np.testing.assert_allclose(b[:, 7], 1.092548 * x * z, atol=1e-6)
    np.testing.assert_allclose(b[:, 8], 0.546274 * (x * x - y * y), atol=1e-6)
    np.testing.assert_array_equal(pm.sh4_basis(d), b[:, :4])
    dirs, w = quadrature()
    gram = (pm.sh9_basis(dirs) * w[:, None]).T @ pm.sh9_basis(dirs)
    np.testing.assert_allclose(gram, np.eye(9), atol=1e-3)                   # orthonormal


def test_sh_projection_recovers_degree2_radiance():
    dirs, w = quadrature()
    rng = np.random.default_rng(11)
    for _ in range(5):
        c = rng.uniform(-1, 1, (9, 3))
        np.testing.assert_allclose(pm.sh9_project(dirs, pm.sh9_eval(c, dirs), w), c, atol=1e-3)
    c1 = rng.uniform(-1, 1, 9)                                               # one channel
    np.testing.assert_allclose(pm.sh9_project(dirs, pm.sh9_eval(c1, dirs), w), c1, atol=1e-3)


def test_sh_irradiance_constant_and_clamped_cosine():
    normals = np.concatenate([random_dirs(500), special_dirs()])
    # constant radiance 1: exact coefficients, and the quadrature projection of ones
    exact = np.zeros((9, 3))
    exact[0] = 4 * np.pi * pm.SH_Y0
    np.testing.assert_allclose(pm.sh9_irradiance(exact, normals), np.pi, atol=1e-12)
    np.testing.assert_allclose(pm.sh4_irradiance(exact[:4], normals), np.pi, atol=1e-12)
    dirs, w = quadrature()
    ones = pm.sh9_project(dirs, np.ones((len(w), 3)), w)
    np.testing.assert_allclose(pm.sh9_irradiance(ones, normals), np.pi, atol=1e-3)
    # clamped cosine around +z: band-2 truncation of 2 pi / 3 (module docstring)
    c = pm.sh9_project(dirs, np.maximum(0.0, dirs[:, 2]), w)
    e = float(pm.sh9_irradiance(c, np.array([0.0, 0.0, 1.0])))
    assert abs(e - SH_L2_CLAMPED_COSINE) < 1e-3
    assert abs(e - TWO_PI_3) < np.pi / 192 + 1e-3
    assert abs(TWO_PI_3 - SH_L2_CLAMPED_COSINE - np.pi / 192) < 1e-12
    # the analytic coefficients A_l Y_lm(z) give that value exactly
    analytic = pm.SH_A[pm.SH_BAND] * pm.sh9_basis(np.array([0.0, 0.0, 1.0]))
    assert abs(float(pm.sh9_irradiance(analytic, np.array([0.0, 0.0, 1.0]))) - SH_L2_CLAMPED_COSINE) < 1e-12
    np.testing.assert_allclose(c, analytic, atol=1e-3)
    # sh4 = sh9 with band 2 removed
    c9 = np.random.default_rng(2).uniform(-1, 1, (9, 3))
    c9[4:] = 0
    np.testing.assert_allclose(pm.sh4_irradiance(c9[:4], normals), pm.sh9_irradiance(c9, normals),
                               atol=1e-12)


# --- sampling ------------------------------------------------------------------------------

def test_hammersley_vdc_pcg():
    np.testing.assert_array_equal(pm.radical_inverse_vdc([0, 1, 2, 3, 4]), [0, 0.5, 0.25, 0.75, 0.125])
    assert pm.radical_inverse_vdc(0xFFFFFFFF) < 1.0
    assert pm.radical_inverse_vdc(0xFFFFFFFF).dtype == np.float32
    for n in (16, 64):
        h = pm.hammersley(n)
        assert h.dtype == np.float32 and h.shape == (n, 2)
        np.testing.assert_array_equal(h[:, 0], np.arange(n) / n)
        np.testing.assert_array_equal(np.sort(h[:, 1]), np.arange(n) / n)  # a stratified permutation
        np.testing.assert_array_equal(pm.hammersley(n, np.arange(n)), h)
    v = pm.pcg_hash(np.arange(1 << 16))
    assert v.dtype == np.uint32
    assert len(np.unique(v)) == 1 << 16                                      # a permutation of uint32
    bits = (v[:, None] >> np.arange(32, dtype=np.uint32)) & 1
    assert np.all(np.abs(bits.mean(0) - 0.5) < 0.01)
    assert int(pm.pcg_hash(0)) == 129708002


def test_tangent_frame_cosine_and_uniform_sphere():
    n = np.concatenate([random_dirs(2000, 7), special_dirs(),
                        [[0, 0, -1 + 1e-9], [1e-9, 0, -1.0], [1.0, 0, -0.0], [0, -1.0, -0.0]]])
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    f = pm.tangent_frame(n)
    np.testing.assert_allclose(np.einsum("kji,kjl->kil", f, f), np.broadcast_to(np.eye(3), f.shape),
                               atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-6)
    np.testing.assert_array_equal(f[..., 2], n)
    u = pm.hammersley(4096).astype(np.float64)
    for normal in ([0, 0, 1.0], [0, 0, -1.0], random_dirs(1, 9)[0]):
        d = pm.cosine_hemisphere(u, np.array(normal))
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        cos = d @ np.array(normal)
        assert cos.min() >= -1e-12
        assert abs(cos.mean() - 2.0 / 3.0) < 2e-3                            # E[cos] for pdf cos/pi
    s = pm.uniform_sphere(u)
    np.testing.assert_allclose(np.linalg.norm(s, axis=1), 1.0, atol=1e-12)
    assert np.abs(s.mean(0)).max() < 2e-3
    np.testing.assert_allclose((s * s).mean(0), 1.0 / 3.0, atol=2e-3)


# --- probe interpolation -------------------------------------------------------------------

def bilinear_weights(b):
    bx, by = b[..., 0], b[..., 1]
    return np.stack([(1 - bx) * (1 - by), bx * (1 - by), (1 - bx) * by, bx * by], -1)


def plane_case(rel_off, valid=(1, 1, 1, 1), bilinear=(0.3, 0.6), depth=4.0):
    """Pixel at (0.2, -0.1, 0.5) on the plane with normal (0, 0.6, 0.8); corners one probe
    spacing away in the plane, each lifted off it by rel_off[i] * depth."""
    n = np.array([0.0, 0.6, 0.8])
    p = np.array([0.2, -0.1, 0.5])
    t, b = np.array([1.0, 0, 0]), np.array([0, 0.8, -0.6])
    corners = [p + (i - 0.3) * 0.25 * t + (j - 0.6) * 0.25 * b + n * r * depth
               for (i, j), r in zip(((0, 0), (1, 0), (0, 1), (1, 1)), rel_off)]
    return (np.array(bilinear), *corners, np.array(valid, float), np.append(n, n @ p), depth)


def probe_cases():
    return [plane_case((0, 0, 0, 0)), plane_case((0, 0.05, 0, 0)), plane_case((0.05,) * 4),
            plane_case((0.05, -0.05, 0.08, 0.2)), plane_case((0, 0, 0, 0), valid=(1, 0, 1, 1)),
            plane_case((0, 0, 0, 0), valid=(0, 0, 0, 0)), plane_case((0.01, 0, 0, 0))]


def random_probe_inputs(n, seed=13, axis_aligned=False):
    """Random pixels / planes / probes: each corner on the plane, slightly or far off it, ~20 %
    invalid. axis_aligned: plane normals +-x, +-y or +-z, so that float32 computes every plane
    distance with one rounding (the products are by 0 and +-1): see test_gpu_matches_numpy_twins."""
    rng = np.random.default_rng(seed)
    if axis_aligned:
        normal = np.eye(3)[rng.integers(0, 3, n)] * rng.choice([-1.0, 1.0], (n, 1))
    else:
        normal = random_dirs(n, seed + 1)
    pixel = rng.uniform(-1, 1, (n, 3))
    depth = rng.uniform(1.0, 3.0, n)
    tang = pm.tangent_frame(normal)
    corners = []
    for _ in range(4):
        lateral = rng.uniform(-0.4, 0.4, (n, 2))
        kind = rng.integers(0, 4, n)
        rel = np.choose(kind, [np.zeros(n), rng.uniform(-0.005, 0.005, n),
                               rng.uniform(-0.03, 0.03, n), rng.uniform(-0.2, 0.2, n)])
        corners.append(pixel + tang[..., 0] * lateral[:, :1] + tang[..., 1] * lateral[:, 1:]
                       + normal * (rel * depth)[:, None])
    valid = (rng.uniform(size=(n, 4)) > 0.2).astype(float)
    plane = np.concatenate([normal, (normal * pixel).sum(1, keepdims=True)], 1)
    return rng.uniform(0, 1, (n, 2)), *corners, valid, plane, depth


def test_probe_weights_lecture_cases():
    (w, v) = pm.probe_corner_weights(*plane_case((0, 0, 0, 0)))
    bl = bilinear_weights(np.array([0.3, 0.6]))
    np.testing.assert_allclose(w, bl, atol=1e-12)
    assert v == 1
    w, v = pm.probe_corner_weights(*plane_case((0, 0.05, 0, 0)))
    dw = 2.0 ** -25
    np.testing.assert_allclose(w[1], bl[1] * dw / (1 - bl[1] + bl[1] * dw), rtol=1e-6)
    assert w[1] < 1e-7 and v == 1
    np.testing.assert_allclose(w[[0, 2, 3]], bl[[0, 2, 3]] / (1 - bl[1]), rtol=1e-6)
    w, v = pm.probe_corner_weights(*plane_case((0.05,) * 4))
    assert v == 0 and w.sum() < 1e-5                                         # all off: raw sum 2^-25
    w, v = pm.probe_corner_weights(*plane_case((0, 0, 0, 0), valid=(1, 0, 1, 1)))
    assert w[1] == 0 and v == 1
    np.testing.assert_allclose(w.sum(), 1.0, atol=1e-12)
    w, v = pm.probe_corner_weights(*plane_case((0, 0, 0, 0), valid=(0, 0, 0, 0)))
    assert v == 0 and np.all(w == 0)
    w, v = pm.probe_corner_weights(*plane_case((0.01, 0, 0, 0)))             # 1 % off: depth weight 1/2
    np.testing.assert_allclose(w, bl * [0.5, 1, 1, 1] / (bl @ [0.5, 1, 1, 1]), rtol=1e-9)
    # the lecture's validity rule: 0 exactly when the raw sum is below eps (1 - eps)
    sums = np.array([0.0098, 0.00989, 0.00991, 0.0099999, 0.01, 0.5])
    bil = np.tile([0.0, 0.0], (6, 1))                                        # all weight on corner 00
    rel = np.sqrt(-np.log2(sums) / 10000.0)
    z = np.zeros((6, 3))
    p00 = z + rel[:, None] * [0, 0, 1.0]
    _, v = pm.probe_corner_weights(bil, p00, z, z, z, np.ones((6, 4)), np.tile([0, 0, 1.0, 0], (6, 1)),
                                   np.ones(6))
    np.testing.assert_array_equal(v, [0, 0, 1, 1, 1, 1])
    # vectorised == one by one
    inp = random_probe_inputs(50)
    w_all, v_all = pm.probe_corner_weights(*inp)
    for k in range(0, 50, 7):
        w1, v1 = pm.probe_corner_weights(*(a[k] for a in inp))
        np.testing.assert_array_equal(w1, w_all[k])
        assert v1 == v_all[k]


def test_probe_math_imports_without_blender():
    import ast
    tree = ast.parse(Path(pm.__file__).read_text())
    top = {a.name.split(".")[0] for node in tree.body if isinstance(node, (ast.Import, ast.ImportFrom))
           for a in node.names} | {node.module.split(".")[0] for node in tree.body
                                   if isinstance(node, ast.ImportFrom) and node.module}
    assert not top & {"gpu", "bpy", "mathutils", "gpu_extras"}


# --- GPU -----------------------------------------------------------------------------------

GRID = 100                      # a block is GRID x GRID samples; textures stack blocks vertically
IN_BLOCKS, OUT_BLOCKS = 12, 8

GPU_SNIPPET = f"""
import time, traceback
from lumen_gi.gpu_shaders.resources import glsl, float_buffer
from lumen_gi.gpu_shaders.gbuffer import read_texture
import gpu

W, IN_BLOCKS, OUT_BLOCKS = {GRID}, {IN_BLOCKS}, {OUT_BLOCKS}
TEST_MAIN = '''
#define W {GRID}
vec4 in_block(int s, int k) {{ return texelFetch(inp, ivec2(s % W, s / W + k * W), 0); }}
void out_block(int s, int k, vec4 v) {{ imageStore(outp, ivec2(s % W, s / W + k * W), v); }}
void main()
{{
  ivec2 g = ivec2(gl_GlobalInvocationID.xy);
  int s = g.x + W * g.y;
  if (g.x >= W || g.y >= W || s >= count) {{
    return;
  }}
  if (mode == 0) {{                                   /* octahedral: encode / decode / texel */
    vec3 d = in_block(s, 0).xyz;
    vec2 uv = oct_encode(d);
    out_block(s, 0, vec4(uv, vec2(oct_texel(d, res))));
    out_block(s, 1, vec4(oct_decode(uv), 0.0));
    out_block(s, 2, vec4(oct_decode(in_block(s, 1).xy), 0.0));
  }}
  else if (mode == 1) {{                              /* texel grid of a res x res probe */
    ivec2 t = ivec2(s % res, s / res);
    vec3 dc = oct_texel_dir(t, res, vec2(0.5));
    out_block(s, 0, vec4(dc, oct_texel_solid_angle(t, res)));
    out_block(s, 1, vec4(vec2(oct_texel(dc, res)), 0.0, 0.0));
    out_block(s, 2, vec4(oct_texel_dir(t, res, in_block(s, 0).xy), 0.0));
  }}
  else if (mode == 2) {{                              /* SH */
    vec3 c[9];
    for (int i = 0; i < 9; i++) {{
      c[i] = in_block(s, i).xyz;
    }}
    vec3 c4[4] = vec3[4](c[0], c[1], c[2], c[3]);
    vec3 n = in_block(s, 9).xyz;
    vec3 d = in_block(s, 10).xyz;
    float b[9];
    float b4[4];
    sh9_basis(d, b);
    sh4_basis(n, b4);
    out_block(s, 0, vec4(sh9_irradiance(c, n), 0.0));
    out_block(s, 1, vec4(sh9_eval(c, d), 0.0));
    out_block(s, 2, vec4(sh4_irradiance(c4, n), 0.0));
    out_block(s, 3, vec4(b[0], b[1], b[2], b[3]));
    out_block(s, 4, vec4(b[4], b[5], b[6], b[7]));
    out_block(s, 5, vec4(b[8], b4[1], b4[2], b4[3]));
  }}
  else if (mode == 3) {{                              /* sampling */
    uint i = uint(s);
    uint h = pcg_hash(i);
    out_block(s, 0, vec4(hammersley(i, 16u), hammersley(i, 64u)));
    out_block(s, 1, vec4(float(h >> 16u), float(h & 0xFFFFu), radical_inverse_vdc(i),
                         radical_inverse_vdc(h)));
    vec2 u = in_block(s, 0).xy;
    vec3 n = in_block(s, 1).xyz;
    mat3 f = tangent_frame(n);
    out_block(s, 2, vec4(cosine_hemisphere(u, n), 0.0));
    out_block(s, 3, vec4(uniform_sphere(u), 0.0));
    out_block(s, 4, vec4(f[0], 0.0));
    out_block(s, 5, vec4(f[1], 0.0));
    out_block(s, 6, vec4(f[2], 0.0));
  }}
  else {{                                             /* probe interpolation weights */
    vec4 a = in_block(s, 0);
    float valid;
    vec4 w = probe_corner_weights(a.xy, in_block(s, 1).xyz, in_block(s, 2).xyz,
                                  in_block(s, 3).xyz, in_block(s, 4).xyz, in_block(s, 5),
                                  in_block(s, 6), a.z, valid);
    out_block(s, 0, w);
    out_block(s, 1, vec4(valid, 0.0, 0.0, 0.0));
  }}
}}
'''
inputs = np.load("inputs.npz")
ERRORS, OUT, TIMES = [], {{}}, {{}}

def job():
    t = time.perf_counter()
    info = gpu.types.GPUShaderCreateInfo()
    info.local_group_size(8, 8, 1)
    info.sampler(0, 'FLOAT_2D', 'inp')
    info.image(0, 'RGBA32F', 'FLOAT_2D', 'outp', qualifiers={{'WRITE'}})
    info.push_constant('INT', 'mode')
    info.push_constant('INT', 'res')
    info.push_constant('INT', 'count')
    libs = "".join(glsl(name) + "\\n" for name in (
        "octahedral_lib.glsl", "sh_lib.glsl", "sampling_lib.glsl", "probe_interp_lib.glsl"))
    info.compute_source(libs + libs + TEST_MAIN)           # twice: the include guards hold
    shader = gpu.shader.create_from_info(info)
    TIMES["compile"] = time.perf_counter() - t
    for key, mode, res, count, used in (("oct", 0, 64, 10000, 3), ("texels8", 1, 8, 64, 3),
                                        ("texels64", 1, 64, 4096, 3), ("sh", 2, 0, 10000, 6),
                                        ("sampling", 3, 0, 10000, 7), ("probe", 4, 0, 10000, 2)):
        t = time.perf_counter()
        blocks = np.zeros((IN_BLOCKS, W * W, 4), np.float32)
        data = inputs[key]
        blocks[:data.shape[0], :data.shape[1], :data.shape[2]] = data
        inp = gpu.types.GPUTexture((W, W * IN_BLOCKS), format='RGBA32F', data=float_buffer(blocks))
        outp = gpu.types.GPUTexture((W, W * OUT_BLOCKS), format='RGBA32F')
        shader.bind()
        shader.uniform_int('mode', mode)
        shader.uniform_int('res', res)
        shader.uniform_int('count', count)
        shader.uniform_sampler('inp', inp)
        shader.image('outp', outp)
        gpu.compute.dispatch(shader, -(-W // 8), -(-W // 8), 1)
        out = read_texture(outp, W, W * OUT_BLOCKS).reshape(OUT_BLOCKS, W * W, 4)[:used, :count]
        OUT[key] = out.tolist()
        TIMES[key] = time.perf_counter() - t

class ProbeMathEngine(bpy.types.RenderEngine):
    bl_idname = "LUMEN_PROBE_MATH_TEST"
    bl_label = "Probe math test"
    bl_use_gpu_context = True
    def render(self, depsgraph):
        try:
            job()
        except Exception:
            ERRORS.append(traceback.format_exc())
        r = self.begin_result(0, 0, 4, 4)
        self.end_result(r)

bpy.utils.register_class(ProbeMathEngine)
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.camera = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))    # render() needs one
scene.collection.objects.link(scene.camera)
scene.render.engine = "LUMEN_PROBE_MATH_TEST"
scene.render.resolution_x = scene.render.resolution_y = 4
scene.render.resolution_percentage = 100
bpy.ops.render.render()
assert not ERRORS, ERRORS[0]
emit(times=TIMES, **OUT)
"""


def float32_weight_error(bilinear, p00, p10, p01, p11, corner_valid, scene_plane, scene_depth):
    """Bound on |float32 - exact| of probe_corner_weights' normalised weights [n, 4].

    The plane distance n.P - w of O(1) positions loses absolute precision to cancellation:
    |error| <= ~4 ulp of sum |P_i n_i| + |w| (~2e-7 here). The depth weight D = exp2(-10000 r^2)
    has dD/dr = -20000 ln2 r D (up to 71 per unit of r), and the normalisation divides by
    S = max(sum B D, 0.01), so W = B D / S moves by up to
        (B_j dD_j + W_j sum_i B_i dD_i) / S   (+ exp2 / rounding: 1e-6 relative)
    i.e. a few 1e-6 at 1-3 % of the depth off the plane with a small S. Axis-aligned planes make
    n.P exact up to one rounding of the tiny difference, where 1e-6 holds."""
    plane = np.asarray(scene_plane, np.float64)
    depth = np.asarray(scene_depth, np.float64)[:, None]
    p = np.stack([np.asarray(q, np.float64) for q in (p00, p10, p01, p11)], 1)
    dist = np.einsum("nki,ni->nk", p, plane[:, :3]) - plane[:, 3:4]
    mag = np.abs(p * plane[:, None, :3]).sum(-1) + np.abs(plane[:, 3:4])
    rel = np.abs(dist) / depth
    d_rel = (4.0 * 2.0 ** -24 * mag + 2.0 ** -24 * np.abs(dist)) / depth
    d_depth = np.exp2(-10000.0 * rel * rel) * (corner_valid > 0.5)
    dd = d_depth * (20000.0 * np.log(2.0) * (rel + d_rel) * d_rel + 1e-6)
    b = bilinear_weights(np.asarray(bilinear, np.float64))
    s = np.maximum((b * d_depth).sum(-1, keepdims=True), pm.PROBE_WEIGHT_EPS)
    w = b * d_depth / s
    return (b * dd + w * (b * dd).sum(-1, keepdims=True)) / s + 1e-6 * w


def _blocks(*arrays):
    """Stack per-sample arrays [n, <=4] as input blocks [k, n, 4] (float32, zero padded)."""
    n = len(arrays[0])
    out = np.zeros((len(arrays), n, 4), np.float32)
    for k, a in enumerate(arrays):
        a = np.asarray(a, np.float32).reshape(n, -1)
        out[k, :, :a.shape[1]] = a
    return out


def test_gpu_matches_numpy_twins(tmp_path):
    if importlib.util.find_spec("bpy") is None:
        pytest.skip(f"bpy cannot be imported by {sys.executable}: no Blender to run the GPU test")
    rng = np.random.default_rng(21)
    # inputs, as float32 (what the GPU reads); the twins are evaluated on exactly those values
    dirs = oct_test_dirs().astype(np.float32)
    uv_in = rng.uniform(0, 1, (10000, 2)).astype(np.float32)
    uv_in[:4] = [[0, 0], [1, 1], [0.5, 0.5], [1, 0]]
    jit8, jit64 = (rng.uniform(0, 1, (r * r, 2)).astype(np.float32) for r in (8, 64))
    coef = rng.uniform(-1, 1, (9, 10000, 3)).astype(np.float32)
    coef[:, :8] = 0
    coef[0, :8] = 4 * np.pi * pm.SH_Y0                                      # constant radiance 1
    sh_n = np.concatenate([special_dirs()[:8], random_dirs(9992, 4)]).astype(np.float32)
    sh_d = random_dirs(10000, 6).astype(np.float32)
    su = rng.uniform(0, 1, (10000, 2)).astype(np.float32)
    sn = np.concatenate([special_dirs(), random_dirs(10000 - len(special_dirs()), 8)]).astype(np.float32)
    cases = probe_cases()
    n_axis = 5000 - len(cases)
    axis, general = random_probe_inputs(n_axis, 14, axis_aligned=True), random_probe_inputs(5000, 13)
    probe = [np.concatenate([np.stack([np.asarray(c[k], float) for c in cases]), a, g])
             .astype(np.float32) for k, (a, g) in enumerate(zip(axis, general))]
    bil, p00, p10, p01, p11, valid, plane, depth = probe
    np.savez(tmp_path / "inputs.npz",
             oct=_blocks(dirs, uv_in), texels8=_blocks(jit8), texels64=_blocks(jit64),
             sh=_blocks(*coef, sh_n, sh_d), sampling=_blocks(su, sn),
             probe=_blocks(np.concatenate([bil, depth[:, None]], 1), p00, p10, p01, p11, valid, plane))

    start = time.perf_counter()
    run = run_python(GPU_SNIPPET, tmp_path, timeout=60)
    wall = time.perf_counter() - start
    assert run.returncode == 0, run.explain()
    res = {k: np.asarray(v, np.float64) for k, v in run.result.items() if k != "times"}
    print(f"\nGPU subprocess {wall:.2f} s; in-process seconds {run.result['times']}")

    # octahedral
    o = res["oct"]
    np.testing.assert_allclose(o[0, :, :2], pm.oct_encode(dirs), atol=1e-5, rtol=0)
    np.testing.assert_allclose(o[1, :, :3], dirs, atol=1e-5, rtol=0)                  # round trip
    np.testing.assert_allclose(o[2, :, :3], pm.oct_decode(uv_in), atol=1e-5, rtol=0)
    texel = pm.oct_texel(dirs, 64)
    agree = (o[0, :, 2:4] == texel).all(1)
    # a direction within float32 rounding of a texel edge may fall on either side
    uv64 = pm.oct_encode(dirs) * 64
    edge = np.abs(uv64 - np.round(uv64)).min(1) < 1e-3
    assert np.all(agree | edge) and agree.mean() > 0.99
    for key, r, jit in (("texels8", 8, jit8), ("texels64", 64, jit64)):
        t = res[key]
        grid = np.stack([np.arange(r * r) % r, np.arange(r * r) // r], 1)
        np.testing.assert_allclose(t[0, :, :3], pm.oct_texel_dir(grid, r), atol=1e-5, rtol=0)
        np.testing.assert_array_equal(t[1, :, :2], grid)                              # own texel
        np.testing.assert_allclose(t[0, :, 3], pm.oct_texel_solid_angle(grid, r), rtol=1e-4)
        assert abs(t[0, :, 3].sum() / (4 * np.pi) - 1) < 1e-4
        np.testing.assert_allclose(t[2, :, :3], pm.oct_texel_dir(grid, r, jit), atol=1e-5, rtol=0)

    # spherical harmonics
    s = res["sh"]
    c = np.moveaxis(coef, 0, 1).astype(np.float64)                                   # [n, 9, 3]
    np.testing.assert_allclose(s[0, :, :3], pm.sh9_irradiance(c, sh_n), atol=1e-5, rtol=0)
    np.testing.assert_allclose(s[1, :, :3], pm.sh9_eval(c, sh_d), atol=1e-5, rtol=0)
    np.testing.assert_allclose(s[2, :, :3], pm.sh4_irradiance(c[:, :4], sh_n), atol=1e-5, rtol=0)
    b9, b4 = pm.sh9_basis(sh_d), pm.sh4_basis(sh_n)
    np.testing.assert_allclose(s[3], b9[:, :4], atol=1e-6, rtol=0)
    np.testing.assert_allclose(s[4], b9[:, 4:8], atol=1e-6, rtol=0)
    np.testing.assert_allclose(s[5], np.concatenate([b9[:, 8:], b4[:, 1:]], 1), atol=1e-6, rtol=0)
    np.testing.assert_allclose(s[0, :8, :3], np.pi, atol=1e-5)                      # constant -> pi

    # sampling: the bit functions exactly
    m = res["sampling"]
    i = np.arange(10000, dtype=np.uint32)
    for n, cols in ((16, slice(0, 2)), (64, slice(2, 4))):
        np.testing.assert_array_equal(m[0, :n, cols], pm.hammersley(n))
    h = pm.pcg_hash(i)
    np.testing.assert_array_equal(m[1, :, 0], h >> 16)
    np.testing.assert_array_equal(m[1, :, 1], h & 0xFFFF)
    np.testing.assert_array_equal(m[1, :, 2], pm.radical_inverse_vdc(i))
    np.testing.assert_array_equal(m[1, :, 3], pm.radical_inverse_vdc(h))
    np.testing.assert_allclose(m[2, :, :3], pm.cosine_hemisphere(su, sn), atol=1e-5, rtol=0)
    np.testing.assert_allclose(m[3, :, :3], pm.uniform_sphere(su), atol=1e-5, rtol=0)
    frame = pm.tangent_frame(sn)
    for k in range(3):
        np.testing.assert_allclose(m[4 + k, :, :3], frame[..., k], atol=1e-5, rtol=0)

    # probe weights: the lecture cases and axis-aligned planes within 1e-6; general planes within
    # the float32 bound of float32_weight_error (up to a few 1e-6: see there)
    p = res["probe"]
    w, v = pm.probe_corner_weights(*probe)
    exact = slice(0, len(cases) + n_axis)
    np.testing.assert_allclose(p[0, exact], w[exact], atol=1e-6, rtol=0)
    err = np.abs(p[0] - w)
    bound = float32_weight_error(*probe)
    assert np.all(err <= 1e-7 + bound)                                  # measured: <= 0.2 x bound
    general_err = err[len(cases) + n_axis:].max()
    print(f"probe weights: |gpu - numpy| max {err[exact].max():.2e} (lecture cases + axis-aligned "
          f"planes), {general_err:.2e} (general planes; float32 bound up to {bound.max():.2e})")
    np.testing.assert_array_equal(p[1, :, 0], v)
    assert 0.2 < v.mean() < 0.95                                                    # both outcomes
    bl = bilinear_weights(np.array([0.3, 0.6]))
    np.testing.assert_allclose(p[0, 0], bl, atol=1e-6)                              # flat plane
    assert p[1, 0, 0] == 1
    assert p[0, 1, 1] < 1e-6 and p[1, 1, 0] == 1                                    # one corner 5 % off
    assert p[1, 2, 0] == 0 and p[1, 5, 0] == 0                                      # all off / invalid
