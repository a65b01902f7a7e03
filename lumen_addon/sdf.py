"""Sparse per-mesh signed distance fields in bricks, with three mips (the lecture's mesh SDF).

Layout of one mip (all arrays indexed [x, y, z]):
- the volume spans `resolution` voxels of edge `voxel_size` per axis from `origin` (a multiple
  of 7 per axis); distance samples sit on the voxel corners, `resolution + 1` per axis;
- it is cut into bricks of 8^3 samples: 7^3 own samples plus the first layer of the next brick,
  so trilinear filtering inside a brick never reads a neighbour;
- `indirection[bx, by, bz]` is a slot in `bricks` or INVALID_OUTSIDE / INVALID_INSIDE for a brick
  whose samples are all farther than the band from the surface (not stored);
- `bricks[slot]` holds uint8 codes of the distance over [-band, +band] (band = BAND_VOXELS voxels
  of that mip): d = (code - 127.5) / 127.5 * band.

`MeshSDF.sample` is the numpy reference that the GPU shaders are tested against.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .distance import Grid, box_samples, narrow_band_distance
from .geometry import TrianglePairs, boundary_loops
from .geometry import MeshError, clean_mesh
from .sign import INSIDE_FRACTION, SignTester, flood_signs

BRICK = 8                  # samples per brick edge
BRICK_CELLS = BRICK - 1    # unique samples (voxels) per brick edge
BAND_VOXELS = 4.0          # max encode distance, in voxels of the mip
MARGIN_VOXELS = 2          # empty voxels around the mesh bounds
MIP_COUNT = 3
DEFAULT_MAX_RESOLUTION = 126   # voxels per axis at mip 0 (UE clamps ordinary meshes here)
HARD_MAX_RESOLUTION = 252      # beyond this a single mesh would need gigabytes while baking
INVALID_OUTSIDE = -1
INVALID_INSIDE = -2


class BakeCancelled(Exception):
    """Raised from a progress callback to stop a bake; nothing is written."""


@dataclass
class SDFMip:
    voxel_size: float
    resolution: tuple          # voxels per axis (multiple of 7)
    indirection: np.ndarray    # int32 [bx, by, bz]
    bricks: np.ndarray         # uint8 [slot, 8, 8, 8]

    @property
    def band(self) -> float:
        return BAND_VOXELS * self.voxel_size

    @property
    def brick_grid(self) -> tuple:
        return tuple(int(n) for n in self.indirection.shape)


@dataclass
class MeshSDF:
    origin: np.ndarray         # local-space position of sample (0, 0, 0), metres
    bounds_min: np.ndarray     # mesh bounds (local space)
    bounds_max: np.ndarray
    two_sided: bool
    mips: list = field(default_factory=list)
    requested_resolution: tuple = ()   # what density x scale asked for, before the clamp
    dropped_degenerate: int = 0
    timings: dict = field(default_factory=dict)   # seconds per bake stage, summed over mips
    orientation_notes: list = field(default_factory=list)   # faces flipped, for the warnings
    edge_voxels: list = field(default_factory=list)   # per mip: edge_rounding (empty: unknown)

    @property
    def voxel_size(self) -> float:
        """Mip-0 voxel edge in metres."""
        return self.mips[0].voxel_size

    @property
    def clamped(self) -> bool:
        return tuple(self.requested_resolution) != tuple(self.mips[0].resolution)

    def stats(self) -> list:
        """Per mip: resolution, bricks kept/total and bytes (kept bricks + indirection table)."""
        out = []
        for m in self.mips:
            total = int(np.prod(m.brick_grid))
            kept = int(len(m.bricks))
            out.append({
                "resolution": list(m.resolution),
                "voxel_size": m.voxel_size,
                "bricks_kept": kept,
                "bricks_total": total,
                "bytes": kept * BRICK ** 3 + m.indirection.nbytes,
                "bytes_all_bricks": total * BRICK ** 3,
            })
        return out

    def sample(self, points, mip: int = 0) -> np.ndarray:
        """Signed distance (metres, negative inside) at local-space points, trilinear over bricks.

        Inside the band: the stored distance. Beyond it: +-band (same sign). Outside the volume:
        a lower bound of the true distance, safe for sphere tracing.
        """
        m = self.mips[mip]
        p = np.asarray(points, np.float64).reshape(-1, 3)
        res = np.array(m.resolution)
        g = (p - self.origin) / m.voxel_size
        gc = np.clip(g, 0.0, res)
        b = np.minimum((gc // BRICK_CELLS).astype(np.int64), np.array(m.brick_grid) - 1)
        local = gc - b * BRICK_CELLS
        slot = m.indirection[b[:, 0], b[:, 1], b[:, 2]]
        out = np.where(slot == INVALID_INSIDE, -m.band, m.band)
        ok = np.flatnonzero(slot >= 0)
        if ok.size:
            i0 = np.minimum(local[ok].astype(np.int64), BRICK - 2)
            f = local[ok] - i0
            s = slot[ok]
            acc = np.zeros(ok.size)
            for dx in (0, 1):
                wx = f[:, 0] if dx else 1 - f[:, 0]
                for dy in (0, 1):
                    wy = f[:, 1] if dy else 1 - f[:, 1]
                    for dz in (0, 1):
                        wz = f[:, 2] if dz else 1 - f[:, 2]
                        code = m.bricks[s, i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz]
                        acc += wx * wy * wz * code
            out[ok] = (acc - 127.5) / 127.5 * m.band
        outside = np.any((g < 0) | (g > res), axis=1)
        if outside.any():
            q = self.origin + gc[outside] * m.voxel_size
            gap = np.linalg.norm(p[outside] - q, axis=1)
            to_box = np.linalg.norm(
                np.maximum(np.maximum(self.bounds_min - p[outside], p[outside] - self.bounds_max), 0), axis=1)
            out[outside] = np.maximum(to_box, out[outside] - gap)
        return out

    def sphere_trace(self, origins, directions, t_max: float, mip: int = 0,
                     max_steps: int = 256) -> np.ndarray:
        """Distance along each unit ray to the first surface (sdf <= hit epsilon), inf on a miss.

        The numpy reference for the GPU tracer: steps by the sampled distance (at least a tenth
        of a voxel, so grazing rays still advance); all rays advance together, one step per loop.
        """
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        h = self.mips[mip].voxel_size
        eps, min_step = 0.05 * h, 0.1 * h
        t = np.zeros(len(o))
        hit = np.full(len(o), np.inf)
        live = np.arange(len(o))
        for _ in range(max_steps):
            if not live.size:
                break
            dist = self.sample(o[live] + t[live, None] * d[live], mip)
            done = dist <= eps
            hit[live[done]] = t[live[done]]
            t[live] += np.maximum(dist, min_step)
            live = live[~done & (t[live] <= t_max)]
        return hit


def plan_resolution(extent, voxel_density: float, resolution_scale: float, max_resolution: int):
    """Voxel size and per-axis mip-0 resolution (whole bricks) for mesh bounds `extent`.

    Returns (voxel_size, resolution, requested_resolution). Raises MeshError on a bad request.
    """
    for name, val in (("voxel density", voxel_density), ("resolution scale", resolution_scale)):
        if not (math.isfinite(val) and val > 0):
            raise MeshError(f"{name} must be a positive number, got {val!r}")
    if not (2 * MARGIN_VOXELS + BRICK_CELLS <= max_resolution <= HARD_MAX_RESOLUTION):
        raise MeshError(f"max resolution must be within {2 * MARGIN_VOXELS + BRICK_CELLS}.."
                        f"{HARD_MAX_RESOLUTION} voxels per axis, got {max_resolution}")
    extent = np.maximum(np.asarray(extent, np.float64), 0.0)

    def cells(h):
        n = np.ceil(extent / h - 1e-9).astype(np.int64) + 2 * MARGIN_VOXELS
        return tuple(int(x) for x in -(-n // BRICK_CELLS) * BRICK_CELLS)

    h = 1.0 / (voxel_density * resolution_scale)
    longest = float(extent.max())
    # What was asked for, for the clamp message (float maths: a silly request must not overflow).
    asked = np.minimum(np.ceil(extent / h - 1e-9) + 2 * MARGIN_VOXELS, 1e15)
    requested = tuple(int(x) for x in -(-asked // BRICK_CELLS) * BRICK_CELLS)
    cap = max_resolution // BRICK_CELLS * BRICK_CELLS
    if max(requested) > cap or not (longest / h < 1e15):
        h = longest / (cap - 2 * MARGIN_VOXELS)
    return h, cells(h), requested


def bake_mesh_sdf(vertices, triangles, *, voxel_density: float = 20.0, resolution_scale: float = 1.0,
                  two_sided: bool = False, max_resolution: int = DEFAULT_MAX_RESOLUTION,
                  mip_count: int = MIP_COUNT, inside_fraction: float = INSIDE_FRACTION,
                  progress=None, orientation=None) -> MeshSDF:
    """Bake a sparse brick SDF with `mip_count` mips for one mesh.

    vertices: (V, 3) local-space positions in metres; triangles: (T, 3) vertex indices.
    voxel_density: voxels per metre at resolution_scale 1 (clamped to max_resolution per axis).
    inside_fraction: a sample is inside when more than this fraction of its rays hit back faces
      (the lecture uses 0.25; 0.5 matches the generalised winding number on open meshes).
    two_sided: the mesh has no inside (foliage, cards, open sheets): distance minus half a voxel
      everywhere, so a surface thinner than a voxel still blocks rays (over-occlude, never leak).
    progress: optional callable(fraction 0..1); raise BakeCancelled from it to stop.
    orientation: geometry.orient_triangles(vertices, triangles) when the caller has it already.
    Closed parts that are inside-out are flipped first (geometry.orient_triangles; the notes
    are in MeshSDF.orientation_notes). Raises MeshError (with the reason) on meshes that cannot
    be baked.
    """
    t0 = time.perf_counter()
    mesh = clean_mesh(vertices, triangles, orient=not two_sided, orientation=orientation)
    v, t = mesh.vertices, mesh.triangles
    used = v[np.unique(t)]
    bmin, bmax = used.min(axis=0), used.max(axis=0)
    h0, res0, requested = plan_resolution(bmax - bmin, voxel_density, resolution_scale, max_resolution)
    centre = 0.5 * (bmin + bmax)
    origin = centre - 0.5 * np.array(res0) * h0
    sdf = MeshSDF(origin=origin, bounds_min=bmin, bounds_max=bmax, two_sided=bool(two_sided),
                  requested_resolution=requested, dropped_degenerate=mesh.dropped_degenerate,
                  orientation_notes=mesh.orientation.notes() if mesh.orientation else [])
    # Rays in a frame centred on the mesh (float32 in Embree); distances are already relative
    # to the grid origin (TrianglePairs), so a mesh far from its own origin bakes as at home.
    signer = None if two_sided else SignTester(v, t, inside_fraction=inside_fraction, origin=centre)
    pairs = TrianglePairs(v, t, origin)
    tri = v[t] - origin
    holes = boundary_loops(v, t) if signer is not None else None
    sdf.timings["setup"] = time.perf_counter() - t0
    # Mip k has half the voxels of mip k-1, rounded up to whole bricks. Its samples coincide with
    # the even samples of mip k-1, whose closest triangles and signs seed it: coarse mips are cheap.
    weights = np.array([1.0] + [0.15] * (mip_count - 1))
    done = np.concatenate([[0], np.cumsum(weights)]) / weights.sum()
    res, prev = np.array(res0), None
    for k in range(mip_count):
        if k:
            res = -(-(res // 2 + res % 2) // BRICK_CELLS) * BRICK_CELLS
        sub = None
        if progress:
            lo, span = done[k], done[k + 1] - done[k]
            sub = lambda f, lo=lo, span=span: progress(lo + span * f)  # noqa: E731
        mip, prev = _bake_mip(pairs, tri, origin, h0 * 2 ** k, tuple(int(x) for x in res),
                              signer, holes, prev, sub, sdf.timings)
        sdf.mips.append(mip)
    # two-sided: the margin is the thin-wall rule's whatever the edges (packing.thin_voxels)
    sdf.edge_voxels = [None if two_sided else edge_rounding(sdf, v, t, k)
                       for k in range(len(sdf.mips))]
    if progress:
        progress(1.0)
    return sdf


EDGE_ANGLE = 20.0          # degrees between face normals that make an edge
EDGE_POINTS = 20000        # at most this many points on edges are sampled


def edge_rounding(sdf: MeshSDF, vertices, triangles, mip: int = 0):
    """How far, in voxels of `mip`, the trilinear field reads this mesh's convex edges off the
    surface: the mean of the field on the edges themselves (true distance 0), over points every
    half voxel along every convex edge sharper than EDGE_ANGLE (length-weighted), None when the
    mesh has none.
    Why: trilinear interpolation of a distance field rounds a convex edge inward, by up to 0.3
    voxel when the edge lies midway between samples and by 0 when it lies on them, so the shadow
    cones (light_lib.glsl) count a thick mesh's occluders that much thicker (packing.thin_voxels)
    to keep its silhouettes. A fixed worst-ish quarter voxel narrowed every opening whose edges the
    field holds exactly: bench/quality.py's window room (20 cm walls on 5 cm voxels, edges on
    samples) lost 7% of its sun patch (bench/bias_by_bounce.py, GI Off vs Cycles with no bounces,
    64 px: -6.1% with 0.25, +1.3% with 0), and every bounce after it."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    if not len(t):
        return None
    nf = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    ln = np.linalg.norm(nf, axis=1)
    good = ln > 1e-20
    nf = nf / np.maximum(ln, 1e-30)[:, None]
    # every directed edge (a, b) of a triangle, keyed undirected; manifold edges appear twice
    a = t.reshape(-1)
    b = t[:, [1, 2, 0]].reshape(-1)
    opp = t[:, [2, 0, 1]].reshape(-1)
    tri = np.repeat(np.arange(len(t)), 3)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (len(v) + 1) + hi
    order = np.argsort(key, kind="stable")
    k = key[order]
    first = np.flatnonzero((k[:-1] == k[1:]) & np.r_[True, k[1:-1] != k[:-2]]
                           & np.r_[k[2:] != k[1:-1], True])
    if not len(first):
        return None
    e0, e1 = order[first], order[first + 1]
    ta, tb = tri[e0], tri[e1]
    ok = good[ta] & good[tb]
    na, nb = nf[ta], nf[tb]
    # convex: triangle B's far vertex lies behind A's plane; sharp: the normals differ enough
    behind = np.einsum("ij,ij->i", na, v[opp[e1]] - v[a[e0]])
    sharp = np.einsum("ij,ij->i", na, nb) < np.cos(np.radians(EDGE_ANGLE))
    sel = ok & sharp & (behind < 0.0)
    if not sel.any():
        return None
    p0, p1 = v[a[e0][sel]], v[b[e0][sel]]
    h = sdf.mips[mip].voxel_size
    n = np.maximum(np.ceil(np.linalg.norm(p1 - p0, axis=1) / (0.5 * h)).astype(np.int64), 1)
    edge = np.repeat(np.arange(len(n)), n)
    start = np.repeat(np.cumsum(n) - n, n)
    f = (np.arange(int(n.sum())) - start + 0.5) / np.repeat(n, n)
    if len(f) > EDGE_POINTS:
        pick = np.random.default_rng(0).choice(len(f), EDGE_POINTS, replace=False)
        edge, f = edge[pick], f[pick]
    pts = p0[edge] + (p1[edge] - p0[edge]) * f[:, None]
    r = sdf.sample(pts, mip) / h
    return float(np.clip(r, 0.0, 0.5).mean())


def _bake_mip(pairs, tri, origin, h, res, signer, holes, prev, progress, timings):
    """One mip. signer: None for two-sided meshes. holes: boundary-loop spheres (centres, radii).
    prev: (closest, sign) dense grids of the finer mip, or None. Returns (mip, state)."""
    two_sided = signer is None
    band = BAND_VOXELS * h
    grid = Grid(origin, h, tuple(n + 1 for n in res))
    seeds, known_sign = None, None
    if prev is not None:
        closest_f, sign_f = (a[::2, ::2, ::2] for a in prev)
        common = tuple(slice(0, min(a, b)) for a, b in zip(closest_f.shape, grid.shape))
        cl = np.full(grid.shape, -1, np.int32)
        cl[common] = closest_f[common]
        known_sign = np.zeros(grid.shape, np.int8)
        known_sign[common] = sign_f[common]
        lin = np.flatnonzero(cl >= 0)
        seeds = (lin, cl.reshape(-1)[lin])
    clock = time.perf_counter()
    # Samples beyond the band are stored clamped, so the band is as far as distances are needed.
    udf, closest = narrow_band_distance(pairs, tri, grid, band, seeds=seeds,
                                        progress=(lambda f: progress(0.8 * f)) if progress else None)
    dist = udf - 0.5 * h if two_sided else udf
    clock = _tick(timings, "distance", clock)
    nb = tuple(n // BRICK_CELLS for n in res)
    near = _brick_min(np.abs(dist), nb) < band
    kept = np.argwhere(near)                     # (K, 3) brick coordinates, C order
    indirection = np.full(nb, INVALID_OUTSIDE, np.int32)
    indirection[near] = np.arange(len(kept), dtype=np.int32)

    off = np.stack(np.meshgrid(*(np.arange(BRICK),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    idx = (kept[:, None, :] * BRICK_CELLS + off[None]).reshape(-1, 3)
    lin = np.ravel_multi_index(idx.T, grid.shape)
    values = dist.reshape(-1)[lin]
    sign = np.zeros(grid.shape, np.int8)         # -1 inside, +1 outside, 0 not computed
    if signer is not None:
        # Rays for every 4th sample per axis (a coarser mip: every 2nd, which the finer mip
        # already answered), then flood signs across surface-free edges; rays for what is left.
        uniq, inv = np.unique(lin, return_inverse=True)
        if known_sign is not None:
            sign.reshape(-1)[uniq] = known_sign.reshape(-1)[uniq]
        stride = 4 if known_sign is None else 2
        coarse = uniq[np.all(np.stack(np.unravel_index(uniq, grid.shape)) % stride == 0, axis=0)]
        _cast(signer, grid, sign, coarse[sign.reshape(-1)[coarse] == 0])
        rest = flood_signs(sign, udf, h, uniq, blocked=_near_holes(grid, holes), steps=3 * stride)
        _cast(signer, grid, sign, rest)
        s = sign.reshape(-1)[uniq]
        values = values * s[inv]
        clock = _tick(timings, "sign", clock)
        empty = np.argwhere(~near)
        if len(empty):
            centres = origin + (empty + 0.5) * BRICK_CELLS * h
            deep = signer.inside(centres)
            indirection[tuple(empty[deep].T)] = INVALID_INSIDE
    if progress:
        progress(1.0)
    codes = np.clip(np.rint(np.clip(values, -band, band) / band * 127.5 + 127.5), 0, 255)
    bricks = codes.astype(np.uint8).reshape(len(kept), BRICK, BRICK, BRICK)
    _tick(timings, "bricks", clock)
    return SDFMip(voxel_size=h, resolution=res, indirection=indirection, bricks=bricks), (closest, sign)


def _tick(timings, stage, since):
    now = time.perf_counter()
    timings[stage] = timings.get(stage, 0.0) + now - since
    return now


def _near_holes(grid, holes):
    """Dense mask of samples within a hole's bounding sphere grown by two voxels (None: no holes)."""
    centres, radii = holes
    if not len(radii):
        return None
    mask = np.zeros(grid.shape, bool)
    reach = (radii + 2 * grid.h)[:, None]
    rel = centres - grid.origin
    for loop, _, lin, _ in box_samples(np.floor((rel - reach) / grid.h), np.ceil((rel + reach) / grid.h), grid.shape):
        d = np.linalg.norm(grid.coords(lin) - rel[loop], axis=1)
        mask.reshape(-1)[lin[d <= reach[loop, 0]]] = True
    return mask


def _cast(signer, grid, sign, lin):
    if lin.size:
        inside = signer.inside(grid.origin + grid.coords(lin).astype(np.float64))
        sign.reshape(-1)[lin] = np.where(inside, -1, 1)


def _brick_min(values: np.ndarray, nb) -> np.ndarray:
    """Minimum of each brick's 8^3 samples (7^3 own + shared border) over a sample grid."""
    m = values
    for axis, n in enumerate(nb):
        body = np.take(m, np.arange(n * BRICK_CELLS), axis=axis)
        shape = list(body.shape)
        shape[axis:axis + 1] = [n, BRICK_CELLS]
        blocks = body.reshape(shape).min(axis=axis + 1)
        border = np.take(m, np.arange(1, n + 1) * BRICK_CELLS, axis=axis)
        m = np.minimum(blocks, border)
    return m
