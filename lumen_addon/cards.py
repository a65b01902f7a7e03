"""Mesh cards: orthographic captures of a mesh along the six axes (the lecture's surface cache).

A card is an axis-aligned rectangle in the mesh's local space that looks along one of +X, -X,
+Y, -Y, +Z, -Z, with a depth range [near, far]: one ray per texel from the near plane, stopping at
far, captures albedo, normal, depth, emissive and opacity with Embree.

Placement: the six cards of the mesh's bounds see everything visible from outside. Surfaces they
cannot see (a room seen from inside, the inside of a U, cavities) are found with area-weighted
surface samples: each unseen sample picks the axis it faces most, and the distance from it to the
first occluder towards that axis' card gives an interval of near-plane depths from which a card
would see it. The depth that stabs the most sample area, restricted to the largest connected
patch of those samples in the card plane, becomes the next card, tight around that patch (few
texels). Repeat until coverage reaches the target or the card limit (UE: 12 by default, 32 at
most). Compared with depth-peeled layers over the whole bounds, each extra card costs texels only
where unseen surface is.

Both sides of a face are surface unless it belongs to a closed part (geometry.orient_triangles),
whose backs are its inside, or its back faces an enclosed inside (enclosed_backs: a scan with
holes): Cycles and EEVEE shade and emit on both sides, so the back of an open
sheet (an emissive quad, an imported wall) gets cards too (tests/gpu/test_back_emission.py).
Coverage is measured on the captured texels: the share of area-weighted surface samples that
some card texel sees at the sample's depth (within a tolerance that allows for the surface slope
across a texel).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .geometry import CLOSED, MeshError, clean_mesh
from .materials import Material, shade

AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
AXIS_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
# For a card looking along axis a: the local coordinates that span its rectangle (u, v).
PLANE = {0: (1, 2), 1: (1, 2), 2: (0, 2), 3: (0, 2), 4: (0, 1), 5: (0, 1)}
MIN_RES, MAX_RES = 4, 512
FACING = 0.05          # |cos| below which a surface is edge-on to a card and not counted as seen


@dataclass
class Card:
    axis: int                  # look direction: index into AXES / AXIS_NAMES
    rect_min: np.ndarray       # (2,) local coordinates along the card's (u, v) axes, PLANE[axis]
    rect_max: np.ndarray
    near: float                # depth range along the look direction (depth = AXES[axis] . p)
    far: float
    resolution: tuple = (0, 0)  # texels (w along u, h along v)
    # Captured layers, indexed [row = v, column = u]:
    albedo: Optional[np.ndarray] = None     # (h, w, 3) linear RGB
    normal: Optional[np.ndarray] = None     # (h, w, 3) unit local-space normal (0 where empty)
    depth: Optional[np.ndarray] = None      # (h, w) metres from the near plane (0 where empty)
    emissive: Optional[np.ndarray] = None   # (h, w, 3) linear RGB x strength
    opacity: Optional[np.ndarray] = None    # (h, w) 1 where a surface side was hit

    @property
    def size(self) -> np.ndarray:
        return self.rect_max - self.rect_min

    def texel_size(self) -> np.ndarray:
        return self.size / np.maximum(np.array(self.resolution, float), 1)


@dataclass
class MeshCards:
    cards: list
    coverage: float = 0.0
    warnings: list = field(default_factory=list)

    @property
    def texels(self) -> int:
        return int(sum(c.resolution[0] * c.resolution[1] for c in self.cards))


class _Surface:
    """The mesh, its Embree scene and area-weighted surface samples for placement and coverage.

    Everything here is in a frame centred on the mesh bounds (`offset` in mesh space): Embree is
    float32, and a mesh 1e7 m from its origin got no cards at all (1e4 m: twice the cards, its own
    faces hiding its samples). finish() moves the cards back to mesh space.
    """

    def __init__(self, v, t, samples, seed=0, two_sided=False, open_faces=None):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        used = v[np.unique(t)]
        self.offset = 0.5 * (used.min(axis=0) + used.max(axis=0))
        v = v - self.offset
        self.v, self.t = v, t
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, np.ascontiguousarray(v, np.float32), np.ascontiguousarray(t, np.int32))
        tri = v[t]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = np.linalg.norm(cross, axis=1)
        self.face_normal = cross / np.maximum(area, 1e-300)[:, None]
        self.area = area
        self.two_sided = bool(two_sided)
        # Faces whose back is surface too: every face of a two-sided mesh, else the faces of open
        # parts (geometry.orient_triangles: OPEN / NON_ORIENTABLE). Cycles and EEVEE shade and
        # emit on both sides of every face; only a closed part hides its backs (its inside). An
        # emissive quad lights the ceiling above it with its back as much as the room below.
        if self.two_sided:
            self.both = np.ones(len(t), bool)
        elif open_faces is not None:
            self.both = np.asarray(open_faces, bool).copy()
        else:
            self.both = np.zeros(len(t), bool)
        self.p, self.n = self.sample(samples, seed)
        self.bmin, self.bmax = used.min(axis=0) - self.offset, used.max(axis=0) - self.offset
        self.eps = 1e-5 * float(np.max(self.bmax - self.bmin) or 1.0)

    def sample(self, count: int, seed: int):
        """Area-weighted random points on the triangles and their face normals."""
        rng = np.random.default_rng(seed)
        ids = rng.choice(len(self.t), count, p=self.area / self.area.sum())
        r1, r2 = np.sqrt(rng.random(count)), rng.random(count)
        pt = self.v[self.t[ids]]
        p = (pt[:, 0] * (1 - r1)[:, None] + pt[:, 1] * (r1 * (1 - r2))[:, None]
             + pt[:, 2] * (r1 * r2)[:, None])
        n = self.face_normal[ids]
        # both sides are surface: half the samples look the other way
        back = self.both[ids] & (np.arange(count) % 2 == 1)
        n = np.where(back[:, None], -n, n)
        return p, n

    def blocker_distance(self, idx, axis):
        """Distance from samples idx towards the card side of `axis` to the first surface."""
        d = -AXES[axis]
        o = (self.p[idx] + d * self.eps).astype(np.float32)
        hit = self.scene.run(o, np.repeat(d[None].astype(np.float32), len(idx), 0), output=1)
        return np.where(hit["primID"] >= 0, hit["tfar"].astype(np.float64) + self.eps, np.inf)

    def seen_by(self, card: Card) -> np.ndarray:
        """Samples an ideal (infinitely fine) card would see: facing it, inside its rectangle
        and depth range, and nothing in between."""
        a, (iu, iv) = card.axis, PLANE[card.axis]
        depth = self.p @ AXES[a]
        ok = ((self.n @ AXES[a] < -FACING)
              & (self.p[:, iu] >= card.rect_min[0]) & (self.p[:, iu] <= card.rect_max[0])
              & (self.p[:, iv] >= card.rect_min[1]) & (self.p[:, iv] <= card.rect_max[1])
              & (depth >= card.near) & (depth <= card.far))
        idx = np.flatnonzero(ok)
        if idx.size:
            free = self.blocker_distance(idx, a) > depth[idx] - card.near
            ok[idx[~free]] = False
        return ok


def bounds_cards(surface: _Surface) -> list:
    """The six cards of the mesh bounds."""
    pad = surface.eps * 10
    out = []
    for a in range(6):
        iu, iv = PLANE[a]
        depth = surface.v @ AXES[a]
        out.append(Card(a, np.array([surface.bmin[iu] - pad, surface.bmin[iv] - pad]),
                        np.array([surface.bmax[iu] + pad, surface.bmax[iv] + pad]),
                        float(depth.min() - pad), float(depth.max() + pad)))
    return out


def _largest_patch(uv: np.ndarray, cells: int = 24) -> np.ndarray:
    """Mask of the samples in the largest connected patch of a coarse occupancy grid (cells
    dilated by one), so one card does not span two far-apart surfaces."""
    lo = uv.min(axis=0)
    cell = max(float((uv.max(axis=0) - lo).max()) / cells, 1e-12)
    ij = np.minimum(((uv - lo) / cell).astype(np.int64), cells) + 2     # 2 empty cells of border
    n = cells + 5
    occ = np.zeros((n, n), bool)
    occ[ij[:, 0], ij[:, 1]] = True
    shifts = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
    grown = np.zeros_like(occ)
    for dx, dy in shifts:
        grown |= np.roll(occ, (dx, dy), axis=(0, 1))
    big = occ.size
    label = np.where(grown, np.arange(big).reshape(n, n), big)
    while True:   # min-label propagation over the small grid until stable
        best = label
        for dx, dy in shifts:
            best = np.minimum(best, np.roll(label, (dx, dy), axis=(0, 1)))
        best = np.where(grown, best, big)
        if np.array_equal(best, label):
            break
        label = best
    lab = label[ij[:, 0], ij[:, 1]]
    values, counts = np.unique(lab, return_counts=True)
    return lab == values[np.argmax(counts)]


def _candidate(surface: _Surface, idx: np.ndarray, axis: int):
    """The card along `axis` that sees the most of samples idx: the near-plane depth that stabs
    the most visibility intervals, around the largest connected patch of those samples."""
    depth = surface.p[idx] @ AXES[axis]
    lo = depth - surface.blocker_distance(idx, axis)   # the near plane must be beyond lo ...
    hi = depth                                         # ... and not beyond the sample
    cand = np.sort(hi)
    stabbed = np.searchsorted(np.sort(lo), cand, side="left") - np.searchsorted(cand, cand, side="left")
    z = float(cand[np.argmax(stabbed)])
    inside = (lo < z) & (hi >= z)
    sel, lo_sel = idx[inside], lo[inside]
    iu, iv = PLANE[axis]
    patch = _largest_patch(surface.p[sel][:, [iu, iv]])
    sel, lo_sel = sel[patch], lo_sel[patch]
    pad = surface.eps * 10
    uv = surface.p[sel][:, [iu, iv]]
    # Near plane strictly beyond every selected sample's occluder and not beyond z.
    lo_max = float(lo_sel.max())
    near = max(z - pad, 0.5 * (lo_max + z)) if np.isfinite(lo_max) else z - pad
    far = float((surface.p[sel] @ AXES[axis]).max() + pad)
    return Card(axis, uv.min(axis=0) - pad, uv.max(axis=0) + pad, near, far)


def place_cards(surface: _Surface, *, max_cards: int = 32, target: float = 0.999,
                min_gain: float = 0.0002) -> list:
    """Six bounds cards, then greedy cards for what they cannot see (see module docstring):
    each round builds the best candidate along every axis and keeps the one that sees the most
    unseen surface."""
    cards = bounds_cards(surface)
    seen = np.zeros(len(surface.p), bool)
    for c in cards:
        seen |= surface.seen_by(c)
    facing = -(surface.n @ AXES.T)                      # (N, 6) cosine towards each card side
    least = max(1, int(min_gain * len(seen)))
    while len(cards) < max_cards and seen.mean() < target:
        best_card, best_gain = None, None
        for axis in range(6):
            idx = np.flatnonzero(~seen & (facing[:, axis] > 0.2))
            if idx.size < least:
                continue
            card = _candidate(surface, idx, axis)
            gain = surface.seen_by(card) & ~seen
            if best_gain is None or gain.sum() > best_gain.sum():
                best_card, best_gain = card, gain
        if best_gain is None or best_gain.sum() < least:
            break
        seen |= best_gain
        cards.append(best_card)
    return cards


def set_resolution(cards, texel_density: float):
    for c in cards:
        w, h = np.clip(np.ceil(c.size * texel_density), MIN_RES, MAX_RES).astype(int)
        c.resolution = (int(w), int(h))


def capture(surface: _Surface, cards, normals=None, uvs=None, material_ids=None, materials=(),
            colors=None):
    """Fill every card's layers with one Embree ray per texel."""
    for c in cards:
        w, h = c.resolution
        iu, iv = PLANE[c.axis]
        ts = c.size / np.array([w, h], float)
        cu = c.rect_min[0] + (np.arange(w) + 0.5) * ts[0]
        cv = c.rect_min[1] + (np.arange(h) + 0.5) * ts[1]
        V, U = np.meshgrid(cv, cu, indexing="ij")              # rows = v, columns = u
        o = np.zeros((h * w, 3))
        o[:, iu], o[:, iv] = U.ravel(), V.ravel()
        o += AXES[c.axis] * c.near
        d = np.repeat(AXES[c.axis][None].astype(np.float32), len(o), 0)
        r = surface.scene.run(o.astype(np.float32), d,
                              dists=np.full(len(o), c.far - c.near, np.float32), output=1)
        prim = r["primID"]
        hit = np.flatnonzero(prim >= 0)
        facing = surface.face_normal[prim[hit]] @ AXES[c.axis]
        # Front faces belong to this card, back faces only where the back is surface (open
        # parts, two-sided meshes): a closed part's back face means we are looking from inside.
        keep = (facing < 0) | surface.both[prim[hit]]
        hit, facing = hit[keep], facing[keep]
        pid = prim[hit]
        bu, bv = r["u"][hit].astype(np.float64), r["v"][hit].astype(np.float64)
        bary = np.stack([1 - bu - bv, bu, bv], axis=1)
        if normals is not None:
            nrm = np.einsum("nk,nkj->nj", bary, normals[pid])
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
        else:
            nrm = surface.face_normal[pid]
        nrm = np.where((facing > 0)[:, None], -nrm, nrm)   # two-sided: the side the card sees
        uv = np.einsum("nk,nkj->nj", bary, uvs[pid]) if uvs is not None else None
        mid = material_ids[pid] if material_ids is not None else np.zeros(len(pid), np.int64)
        col = np.einsum("nk,nkj->nj", bary, colors[pid]) if colors is not None else None
        albedo, emissive = shade(materials, mid, uv, col)
        c.albedo = np.zeros((h * w, 3), np.float32)
        c.normal = np.zeros((h * w, 3), np.float32)
        c.depth = np.zeros(h * w, np.float32)
        c.emissive = np.zeros((h * w, 3), np.float32)
        c.opacity = np.zeros(h * w, np.float32)
        c.albedo[hit], c.normal[hit], c.emissive[hit] = albedo, nrm, emissive
        c.depth[hit] = r["tfar"][hit]
        c.opacity[hit] = 1.0
        c.albedo, c.normal, c.emissive = (x.reshape(h, w, 3) for x in (c.albedo, c.normal, c.emissive))
        c.depth, c.opacity = c.depth.reshape(h, w), c.opacity.reshape(h, w)


def texel_coverage(surface: _Surface, cards, samples: int = 32768, seed: int = 1) -> float:
    """Share of surface samples that some captured texel sees at the sample's depth. The samples
    are drawn afresh (another seed than placement's), so the number is not biased by them."""
    pts, nrm = surface.sample(samples, seed)
    seen = np.zeros(len(pts), bool)
    for c in cards:
        a, (iu, iv) = c.axis, PLANE[c.axis]
        cos = -(nrm @ AXES[a])
        depth = pts @ AXES[a] - c.near
        ts = c.texel_size()
        # The 2x2 texels a bilinear lookup at the sample reads (texel centres at i + 0.5).
        fu = (pts[:, iu] - c.rect_min[0]) / ts[0] - 0.5
        fv = (pts[:, iv] - c.rect_min[1]) / ts[1] - 0.5
        w, h = c.resolution
        ok = np.flatnonzero((cos > FACING) & (fu > -1) & (fu < w) & (fv > -1) & (fv < h) & ~seen)
        if not ok.size:
            continue
        # Depth tolerance: half a texel, plus how far the surface's slope moves across a texel.
        tan = np.sqrt(np.maximum(1 - cos[ok] ** 2, 0)) / cos[ok]
        tol = float(ts.max()) * (0.5 + 1.5 * np.minimum(tan, 20.0))
        i0, j0 = np.floor(fu[ok]).astype(np.int64), np.floor(fv[ok]).astype(np.int64)
        good = np.zeros(ok.size, bool)
        for di in (0, 1):
            for dj in (0, 1):
                ii, jj = np.clip(i0 + di, 0, w - 1), np.clip(j0 + dj, 0, h - 1)
                good |= (c.opacity[jj, ii] > 0) & (np.abs(c.depth[jj, ii] - depth[ok]) <= tol)
        seen[ok[good]] = True
    return float(seen.mean())


def bake_mesh_cards(vertices, triangles, *, texel_density: float = 20.0, normals=None, uvs=None,
                    material_ids=None, materials=None, max_cards: int = 32, two_sided: bool = False,
                    samples: int = 16384, seed: int = 0, colors=None) -> MeshCards:
    """Place, capture and measure the cards of one mesh (local space, metres).

    normals (T,3,3), uvs (T,3,2), material_ids (T,), materials [Material], colors (T,3,3):
    optional surface attributes; without materials the albedo is plain grey. texel_density: texels per metre
    (each card side clamped to 4..512 texels). two_sided: both sides of every face are surface
    (foliage, sheets). Raises MeshError on meshes that cannot be baked.
    """
    if not (np.isfinite(texel_density) and texel_density > 0):
        raise MeshError(f"texel density must be a positive number, got {texel_density!r}")
    surface, attrs, warnings = prepare(vertices, triangles, normals, uvs, material_ids, materials,
                                       samples, seed, two_sided, colors=colors)
    cards = place_cards(surface, max_cards=max_cards)
    set_resolution(cards, texel_density)
    capture(surface, cards, **attrs)
    return finish(surface, cards, warnings)


def finish(surface: _Surface, cards, warnings) -> MeshCards:
    """Drop cards that captured nothing (a bounds card of a room seen from inside), measure,
    and move the cards from the surface's centred frame to mesh space."""
    cards = [c for c in cards if c.opacity.any()]
    coverage = texel_coverage(surface, cards)
    for c in cards:
        shift = float(AXES[c.axis] @ surface.offset)
        c.rect_min = c.rect_min + surface.offset[list(PLANE[c.axis])]
        c.rect_max = c.rect_max + surface.offset[list(PLANE[c.axis])]
        c.near, c.far = c.near + shift, c.far + shift
    return MeshCards(cards, coverage, warnings)


ENCLOSED_FRACTION = 0.75   # back-face share of rays from behind a face above which its back is inside


def enclosed_backs(v, t, which) -> np.ndarray:
    """bool per face (only `which` tested): its back faces an enclosed inside, as a scan's with
    holes does (the Stanford bunny, open at its base: 32 cards, 26 of them for its inside, 6
    without). Such a back is no surface: no ray reaches it (the SDF caps the holes, sign.py).

    A point just behind the face's centre is inside when more than ENCLOSED_FRACTION of its rays
    hit back faces (sign.SignTester). Behind an open sheet half of them do (the sheet itself):
    its back stays surface, with a margin over the SDF's 0.5 (tests/gpu/test_back_emission.py).
    """
    from .sign import SignTester

    out = np.zeros(len(t), bool)
    idx = np.flatnonzero(which)
    if not len(idx):
        return out
    tri = v[t[idx]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    used = v[np.unique(t)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    eps = 1e-4 * float(np.linalg.norm(hi - lo))
    tester = SignTester(v, t, inside_fraction=ENCLOSED_FRACTION, origin=0.5 * (lo + hi))
    out[idx] = tester.inside(tri.mean(axis=1) - eps * n)
    return out


def prepare(vertices, triangles, normals, uvs, material_ids, materials, samples=16384, seed=0,
            two_sided=False, orientation=None, colors=None):
    """Validate the mesh and its attributes; drop what is unusable with a warning.

    Inside-out faces are flipped as for the SDF (clean_mesh; orientation: orient_triangles of
    these arrays when the caller has it), so cards capture the outside; corner attributes follow.
    """
    mesh = clean_mesh(vertices, triangles, orient=not two_sided, orientation=orientation)
    t = np.asarray(triangles)
    keep = mesh.kept if len(mesh.kept) != len(t) else None
    warnings = []
    mats = list(materials or []) or [Material()]

    def rows(a, shape, what):
        if a is None:
            return None
        a = np.asarray(a)
        if a.shape[0] != len(t) or a.shape[1:] != shape or (a.dtype.kind == "f" and not np.isfinite(a).all()):
            warnings.append(f"{what} ignored (expected {(len(t),) + shape} finite values, got {a.shape})")
            return None
        return a if keep is None else a[keep]

    normals = rows(normals, (3, 3), "normals")
    uvs = rows(uvs, (3, 2), "UVs")
    colors = rows(colors, (3, 3), "colour attribute")
    flip = mesh.flipped
    if flip.any():
        # Corners 1 and 2 swap with the winding; a flipped face's corner normals pointed inwards
        # with it (Blender derives them from the winding), so those facing away are turned.
        if uvs is not None:
            uvs = uvs.copy()
            uvs[flip] = uvs[flip][:, [0, 2, 1]]
        if colors is not None:
            colors = np.array(colors, copy=True)
            colors[flip] = colors[flip][:, [0, 2, 1]]
        if normals is not None:
            normals = np.asarray(normals, np.float64).copy()
            nf = normals[flip][:, [0, 2, 1]]
            tri = mesh.vertices[mesh.triangles[flip]]
            face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            away = np.einsum("tkj,tj->tk", nf, face) < 0
            nf[away] = -nf[away]
            normals[flip] = nf
    material_ids = rows(material_ids, (), "material indices")
    if material_ids is not None:
        material_ids = np.clip(material_ids.astype(np.int64), 0, len(mats) - 1)
    if uvs is None and any(m.base_color_texture is not None or m.emission_texture is not None for m in mats):
        warnings.append("a material has a texture but the mesh has no UVs: base colour used instead")
    open_faces = None if mesh.orientation is None else mesh.orientation.part != CLOSED
    if open_faces is not None and open_faces.any():
        open_faces &= ~enclosed_backs(mesh.vertices, mesh.triangles, open_faces)
    surface = _Surface(mesh.vertices, mesh.triangles, samples, seed, two_sided, open_faces)
    return surface, {"normals": normals, "uvs": uvs, "material_ids": material_ids, "materials": mats,
                     "colors": colors}, warnings
