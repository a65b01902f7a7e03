"""The object grid: which instances a scene distance sample must visit (numpy only, no bpy, no gpu).

Why: sdf_scene (glsl/sdf_lib.glsl) used to test every instance at every sample, so every shadow
cone, ray step and visibility test cost O(objects) (bench/object_scaling.py, GI Off, 128 px:
a still viewport frame of 1,000 icospheres took 70x that of 10, all of it the direct light). Lumen culls objects to a grid before it traces mesh SDFs; so
does this: a uniform grid of cubic cells over the instances' world bounds lists, per cell, the
instances that come within the margin M of the cell, and sdf_scene visits only that list.

Per instance the world bounds are its bounding sphere (object row texel 8) and the world AABB of
its mesh bounds grown by half a voxel (sdf_visit never lets a value fall below their distance,
packing.py; the SDF volume, band padding included, listed a 0.25 m icosphere in every cell
within 1.5 m of it); its distance to a cell box is the larger of the two gaps, and with a
uniform scale its value anywhere in the cell is at least that. A cell stores
  - its list, nearest first, each entry with its distance to the cell: sdf_scene stops at the
    first entry at least as far as the best value so far (every later one is farther still);
  - B, a lower bound of every unlisted instance's distance to the cell: the nearest unlisted one
    within the reach R = REACH_MARGINS x M, else R (1e30 when every instance is listed). B >= M.
sdf_scene returns min(listed distances, sqrt(|p - q|^2 + B^2)), q = p clamped into the grid box
(the cell of q is used for a p outside the grid: every instance lies inside the box, so from p it
is at least that far; for p inside, q = p). Where the full loop's value is below M both agree;
sdf_scene_reach (the global SDF's build) runs the full loop where the bound would cut the value
below its reach.
A cell lists at most CELL_CAP instances (fewer where all the lists would pass ENTRY_BUDGET
entries). A crowded cell (a dense scatter: thousands of pebbles) keeps its nearest `cap` and
lowers B to the first one it drops, so its values are exact below that B, a lower bound above
it. Kept only where B is at least EXACT_VOXELS voxels of every listed object (the thin-wall,
shell and band rules compare a value with at most 4 voxels of the nearest object), else the cell
stores count -1 and sdf_scene runs the full loop there. Why: 1,000 4-cm pebbles on 1.35 x 1.35 m
list up to 388 instances in a cell; with a cap of 64 the full loop over every object at each
sample there made one F12 GI iteration at 16 px take 113-119 s, with no cell over the cap 18 s
(the sample walks its list nearest first and stops early, so a long list costs what is near).

Sizes: cubic cells, at most GRID_MAX = 32 per axis (32^3 = 32768 cells, 0.5 MiB of RGBA32F):
the grid is built whenever the object table is uploaded (an object moved), so its build must
stay tens of milliseconds (about 60 ms of CPU for 1,000 instances in 32 x 32 x 1 cells; after
a move only the cells within reach of the moved rows are measured again, the rest of the last
build kept: build_object_grid's `previous`); 64^3 would be 8x the cells and pairs for lists
that are only shorter in scenes denser than one object per cell. M = one cell edge (at least 4 voxels of the coarsest object, so
a clamped value never reads as "near a surface" to the thin-wall and shell rules).

Texture layout (`grid`: float32 [rows, GRID_WIDTH, 4], uploaded as one RGBA32F 2D texture,
texel i at (i % GRID_WIDTH, i // GRID_WIDTH)):
  texel 0: (grid origin xyz, cell edge)
  texel 1: (cells per axis xyz, first list texel)
  texel 2: (M, voxel for samples with no listed instance, list entries, the cap used)
  texel 3 + x + nx (y + ny z): cell (first list entry, count or -1, B, 0)
  list: (instance index, its distance to the cell) pairs, 2 per texel (entry e in texel
        first_list + e // 2, channels 2 (e % 2) and 2 (e % 2) + 1).
Integers are exact in float32 below 2^24 (checked).
"""
from __future__ import annotations

import numpy as np

from .global_sdf_ref import merge_boxes

GRID_MAX = 32
GRID_WIDTH = 1024
CELL_CAP = 1024           # entries a cell lists at most (fewer where the lists pass ENTRY_BUDGET)
ENTRY_BUDGET = 1 << 20    # list entries in all (2 a texel: 8 MiB of RGBA32F)
EXACT_VOXELS = 4.0        # a truncated cell's bound: at least this many voxels of its objects
REACH_MARGINS = 4.0
MAX_REGIONS = 16          # boxes a changed region is given as at most (then their bounding box)
HEADER_TEXELS = 3
FAR = 1e30
PAIR_CHUNK = 1 << 22      # (instance, cell) candidate pairs per numpy batch (memory bound)
FINE_CELLS = 1 << 17      # cells of the fine level at most (2 MiB of RGBA32F)


def instance_bounds(objects: np.ndarray):
    """World bounds of each object-table row: (valid, sphere centre, radius, aabb lo, aabb hi,
    world voxel). Parked rows (packing.PARKED) are not valid: no sample ever visits them."""
    objs = np.asarray(objects, np.float64)
    sphere = objs[:, 8]
    valid = np.isfinite(objs).all(axis=(1, 2)) & (np.abs(sphere[:, :3]).max(axis=1) < 1e29)
    w2l = objs[:, 0:4, :].copy()
    w2l[~valid] = np.eye(4)
    l2w = np.linalg.inv(w2l)
    half = 0.5 * objs[:, 4, 3:4]                  # the mesh bounds grown by half a voxel, as
    lo_l, hi_l = objs[:, 6, :3] - half, objs[:, 7, :3] + half      # texel 8's sphere (sdf_visit)
    c = np.einsum("nij,nj->ni", l2w[:, :3, :3], (lo_l + hi_l) / 2) + l2w[:, :3, 3]
    e = np.einsum("nij,nj->ni", np.abs(l2w[:, :3, :3]), np.abs(hi_l - lo_l) / 2)
    voxel = objs[:, 4, 3] * objs[:, 7, 3]
    return valid, sphere[:, :3], sphere[:, 3], c - e, c + e, voxel


def _pairs(lo_idx, hi_idx):
    """Every (instance, cell xyz) with cell in the instance's inclusive index box, vectorised."""
    span = hi_idx - lo_idx + 1
    total = span.prod(axis=1)
    inst = np.repeat(np.arange(len(span)), total)
    k = np.arange(total.sum()) - np.repeat(np.cumsum(total) - total, total)
    sx, sy = span[inst, 0], span[inst, 1]
    xyz = np.stack([k % sx, (k // sx) % sy, k // (sx * sy)], axis=1) + lo_idx[inst]
    return inst, xyz


def _cell_distance(inst, xyz, lo, cell, centre, radius, alo, ahi):
    """Lower bound of instance `inst`'s value anywhere in cell `xyz` (edge `cell` from `lo`): the
    larger of the gaps to its AABB and to its sphere."""
    clo = lo + xyz * cell
    chi = clo + cell
    g = np.maximum(clo - ahi[inst], alo[inst] - chi)
    np.maximum(g, 0.0, out=g)
    c = centre[inst]
    s = np.maximum(clo - c, c - chi)
    np.maximum(s, 0.0, out=s)
    # row-wise lengths by einsum: no squared temporaries (np.linalg.norm made two per call)
    gap = np.sqrt(np.einsum("ij,ij->i", g, g))
    sph = np.sqrt(np.einsum("ij,ij->i", s, s)) - radius[inst]
    return np.maximum(gap, sph, out=gap)


def _entry_cap(counts: np.ndarray, cap: int, budget: int) -> int:
    """The largest per-cell cap <= cap whose lists hold at most `budget` entries in all."""
    lo, hi = 1, max(int(cap), 1)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if int(np.minimum(counts, mid).sum()) <= budget else (lo, mid - 1)
    return lo


class GridLists:
    """What an incremental build starts from: the last build's layout (`key`) and every fine
    cell's listed pairs (before the per-cell cap; sorted by cell, nearest first) and bound B."""

    def __init__(self, key, cells, insts, dists, bound):
        self.key, self.cells, self.insts, self.dists, self.bound = key, cells, insts, dists, bound
        self.cap = None          # the cap its texels were packed with (build_object_grid)


def _layout(objects: np.ndarray, grid_max: int, fine_cells: int) -> dict:
    """The grid's box, cells and margin for the object table (every valid instance's bounds)."""
    bounds = instance_bounds(objects)
    valid, _, _, alo, ahi, voxel = bounds
    idx = np.flatnonzero(valid)
    if len(idx):
        lo, hi = alo[idx].min(axis=0), ahi[idx].max(axis=0)
        cell = max(float((hi - lo).max()) / grid_max, 1e-4)
        dims = np.clip(np.ceil((hi - lo) / cell - 1e-9).astype(np.int64), 1, grid_max)
        margin = max(cell, 4.0 * float(voxel[idx].max()))
        fallback_voxel = float(voxel[idx].min())
    else:
        lo, hi, cell, dims, margin, fallback_voxel = (np.zeros(3), np.zeros(3), 1.0,
                                                       np.ones(3, np.int64), 1.0, 1.0)
    split = 2 if int(dims.prod()) * 8 <= fine_cells else 1
    fcell = cell / split
    fdims = np.clip(np.ceil((hi - lo) / fcell - 1e-9).astype(np.int64), 1, dims * split)
    key = (tuple(lo), tuple(hi), cell, tuple(int(v) for v in dims), margin, len(idx),
           len(objects), split)
    return dict(bounds=bounds, idx=idx, lo=lo, hi=hi, cell=cell, dims=dims, margin=margin,
                fallback_voxel=fallback_voxel, reach=REACH_MARGINS * margin, split=split,
                fcell=fcell, fdims=fdims, key=key)


def _coarse_box(lay: dict, boxes) -> tuple:
    """The coarse cells (inclusive index box) whose lists world boxes [(lo, hi)] of changed
    instances may change: an instance is paired with the cells its AABB grown by the reach
    covers (as _fine_lists pairs them)."""
    lo, cell, dims, reach = lay["lo"], lay["cell"], lay["dims"], lay["reach"]
    blo = np.min([np.asarray(b[0], np.float64) for b in boxes], axis=0)
    bhi = np.max([np.asarray(b[1], np.float64) for b in boxes], axis=0)
    a = np.clip(np.floor((blo - reach - lo) / cell), 0, dims - 1).astype(np.int64)
    b = np.clip(np.floor((bhi + reach - lo) / cell), 0, dims - 1).astype(np.int64)
    return a, b


def _fine_lists(lay: dict, box=None) -> tuple:
    """(fine cell, instance, distance) of every listed pair and the fine cells' bounds B.
    box (coarse index lo, hi, inclusive): only the coarse cells in it are computed (their fine
    children's pairs and bounds; the other cells' bounds are not)."""
    valid, centre, radius, alo, ahi, voxel = lay["bounds"]
    idx, lo, cell, dims = lay["idx"], lay["lo"], lay["cell"], lay["dims"]
    margin, reach, split = lay["margin"], lay["reach"], lay["split"]
    fcell, fdims = lay["fcell"], lay["fdims"]
    ncells = int(dims.prod())
    bound = np.full(ncells, FAR)
    in_reach = np.zeros(ncells, np.int64)
    xyz_l, insts_l = [], []
    # candidate cells of each instance: its AABB grown by the reach, clipped to the grid
    cl = np.clip(np.floor((alo[idx] - reach - lo) / cell), 0, dims - 1).astype(np.int64)
    ch = np.clip(np.floor((ahi[idx] + reach - lo) / cell), 0, dims - 1).astype(np.int64)
    sub = idx
    if box is not None:                # only the pairs with the box's cells
        cl, ch = np.maximum(cl, box[0]), np.minimum(ch, box[1])
        some = (cl <= ch).all(axis=1)
        sub, cl, ch = idx[some], cl[some], ch[some]
    per = (ch - cl + 1).prod(axis=1)
    ends = np.cumsum(per)
    starts = np.searchsorted(ends, np.arange(0, int(ends[-1]) if len(ends) else 0, PAIR_CHUNK),
                             side="right")
    bounds_at = list(starts) + [len(sub)]
    for a, b in zip(bounds_at[:-1], bounds_at[1:]):          # batches of instances, not one each
        if b <= a:
            continue
        k, xyz = _pairs(cl[a:b], ch[a:b])
        inst = sub[a:b][k]
        d = _cell_distance(inst, xyz, lo, cell, centre, radius, alo, ahi)
        c = xyz[:, 0] + dims[0] * (xyz[:, 1] + dims[1] * xyz[:, 2])
        near = d < reach
        in_reach += np.bincount(c[near], minlength=ncells)
        far = near & (d >= margin)
        np.minimum.at(bound, c[far], d[far])                    # each cell's nearest unlisted
        listed = d < margin
        xyz_l.append(xyz[listed])
        insts_l.append(inst[listed])
    xyz = np.concatenate(xyz_l) if xyz_l else np.zeros((0, 3), np.int64)
    insts = np.concatenate(insts_l) if insts_l else np.zeros(0, np.int64)
    # instances beyond the reach of a cell exist where not all of them were within it
    bound = np.where(in_reach < len(idx), np.minimum(bound, reach), bound)
    # the fine level: each coarse cell's listed instances against its 2^3 (or 1) children
    child = np.stack(np.meshgrid(*[np.arange(split)] * 3, indexing="ij"), -1).reshape(-1, 3)
    fxyz = (xyz[:, None, :] * split + child[None]).reshape(-1, 3)
    finst = np.repeat(insts, len(child))
    inside = (fxyz < fdims).all(axis=1)
    fxyz, finst = fxyz[inside], finst[inside]
    d = _cell_distance(finst, fxyz, lo, fcell, centre, radius, alo, ahi)
    c = fxyz[:, 0] + fdims[0] * (fxyz[:, 1] + fdims[1] * fxyz[:, 2])
    g = np.stack(np.meshgrid(*[np.arange(n) for n in fdims], indexing="ij"), -1)
    g = g.transpose(2, 1, 0, 3).reshape(-1, 3) // split       # each fine cell's parent, x fastest
    bound = bound[g[:, 0] + dims[0] * (g[:, 1] + dims[1] * g[:, 2])]
    unl = d >= margin
    np.minimum.at(bound, c[unl], d[unl])
    return c[~unl], finst[~unl], d[~unl], bound


def _in_box(cells: np.ndarray, fdims, split: int, box) -> np.ndarray:
    """Whether fine cells (flat indices) lie in coarse index box `box` (inclusive)."""
    xyz = np.stack([cells % fdims[0], (cells // fdims[0]) % fdims[1],
                    cells // (fdims[0] * fdims[1])], axis=1) // split
    return ((xyz >= box[0]) & (xyz <= box[1])).all(axis=1)


def build_object_grid(objects: np.ndarray, grid_max: int = GRID_MAX, cap: int = CELL_CAP,
                      width: int = GRID_WIDTH, fine_cells: int = FINE_CELLS,
                      entry_budget: int = ENTRY_BUDGET, previous: GridLists | None = None,
                      boxes=None) -> tuple:
    """The grid texture's texels for the object table `objects` [n, OBJECT_TEXELS, 4];
    returns (texels float32 [rows, width, 4], info dict: dims, cell, margin, entries, overflow
    (cells running the full loop), truncated (crowded cells keeping their nearest), the cap used,
    mean / max count, `lists` (GridLists, for the next call's `previous`), `incremental`,
    `region`: where sdf_scene's values may differ from `previous`'s build, [(lo, hi)] or []
    (nothing changed), None when it is not known (a full build): everywhere).

    Two levels: a coarse grid (at most grid_max cells per axis) finds each cell's candidates
    within the reach and its bound B; where that grid has at most fine_cells / 8 cells (a flat
    or small scene), each cell is split in 2 x 2 x 2 and only the coarse cell's listed instances
    are measured against its children (an instance within M of a child is within M of its
    parent; an unlisted one is at least the parent's B from it, or is a parent-listed one whose
    distance to the child is measured): the lists of a 1,000-icosphere field get shorter (15.6
    -> 11.9 mean) and its sample's early stop nearer, without a reach pass over 8x the cells.

    `previous` (the last build's info["lists"]) and `boxes` (the world AABBs, old and new, of
    the rows that changed since: SceneResources' change log) make it incremental: when the
    grid's box, cells and margin stay the same, only the coarse cells within the reach of those
    boxes are measured again (each box's reach apart, overlapping ones merged), and the rest
    keep their lists and bounds. The texels are the same
    as a full build's (tests/core/test_object_grid_update.py). Why: one sphere dragged among
    1,000 rebuilt the whole grid every redraw (58 ms of CPU)."""
    lay = _layout(objects, grid_max, fine_cells)
    split, fdims = lay["split"], lay["fdims"]
    incremental = previous is not None and boxes is not None and previous.key == lay["key"]
    region = None
    if incremental and not len(boxes):
        cells, insts, dists, bound = previous.cells, previous.insts, previous.dists, previous.bound
        region = []
    elif incremental:
        # each changed row's reach apart (overlapping ones merged): rows moved far apart are
        # measured where they are, not over the whole box between them
        groups = [_coarse_box(lay, [b]) for b in boxes]
        spans = _merge_spans(groups)
        if len(spans) > MAX_REGIONS:
            spans = [_coarse_box(lay, boxes)]
        if 2 * sum(int(np.prod(b - a + 1)) for a, b in spans) > int(lay["dims"].prod()):
            # most of the grid: one pass over it (measured per box it took longer than a build)
            spans = [(np.zeros(3, np.int64), lay["dims"] - 1)]
        fine = np.arange(len(previous.bound))
        redone = np.zeros(len(fine), bool)
        bound_new = previous.bound.copy()
        parts = []
        for a, b in spans:
            c, i, d, bnd = _fine_lists(lay, (a, b))
            mine = _in_box(fine, fdims, split, (a, b))                  # per fine cell
            bound_new[mine] = bnd[mine]
            redone |= mine
            parts.append((c, i, d))
        cells, insts, dists = _sorted(*(np.concatenate(x) for x in zip(*parts)))
        keep = ~redone[previous.cells]
        region = _changed_region(lay, redone, previous, keep, cells, insts, dists, bound_new,
                                 groups)
        # the kept pairs stay sorted; the new ones (cells disjoint from theirs) go in between
        at = np.searchsorted(previous.cells[keep], cells)
        cells = np.insert(previous.cells[keep], at, cells)
        insts = np.insert(previous.insts[keep], at, insts)
        dists = np.insert(previous.dists[keep], at, dists)
        bound = np.where(redone, bound_new, previous.bound)
    else:
        cells, insts, dists, bound = _fine_lists(lay)
        cells, insts, dists = _sorted(cells, insts, dists)
    lists = GridLists(lay["key"], cells, insts, dists, bound)
    texels, info = _pack(lay, cells, insts, dists, bound, len(objects), cap,
                         width, entry_budget)
    lists.cap = info["cap"]
    if incremental and info["cap"] != getattr(previous, "cap", None):
        region = None          # the entry budget's cap moved: crowded cells anywhere changed
    info.update(lists=lists, incremental=bool(incremental), region=region)
    return texels, info


def _cell_hashes(cells, insts, dists, n: int):
    """Per fine cell (n of them): its entries' count and an order-free uint64 hash of its
    (instance, distance) pairs (sums wrap)."""
    h = (insts.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) \
        ^ (np.ascontiguousarray(dists, np.float64).view(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F))
    sums = np.zeros(n, np.uint64)
    np.add.at(sums, cells, h)
    return np.bincount(cells, minlength=n), sums


def _changed_region(lay, redone, previous, keep, cells, insts, dists, bound, groups) -> list:
    """World boxes (lo, hi) around the re-measured fine cells whose list or bound B differs from
    the previous build's ([] when none does), unbounded where they reach the grid's faces (a
    sample outside the grid reads the cell it clamps into). Outside them every cell is the same,
    so sdf_scene returns what it did: the moved object's reach is 4 margins, but where others
    are nearer it sets no cell's B (1,000 spheres: most of that reach keeps its cells). One box
    per group (each changed row's coarse index box: a cell changes only within reach of one),
    overlapping ones merged, so an object moved far, or several moved apart, do not make one
    box spanning what lies between them (at most MAX_REGIONS, else their bounding box)."""
    n = len(redone)
    old = ~keep
    c0, h0 = _cell_hashes(previous.cells[old], previous.insts[old], previous.dists[old], n)
    c1, h1 = _cell_hashes(cells, insts, dists, n)
    changed = redone & ((c0 != c1) | (h0 != h1) | (previous.bound != bound))
    idx = np.flatnonzero(changed)
    if not len(idx):
        return []
    fdims, fcell, lo, split = lay["fdims"], lay["fcell"], lay["lo"], lay["split"]
    xyz = np.stack([idx % fdims[0], (idx // fdims[0]) % fdims[1],
                    idx // (fdims[0] * fdims[1])], axis=1)
    parent = xyz // split
    spans = []
    for a, b in groups:                          # a few changed rows, not cells
        mine = np.all((parent >= a) & (parent <= b), axis=1)
        if mine.any():
            spans.append([xyz[mine].min(axis=0), xyz[mine].max(axis=0)])
    spans = _merge_spans(spans) if len(spans) <= MAX_REGIONS else \
        [[xyz.min(axis=0), xyz.max(axis=0)]]
    out = []
    for a, b in spans:
        wlo = np.where(a <= 0, -FAR, lo + a * fcell)
        whi = np.where(b >= fdims - 1, FAR, lo + (b + 1) * fcell)
        out.append((wlo.astype(np.float64), whi.astype(np.float64)))
    return out


def _merge_spans(spans: list) -> list:
    """Inclusive index boxes [lo, hi] with every overlapping or touching pair merged into one
    (global_sdf_ref.merge_boxes, whose ends are exclusive)."""
    merged = merge_boxes([(a, np.asarray(b) + 1) for a, b in spans])
    return [(np.asarray(a, np.int64), np.asarray(b, np.int64) - 1) for a, b in merged]


def _sorted(cells, insts, dists) -> tuple:
    """The pairs by cell, nearest first (ties by instance: the same order every build)."""
    order = np.lexsort((insts, dists, cells))
    return cells[order], insts[order], dists[order]


def _pack(lay, cells, insts, dists, bound, n_objects, cap, width,
          entry_budget) -> tuple:
    """The texels of the fine cells' listed pairs (_sorted) and bounds (the cap and truncation
    applied)."""
    voxel = lay["bounds"][5]
    lo, margin, fallback_voxel = lay["lo"], lay["margin"], lay["fallback_voxel"]
    cell, dims = lay["fcell"], lay["fdims"]
    ncells = int(dims.prod())
    counts = np.bincount(cells, minlength=ncells)
    cap = _entry_cap(counts, cap, entry_budget)
    # a crowded cell keeps its nearest `cap` and bounds the rest by the first one dropped, where
    # that bound leaves every rule that reads a value in voxels of a listed object exact
    rank = np.arange(len(cells)) - (np.cumsum(counts) - counts)[cells]
    dropped = rank == cap
    cut = np.full(ncells, FAR)
    cut[cells[dropped]] = dists[dropped]
    kept_voxel = np.zeros(ncells)
    np.maximum.at(kept_voxel, cells[rank < cap], voxel[insts[rank < cap]])
    crowded = counts > cap
    over = crowded & (cut < EXACT_VOXELS * kept_voxel)
    truncated = crowded & ~over
    bound = np.where(truncated, np.minimum(bound, cut), bound)
    keep = (rank < cap) & ~over[cells]
    cells, insts, dists = cells[keep], insts[keep], dists[keep]
    kept = np.bincount(cells, minlength=ncells)
    first = np.cumsum(kept) - kept
    entries = len(insts)
    list_texels = -(-entries // 2)
    total = HEADER_TEXELS + ncells + list_texels
    if total * 4 >= 1 << 24 or n_objects >= 1 << 24:
        raise ValueError(f"object grid of {total} texels: beyond exact float integers")
    rows = -(-total // width)
    tex = np.zeros((rows * width, 4), np.float32)
    first_list = HEADER_TEXELS + ncells
    tex[0] = (*lo, cell)
    tex[1] = (*dims, first_list)
    tex[2] = (margin, fallback_voxel, entries, cap)
    body = tex[HEADER_TEXELS:HEADER_TEXELS + ncells]
    body[:, 0] = first
    body[:, 1] = np.where(over, -1, kept)
    body[:, 2] = bound
    flat = np.full((list_texels * 2, 2), -1.0, np.float32)
    flat[:entries, 0] = insts
    # rounded down, so that float32 never lets the loop stop before an instance that matters
    flat[:entries, 1] = np.maximum(dists * (1.0 - 1e-6) - 1e-6, 0.0)
    tex[first_list:first_list + list_texels] = flat.reshape(-1, 4)
    info = dict(dims=tuple(int(v) for v in dims), cell=cell, margin=margin, entries=entries,
                overflow=int(over.sum()), truncated=int(truncated.sum()), cap=int(cap),
                mean_count=float(kept.mean()) if ncells else 0.0,
                max_count=int(counts.max()) if ncells else 0)
    return tex.reshape(rows, width, 4), info


def changed_boxes(old: np.ndarray, new: np.ndarray, max_rows: int):
    """The world boxes (lo, hi) the rows that differ between object tables `old` and `new`
    change: each changed row's old and new AABB (instance_bounds: mesh bounds grown by half a
    voxel; one box around both where they touch, a row dragged a little), or None (everything)
    when the tables differ in size or more than max_rows rows changed."""
    if old is None or np.shape(old) != np.shape(new):
        return None
    old, new = np.asarray(old, np.float32), np.asarray(new, np.float32)
    rows = np.flatnonzero((old != new).reshape(len(new), -1).any(axis=1))
    if len(rows) > max_rows:
        return None
    va, _, _, alo, ahi, _ = instance_bounds(old[rows])
    vb, _, _, blo, bhi, _ = instance_bounds(new[rows])
    touch = va & vb & np.all((alo <= bhi) & (blo <= ahi), axis=1)
    boxes = [(np.minimum(alo[i], blo[i]), np.maximum(ahi[i], bhi[i]))
             for i in np.flatnonzero(touch)]
    boxes += [(alo[i], ahi[i]) for i in np.flatnonzero(va & ~touch)]
    boxes += [(blo[i], bhi[i]) for i in np.flatnonzero(vb & ~touch)]
    return boxes


def sample_bound(texels: np.ndarray, points: np.ndarray) -> np.ndarray:
    """sdf_scene_grid's `bound` at world points (float [P, 3]): the lower bound of every
    instance its cell does not list (1e30 where the cell lists all or runs the full loop). The
    grid's values are exact wherever the full loop's is below it (numpy twin, for tests)."""
    tex = np.asarray(texels, np.float64).reshape(-1, 4)
    lo, cell = tex[0, :3], tex[0, 3]
    dims = np.floor(tex[1, :3] + 0.5).astype(np.int64)
    p = np.asarray(points, np.float64)
    q = np.clip(p, lo, lo + dims * cell)
    c = np.clip(np.floor((q - lo) / cell).astype(np.int64), 0, dims - 1)
    t = tex[HEADER_TEXELS + c[:, 0] + dims[0] * (c[:, 1] + dims[1] * c[:, 2])]
    listed = np.round(t[:, 1]) >= 0
    return np.where(listed & (t[:, 2] < 1e29),
                    np.hypot(np.linalg.norm(p - q, axis=1), t[:, 2]), FAR)
