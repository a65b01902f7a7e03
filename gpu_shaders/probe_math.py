"""numpy twins of the probe GLSL libraries (no gpu / bpy: importable by pytest without Blender).

| GLSL file                  | twins here                                                        |
|----------------------------|-------------------------------------------------------------------|
| glsl/octahedral_lib.glsl   | oct_encode, oct_decode, oct_texel_dir, oct_texel,                 |
|                            | oct_texel_solid_angle                                             |
| glsl/sh_lib.glsl           | sh4_basis, sh9_basis, sh9_eval, sh4_irradiance, sh9_irradiance    |
| glsl/sampling_lib.glsl     | radical_inverse_vdc, hammersley, pcg_hash, tangent_frame,         |
|                            | cosine_hemisphere, uniform_sphere                                 |
| glsl/probe_interp_lib.glsl | probe_corner_weights                                              |

Every function is vectorised: the last axis holds the vector (3 for directions, 2 for uv / u,
9 or 4 for SH coefficients), leading axes broadcast. Continuous maths runs in float64 (the GPU runs
float32, so compare with a tolerance); the integer / bit functions (vdc, hammersley, pcg_hash) use
uint32 and float32 exactly as the GPU does and match it bit for bit. Helpers with no GLSL twin:
oct_texel_dirs, oct_texel_solid_angles, sh9_project (quadrature). Conventions (texel order, SH
coefficient order, the lecture's validity rule) are documented in the GLSL files' headers.
"""
from __future__ import annotations

import numpy as np

# --- octahedral mapping ---------------------------------------------------------------------


def _sign_not_zero(v):
    return np.where(v >= 0.0, 1.0, -1.0)


def oct_encode(d) -> np.ndarray:
    """Directions [..., 3] (any length > 0) -> uv [..., 2] in [0,1]^2; -z maps to (1, 1)."""
    d = np.asarray(d, np.float64)
    p = d / np.abs(d).sum(axis=-1, keepdims=True)
    f = np.where(p[..., 2:3] < 0.0, (1.0 - np.abs(p[..., 1::-1])) * _sign_not_zero(p[..., :2]),
                 p[..., :2])
    return f * 0.5 + 0.5


def oct_decode(uv) -> np.ndarray:
    """uv [..., 2] -> unit directions [..., 3] (exact inverse of oct_encode)."""
    f = np.asarray(uv, np.float64) * 2.0 - 1.0
    z = 1.0 - np.abs(f).sum(axis=-1)
    t = np.maximum(-z, 0.0)[..., None]
    n = np.concatenate([f - _sign_not_zero(f) * t, z[..., None]], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def oct_texel_dir(texel, res: int, jitter=(0.5, 0.5)) -> np.ndarray:
    """Direction through uv = (texel + jitter) / res; texel [..., 2] (x, y), jitter [..., 2]."""
    return oct_decode((np.asarray(texel, np.float64) + np.asarray(jitter, np.float64)) / res)


def oct_texel(d, res: int) -> np.ndarray:
    """int [..., 2] (x, y): the texel of a res x res octahedral probe containing direction d."""
    return np.clip(np.floor(oct_encode(d) * res).astype(np.int64), 0, res - 1)


def _triangle_solid_angle(a, b, c):
    num = np.abs(np.einsum("...i,...i->...", a, np.cross(b - a, c - a)))
    den = 1.0 + (a * b).sum(-1) + (b * c).sum(-1) + (c * a).sum(-1)
    return 2.0 * np.arctan2(num, den)


def oct_texel_solid_angle(texel, res: int) -> np.ndarray:
    """Solid angle (sr) of texel(s) [..., 2]: exact for even res (two spherical triangles split
    along the octahedron fold; see octahedral_lib.glsl), an approximation for odd res."""
    t = np.asarray(texel, np.float64)
    c00 = oct_decode(t / res)
    c10 = oct_decode((t + (1.0, 0.0)) / res)
    c01 = oct_decode((t + (0.0, 1.0)) / res)
    c11 = oct_decode((t + (1.0, 1.0)) / res)
    centre = (t + 0.5) / res * 2.0 - 1.0
    anti = centre[..., 0] * centre[..., 1] > 0.0
    split_anti = _triangle_solid_angle(c10, c01, c00) + _triangle_solid_angle(c10, c11, c01)
    split_main = _triangle_solid_angle(c00, c10, c11) + _triangle_solid_angle(c00, c11, c01)
    return np.where(anti, split_anti, split_main)


def _texel_grid(res: int) -> np.ndarray:
    y, x = np.mgrid[0:res, 0:res]
    return np.stack([x, y], axis=-1)


def oct_texel_dirs(res: int) -> np.ndarray:
    """[res, res, 3] texel-centre directions, indexed [y, x] (row y = texel.y, like an image)."""
    return oct_texel_dir(_texel_grid(res), res)


def oct_texel_solid_angles(res: int) -> np.ndarray:
    """[res, res] texel solid angles, indexed [y, x]; they sum to 4 pi (exactly for even res)."""
    return oct_texel_solid_angle(_texel_grid(res), res)


# --- spherical harmonics --------------------------------------------------------------------

SH_Y0 = 0.5 * np.sqrt(1.0 / np.pi)
SH_Y1 = np.sqrt(3.0 / (4.0 * np.pi))
SH_Y2 = 0.5 * np.sqrt(15.0 / np.pi)
SH_Y20 = 0.25 * np.sqrt(5.0 / np.pi)
SH_Y22 = 0.25 * np.sqrt(15.0 / np.pi)
SH_BAND = np.array([0, 1, 1, 1, 2, 2, 2, 2, 2])                   # l of coefficient i
SH_A = np.array([np.pi, 2.0 * np.pi / 3.0, np.pi / 4.0])         # clamped-cosine convolution


def sh4_basis(d) -> np.ndarray:
    """[..., 4]: Y00, Y1-1 (y), Y10 (z), Y11 (x) of unit directions [..., 3]."""
    return sh9_basis(d)[..., :4]


def sh9_basis(d) -> np.ndarray:
    """[..., 9] in the order i = l (l + 1) + m (see sh_lib.glsl) of unit directions [..., 3]."""
    d = np.asarray(d, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.full_like(x, SH_Y0), SH_Y1 * y, SH_Y1 * z, SH_Y1 * x,
                     SH_Y2 * x * y, SH_Y2 * y * z, SH_Y20 * (3.0 * z * z - 1.0),
                     SH_Y2 * x * z, SH_Y22 * (x * x - y * y)], axis=-1)


def _apply(c, b):
    """sum_i c[..., i, :] b[..., i] with broadcasting; c [..., k, C], or [k] for one channel."""
    c = np.asarray(c, np.float64)
    if c.ndim == 1:                                   # one channel, one probe
        return (b * c).sum(-1)
    return np.einsum("...i,...ic->...c", b, c)


def sh9_eval(c, d) -> np.ndarray:
    """Radiance sum_i c_i Y_i(d): c [..., 9, C] (or [9] for one channel), d [..., 3]."""
    return _apply(c, sh9_basis(d))


def sh4_irradiance(c, n) -> np.ndarray:
    """Irradiance at normal(s) n [..., 3] from radiance coefficients c [..., 4, C] (or [4])."""
    return _apply(c, sh4_basis(n) * SH_A[SH_BAND[:4]])


def sh9_irradiance(c, n) -> np.ndarray:
    """Irradiance at normal(s) n [..., 3] from radiance coefficients c [..., 9, C] (or [9]):
    sum_i A_l c_i Y_i(n), A = (pi, 2pi/3, pi/4); constant radiance L -> pi L."""
    return _apply(c, sh9_basis(n) * SH_A[SH_BAND])


def sh9_project(dirs, values, weights) -> np.ndarray:
    """Quadrature sum_k w_k v_k Y_i(d_k) ~ integral of v Y_i: dirs [..., 3], values [...] or
    [..., C], weights [...] (solid angles, or 4 pi / N for uniform samples). -> [9] or [9, C]."""
    dirs = np.asarray(dirs, np.float64).reshape(-1, 3)
    w = np.asarray(weights, np.float64).reshape(-1)
    v = np.asarray(values, np.float64)
    scalar = v.size == w.size
    v = v.reshape(w.size, -1)
    c = sh9_basis(dirs).T @ (v * w[:, None])
    return c[:, 0] if scalar else c


# --- sampling -------------------------------------------------------------------------------

TWO_PI = 2.0 * np.pi


def _bit_reverse32(v):
    v = np.asarray(v, np.uint32)
    v = ((v >> 1) & 0x55555555) | ((v & 0x55555555) << 1)
    v = ((v >> 2) & 0x33333333) | ((v & 0x33333333) << 2)
    v = ((v >> 4) & 0x0F0F0F0F) | ((v & 0x0F0F0F0F) << 4)
    v = ((v >> 8) & 0x00FF00FF) | ((v & 0x00FF00FF) << 8)
    return ((v >> 16) | (v << 16)).astype(np.uint32)


def radical_inverse_vdc(bits) -> np.ndarray:
    """float32: the 32 bits reversed as a fraction, truncated to 24 bits (exact, < 1)."""
    return (_bit_reverse32(bits) >> np.uint32(8)).astype(np.float32) * np.float32(2.0 ** -24)


def hammersley(n: int, i=None) -> np.ndarray:
    """float32 [..., 2] Hammersley points (i / n, vdc(i)): all n (i = 0..n-1) or indices i."""
    i = np.arange(n, dtype=np.uint32) if i is None else np.asarray(i, np.uint32)
    return np.stack([i.astype(np.float32) / np.float32(n), radical_inverse_vdc(i)], axis=-1)


def pcg_hash(v) -> np.ndarray:
    """uint32 PCG-RXS-M-XS hash, wrapping 32-bit arithmetic exactly as the GLSL uint ops."""
    v = np.asarray(v, np.uint32)
    with np.errstate(over="ignore"):
        state = v * np.uint32(747796405) + np.uint32(2891336453)
        word = ((state >> ((state >> np.uint32(28)) + np.uint32(4))) ^ state) * np.uint32(277803737)
    return ((word >> np.uint32(22)) ^ word).astype(np.uint32)


def tangent_frame(n) -> np.ndarray:
    """[..., 3, 3] with columns (t, b, n) for unit normals n [..., 3] (Duff et al. 2017):
    frame @ local maps a tangent-space vector (z along n) to world."""
    n = np.asarray(n, np.float64)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    s = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = np.stack([1.0 + s * x * x * a, s * b, -s * x], axis=-1)
    bt = np.stack([b, s + y * y * a, -y], axis=-1)
    return np.stack([t, bt, n], axis=-1)


def cosine_hemisphere(u, n) -> np.ndarray:
    """u [..., 2] in [0,1)^2 -> unit directions around unit n [..., 3], pdf = cos / pi."""
    u = np.asarray(u, np.float64)
    r = np.sqrt(u[..., 0])
    phi = TWO_PI * u[..., 1]
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))],
                     axis=-1)
    return np.einsum("...ij,...j->...i", tangent_frame(n), local)


def uniform_sphere(u) -> np.ndarray:
    """u [..., 2] in [0,1)^2 -> unit directions, pdf = 1 / (4 pi)."""
    u = np.asarray(u, np.float64)
    z = 1.0 - 2.0 * u[..., 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = TWO_PI * u[..., 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


# --- screen-probe interpolation -------------------------------------------------------------

PROBE_WEIGHT_EPS = 0.01
PROBE_PLANE_SHARPNESS = 10000.0


def probe_corner_weights(bilinear, p00, p10, p01, p11, corner_valid, scene_plane, scene_depth):
    """(weights [..., 4] in corner order 00, 10, 01, 11, lighting_valid [...] 0/1), exactly as
    probe_interp_lib.glsl: bilinear x exp2(-10000 (plane distance / depth)^2), 0 for invalid
    corners, divided by max(sum, 0.01); lighting_valid = 0 when the normalised sum < 0.99."""
    bl = np.asarray(bilinear, np.float64)
    bx, by = bl[..., 0], bl[..., 1]
    w_bilinear = np.stack([(1 - bx) * (1 - by), bx * (1 - by), (1 - bx) * by, bx * by], axis=-1)
    plane = np.asarray(scene_plane, np.float64)
    p = np.stack([np.asarray(q, np.float64) for q in (p00, p10, p01, p11)], axis=-2)  # [..., 4, 3]
    distance = np.abs(np.einsum("...ki,...i->...k", p, plane[..., :3]) - plane[..., 3:4])
    relative = distance / np.asarray(scene_depth, np.float64)[..., None]
    w_depth = np.exp2(-PROBE_PLANE_SHARPNESS * relative * relative)
    w_depth = w_depth * (np.asarray(corner_valid, np.float64) > 0.5)
    w = w_bilinear * w_depth
    w = w / np.maximum(w.sum(-1, keepdims=True), PROBE_WEIGHT_EPS)
    valid = np.where(w.sum(-1) < 1.0 - PROBE_WEIGHT_EPS, 0.0, 1.0)
    return w, valid
