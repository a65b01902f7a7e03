"""Materials as plain arrays, and their evaluation at surface hits (bilinear, wrapping textures).

`operators/` turns Blender materials into these: a Principled BSDF's Base Color and Emission
(value, or an Image Texture linked directly), else the material's viewport display colour, as
Workbench does. Colours are linear RGB. Textures are float32 (H, W, C) arrays with row 0 at
v = 0 (Blender's pixel order) and wrap in both directions (Blender's default "Repeat").
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Optional

import numpy as np

DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
# Materials that stop no more than this share of light are see-through (glass, alpha): their faces
# are left out of the SDFs, the cards and the G-buffer, so light and the camera pass them
SEE_THROUGH = 0.5


@dataclass
class Material:
    name: str = "default"
    base_color: tuple = DEFAULT_ALBEDO            # linear RGB, used when there is no texture
    base_color_texture: Optional[np.ndarray] = None
    emission_color: tuple = (0.0, 0.0, 0.0)       # linear RGB, multiplied by the strength
    emission_strength: float = 0.0
    emission_texture: Optional[np.ndarray] = None
    # the share of light the surface stops (1 opaque; 0 clear glass or fully transparent):
    # operators/extract.py leaves out the faces of a material at or under SEE_THROUGH, so it is
    # not in the digest (the faces kept say it)
    opacity: float = 1.0
    # a Holdout shader: the camera sees nothing there (rgba 0, as Cycles), while the surface
    # still blocks and absorbs light (its colours are black). Not in the digest: the cards'
    # black albedo says it
    holdout: bool = False
    # the base colour is the mesh's colour attribute (per corner: ObjectInput.colors), as a
    # Color Attribute node into Base Color makes it; base_color is unused then
    vertex_colors: bool = False
    # a cut-out: the base colour texture's alpha under 0.5 is a hole for the camera (the
    # G-buffer discards it); the SDFs and cards keep the whole faces, as Lumen's distance fields
    # do, and the cards' albedo is weighted by the alpha (the leaves reflect, the holes do not)
    alpha_clip: bool = False
    # a tangent-space normal map (a Normal Map node's Color from an Image Texture, linear data)
    # and its Strength: the G-buffer's shading normal (the object's `tangents`); the SDFs and
    # cards keep the geometric normals. Not in the digest: the cards do not depend on it
    normal_texture: Optional[np.ndarray] = None
    normal_strength: float = 1.0
    # normal_texture is a Bump node's height (H, W) times its Distance (negative: Invert) and
    # normal_strength its Strength: the G-buffer bumps the normal by the height's derivatives
    bump: bool = False

    def digest(self) -> bytes:
        """Content hash input (textures included), for re-baking only what changed."""
        h = hashlib.sha1(repr((self.name, tuple(map(float, self.base_color)),
                               tuple(map(float, self.emission_color)),
                               float(self.emission_strength), bool(self.vertex_colors))).encode())
        if self.alpha_clip:               # only then: other materials keep their digests
            h.update(b"alpha_clip")
        for tex in (self.base_color_texture, self.emission_texture):
            if tex is None:
                h.update(b"-")
            else:
                a = np.ascontiguousarray(tex, dtype=np.float32)
                h.update(str(a.shape).encode())
                h.update(a.tobytes())
        return h.digest()


def sample_texture(tex: np.ndarray, uv: np.ndarray, alpha: bool = False) -> np.ndarray:
    """Bilinear lookup with wrapping; texel centres at (i + 0.5) / size. Returns (N, 3) RGB, or
    with `alpha` (N, 4) RGBA (alpha 1 for a texture without one)."""
    t = np.asarray(tex, np.float32)
    if t.ndim == 2:
        t = t[:, :, None]
    h, w = t.shape[:2]
    x = np.asarray(uv[:, 0], np.float64) * w - 0.5
    y = np.asarray(uv[:, 1], np.float64) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    c = (t[y0, x0] * (1 - fx) * (1 - fy) + t[y0, x1] * fx * (1 - fy)
         + t[y1, x0] * (1 - fx) * fy + t[y1, x1] * fx * fy)
    if alpha:
        a = c[:, 3:4] if c.shape[1] == 4 else np.ones((len(c), 1), c.dtype)
    if c.shape[1] == 1:
        c = np.repeat(c, 3, axis=1)
    return np.concatenate([c[:, :3], a], axis=1) if alpha else c[:, :3]


def shade(materials, material_ids: np.ndarray, uv: Optional[np.ndarray],
          colors: Optional[np.ndarray] = None):
    """Albedo and emission (N, 3) for hits with these material ids and UVs (None: no UV map);
    colors (N, 3): the mesh's colour attribute at the hits, the albedo of vertex_colors
    materials (None: their base_color)."""
    n = len(material_ids)
    albedo = np.empty((n, 3), np.float32)
    emissive = np.zeros((n, 3), np.float32)
    mats = list(materials) or [Material()]
    ids = np.clip(material_ids, 0, len(mats) - 1)
    for k, m in enumerate(mats):          # a loop over materials, each one vectorised
        sel = np.flatnonzero(ids == k)
        if not sel.size:
            continue
        if m.vertex_colors and colors is not None:
            albedo[sel] = colors[sel]
        elif m.base_color_texture is not None and uv is not None and m.alpha_clip:
            rgba = sample_texture(m.base_color_texture, uv[sel], alpha=True)
            albedo[sel] = rgba[:, :3] * rgba[:, 3:4]      # a cut-out: its holes reflect nothing
        elif m.base_color_texture is not None and uv is not None:
            albedo[sel] = sample_texture(m.base_color_texture, uv[sel])
        else:
            albedo[sel] = np.asarray(m.base_color, np.float32)[:3]
        if m.emission_strength:
            col = (sample_texture(m.emission_texture, uv[sel])
                   if m.emission_texture is not None and uv is not None
                   else np.asarray(m.emission_color, np.float32)[None, :3])
            emissive[sel] = col * np.float32(m.emission_strength)
    return albedo, emissive


# Points per triangle where shadow_transmission reads a cut-out's alpha (fewer on big meshes: at
# most COVERAGE_SAMPLES in all, at least one per triangle)
COVERAGE_POINTS = 256
COVERAGE_SAMPLES = 1 << 18


def shadow_transmission(vertices, triangles, uvs, material_ids, materials) -> float:
    """The share of light that passes one layer of the mesh's surface through its cut-outs' holes
    (alpha under 0.5): 0 for an opaque mesh, 0.5 for a plane cut into a checker. Area-weighted over
    every triangle, so a tree's opaque trunk counts with its leaves.

    Why: the SDFs keep a cut-out's whole faces (a leaf card is a plane to them), so its shadow
    would be the whole card's. The shadow cones let this share through each such surface they
    cross (light_lib.glsl), as Lumen's distance fields treat foliage as partly occluding: the mean
    light under a canopy is right, the pattern of its holes is not drawn.
    Numpy only: stratified points on each triangle, the texture's bilinear alpha there."""
    mats = list(materials)
    if not mats or uvs is None or material_ids is None or not len(triangles):
        return 0.0
    cut = np.array([m.alpha_clip and m.base_color_texture is not None for m in mats], bool)
    if not cut.any():
        return 0.0
    v = np.asarray(vertices, np.float64)
    tri = np.asarray(triangles, np.int64)
    with np.errstate(invalid="ignore", over="ignore"):
        area = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]],
                                             v[tri[:, 2]] - v[tri[:, 0]]), axis=1)
    area[~np.isfinite(area)] = 0.0                # a NaN vertex: its triangles weigh nothing
    total = float(area.sum())
    if not np.isfinite(total) or total <= 0.0:
        return 0.0
    ids = np.clip(np.asarray(material_ids, np.int64), 0, len(mats) - 1)
    uv = np.asarray(uvs, np.float64)
    holes = 0.0
    for k in np.flatnonzero(cut):          # a loop over cut-out materials, each vectorised
        sel = np.flatnonzero(ids == k)
        if not sel.size:
            continue
        n = int(np.clip(COVERAGE_SAMPLES // sel.size, 1, COVERAGE_POINTS))
        # stratified barycentric points (a rank-1 lattice folded into the triangle)
        i = np.arange(n) + 0.5
        a, b = i / n, np.modf(i * 0.6180339887498949)[0]
        fold = a + b > 1.0
        a, b = np.where(fold, 1.0 - a, a), np.where(fold, 1.0 - b, b)
        c = uv[sel]                                            # (S, 3, 2)
        pts = (c[:, None, 0] * (1.0 - a - b)[None, :, None] + c[:, None, 1] * a[None, :, None]
               + c[:, None, 2] * b[None, :, None]).reshape(-1, 2)
        alpha = sample_texture(mats[k].base_color_texture, pts, alpha=True)[:, 3]
        open_share = (alpha.reshape(sel.size, n) < 0.5).mean(axis=1)
        holes += float((open_share * area[sel]).sum())
    return float(np.clip(holes / total, 0.0, 1.0))
