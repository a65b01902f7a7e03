"""Which tiles of the surface cache's lighting atlas are relit this frame (numpy only, no gpu).

The lecture's surface-cache update budget (UE: a fixed number of card captures and a fraction of
the lighting updated per frame): a viewport frame relights only `budget` tiles of 8x8 radiosity
probes (32x32 lighting texels), so its cost no longer grows with the scene's total card area. A
tile is chosen by priority:
  1. never lit since the lighting was reset (the scene changed; the viewport's tiles keep
     their old light until then: SurfaceCache.refresh_lighting): these come first;
  2. then by age (frames since the tile's last update) times 2 when a card of the tile belongs to
     an instance inside the view frustum, divided by 1 + distance / 10 m: visible and near tiles
     refresh more often, every tile is refreshed eventually (its age grows without bound).
Each tile keeps its own update count, so its temporal blend (1 / (n + 1), at least 1 / history)
converges as if every tile were updated every frame. Once the viewport has been still for two
redraws it knows which tiles the image reads (`seen`, below, as F12 does): those weigh
SEEN_WEIGHT more, and "refining n/N" waits only for them (the others lit once): an open yard's
ground that no ray reads no longer holds the viewport at "refining" for hundreds of redraws.
An F12 render relights every tile in its first iteration, then per iteration every tile the view
reads (`seen`: some visible tile's rays reach it; a room's walls see each other, an open ground's
tiles far from the objects on it are read by no ray) and a fraction of the others
(GISettings.render_sc_fraction) by `render_priority`: the same age-based score, but from each
tile's own world box and normal (`tile_geometry`: a 12 m ground's far corner, or its underside
that nothing sees, is one instance with the near ground, but not one tile).

The tile -> card rows table is built once per lighting atlas (a CSR of unique rows per tile);
per frame the work is O(card rows + tiles) in numpy.
"""
from __future__ import annotations

import numpy as np

from .card_packing import AXES, PLANE, PROBE_BLOCK

TILE_PROBES = 8                          # probes per tile side (surface_cache_probe_lib.glsl)
TILE = TILE_PROBES * PROBE_BLOCK         # lighting texels per tile side
NEAR_METRES = 10.0                       # distance at which a tile's priority halves
VISIBLE_WEIGHT = 2.0
RENDER_VISIBLE_WEIGHT = 4.0              # F12: a tile in the frustum facing the camera
SEEN_SHARE = 0.02                        # F12: relit every iteration when a visible tile's
                                         # cosine-weighted hemisphere sees this much of it
SEEN_WEIGHT = 20.0                       # the still viewport: a tile the image reads (`seen`)
                                         # (the budget goes to them: the others are read by
                                         # no ray, F12 relights 0.2 of them per iteration)


class PageSchedule:
    """Per-tile update counts and ages of one lighting atlas, and the choice of each frame's tiles."""

    def __init__(self, texel_card: np.ndarray, card_instance: np.ndarray):
        """texel_card: float [H, W] card row per lighting texel (-1: none); card_instance: the
        object-table row of each card row."""
        h, w = texel_card.shape
        self.grid = (-(-w // TILE), -(-h // TILE))                     # tiles (x, y)
        tw, th = self.grid
        padded = np.full((th * TILE, tw * TILE), -1, np.int64)
        padded[:h, :w] = np.rint(texel_card).astype(np.int64)
        per_tile = padded.reshape(th, TILE, tw, TILE).transpose(0, 2, 1, 3).reshape(th * tw, -1)
        tile_id, col = np.nonzero(per_tile >= 0)
        stride = int(padded.max()) + 2                                   # > every card row
        pairs = np.unique(tile_id * stride + per_tile[tile_id, col])     # (tile, row), sorted
        pair_tile, pair_row = pairs // stride, pairs % stride
        used, first = np.unique(pair_tile, return_index=True)           # tiles holding a card
        self.tiles = np.stack([used % tw, used // tw], axis=1).astype(np.int32)
        self.row_start = first                                           # CSR into pair_row
        self.pair_row = pair_row                                         # card row per pair
        self.row_instance = np.asarray(card_instance, np.int64)[pair_row]
        self.count = np.zeros(len(self.tiles), np.int64)
        self.last = np.full(len(self.tiles), -1, np.int64)
        self.tile_frame = np.zeros((th, tw), np.float32)                # frame of each tile's rays
        self.geometry = None            # (centre [T, 3], radius [T], normal [T, 3]): tile_geometry
        self.area = None                # [T] world m^2 of each tile's texels: tile_area
        self._seen = None               # (camera key, seen()): once per F12 camera

    def set_geometry(self, geometry, area=None):
        """The tiles' world (centre, radius, normal) and m^2 (tile_geometry, tile_area)."""
        self.geometry, self.area, self._seen = geometry, area, None

    def __len__(self) -> int:
        return len(self.tiles)

    def reset(self):
        self.count[:] = 0
        self.last[:] = -1

    def priority(self, frame: int, instance_spheres=None, view_proj=None, cam_pos=None,
                 seen=None) -> np.ndarray:
        """Score per tile (higher first); never-lit tiles score above every lit one. seen: bool
        per tile (self.seen; None: not known yet): a tile the image reads weighs SEEN_WEIGHT and
        replaces the frustum and distance weights (which would update the far seen tiles half as
        often as the near ones, and "refining" waits for the slowest)."""
        age = (frame - self.last).astype(np.float64)
        weight = np.ones(len(self.tiles))
        if seen is not None:
            weight *= np.where(seen, SEEN_WEIGHT, 1.0)
        elif instance_spheres is not None and len(self.row_instance):
            spheres = np.asarray(instance_spheres, np.float64)[self.row_instance]
            if view_proj is not None:
                vis = _in_frustum(spheres, np.asarray(view_proj, np.float64)).astype(np.float64)
                weight *= np.where(np.maximum.reduceat(vis, self.row_start) > 0, VISIBLE_WEIGHT, 1.0)
            if cam_pos is not None:
                d = np.linalg.norm(spheres[:, :3] - np.asarray(cam_pos, np.float64)[:3], axis=1)
                d = np.maximum(d - spheres[:, 3], 0.0)
                weight /= 1.0 + np.minimum.reduceat(d, self.row_start) / NEAR_METRES
        score = age * weight
        never = self.count == 0
        score[never] = score.max(initial=0.0) + 1.0 + age[never]
        return score

    def render_priority(self, frame: int, view_proj=None, cam_pos=None) -> np.ndarray:
        """F12's score per tile (higher first; never-lit tiles above every lit one): age times
        RENDER_VISIBLE_WEIGHT when the tile's sphere is in the frustum and its cards face the
        camera, divided by 1 + distance / NEAR_METRES, from the tile's own geometry."""
        age = (frame - self.last).astype(np.float64)
        weight = np.ones(len(self.tiles))
        if self.geometry is not None and cam_pos is not None:
            centre, radius, normal = self.geometry
            to_cam = np.asarray(cam_pos, np.float64)[:3] - centre
            dist = np.linalg.norm(to_cam, axis=1)
            vis = self.facing(cam_pos)
            if view_proj is not None:
                spheres = np.concatenate([centre, radius[:, None]], axis=1)
                vis = vis & _in_frustum(spheres, np.asarray(view_proj, np.float64))
            weight = np.where(vis, RENDER_VISIBLE_WEIGHT, 1.0) \
                / (1.0 + np.maximum(dist - radius, 0.0) / NEAR_METRES)
        score = age * weight
        never = self.count == 0          # first, the visible and near among them first
        score[never] = score.max(initial=0.0) + 1.0 + weight[never]
        return score

    def choose_render(self, fraction: float, frame: int, cap: int = 0, **where) -> np.ndarray:
        """F12: tile indices of this iteration, every tile when `fraction` >= 1, else every
        never-lit tile (an unlit tile would read as black in the gather), every tile the view
        reads (`seen`; without tile areas: every tile facing the camera) and of the others the
        ceil(fraction * others) of highest render_priority. cap > 0 (the image's budget,
        GISettings.render_sc_texels): when the never-lit and seen tiles alone are more, every
        never-lit one and of the seen the highest render_priority (age x visibility /
        distance) up to `cap` in all, none of the others (else the share of the others within
        `cap`): the iteration's cost follows the image, not the scene's card area (1,000 small
        objects: 1,299 tiles, all seen)."""
        n = len(self.tiles)
        if (fraction >= 1.0 and not 0 < cap < n) or not n:
            return np.arange(n)
        cam_pos = where.get("cam_pos")
        never = self.count == 0
        always = (self.seen(cam_pos, where.get("view_proj")) if self.area is not None
                  else self.facing(cam_pos)) | never
        score = self.render_priority(frame, **where)
        if 0 < cap < int(always.sum()):
            lit = np.flatnonzero(always & ~never)
            k = max(cap - int(never.sum()), 0)
            pick = lit[np.argsort(-score[lit], kind="stable")[:k]]
            return np.union1d(np.flatnonzero(never), pick)
        if fraction >= 1.0:
            return np.arange(n)
        rest = np.flatnonzero(~always)
        k = min(int(np.ceil(fraction * len(rest))), len(rest))
        if cap > 0:
            k = min(k, cap - int(always.sum()))
        pick = rest[np.argsort(-score[rest], kind="stable")[:k]]
        return np.union1d(np.flatnonzero(always), pick)

    def seen(self, cam_pos, view_proj=None) -> np.ndarray:
        """bool per tile: the image reads its light. A tile is visible when it is in the frustum
        and faces the camera; the gather's rays leave the visible surfaces and read the tiles
        they hit, and the cache's rays from those tiles read theirs (more bounces). So a tile
        is seen when some visible tile's cosine-weighted hemisphere has at least SEEN_SHARE of
        it (form factor A_i cos_i cos_j / (pi d^2) between tile centres, d at least their mean
        radius; a tile of several cards' normals counts its cosine as 1). A floor's tiles do
        not see each other: an open sunlit ground far from the walls and objects on it is
        visible but read by no ray, while every wall of a room sees the others (measured on
        bench/quality_scenes: thin 170 tiles -> 95 seen, yard 221 -> 100; the rooms keep 90%+).
        Pairs of visible x all tiles in numpy, in blocks of 256 visible tiles (after the first,
        against the tiles not yet seen only), once per camera (cached until set_geometry or the
        camera changes)."""
        if self.geometry is None or self.area is None or cam_pos is None:
            return np.zeros(len(self.tiles), bool)
        key = (np.asarray(cam_pos, np.float64).tobytes(),
               None if view_proj is None else np.asarray(view_proj, np.float64).tobytes())
        if self._seen is not None and self._seen[0] == key:
            return self._seen[1]
        centre, radius, normal = self.geometry
        vis = self.facing(cam_pos)
        if view_proj is not None:
            spheres = np.concatenate([centre, radius[:, None]], axis=1)
            vis = vis & _in_frustum(spheres, np.asarray(view_proj, np.float64))
        j = np.flatnonzero(vis)
        if not len(j):
            return vis
        length = np.linalg.norm(normal, axis=1)
        flat = length >= 0.9
        nrm = normal / np.maximum(length, 1e-12)[:, None]
        best = np.zeros(len(self.tiles))
        # [B, T] dot products from the offsets' matrix products, not from unit offsets
        # [B, T, 3]; and only the tiles not yet seen after the first block (the answer is
        # best >= SEEN_SHARE). 1,299 tiles among 1,000 spheres: 101 -> 36 ms, the same tiles.
        cn_all = np.einsum("tk,tk->t", centre, nrm)                 # c_i . n_i
        for s in range(0, len(j), 256):
            b = j[s:s + 256]
            t = np.flatnonzero(best < SEEN_SHARE)                      # columns still open
            if not len(t):
                break
            w = centre[None, t, :] - centre[b, None, :]                # [B, T']: b -> i
            d = np.sqrt(np.einsum("btk,btk->bt", w, w))
            inv = 1.0 / np.maximum(d, 1e-12)
            # w . n_b = c_i . n_b - c_b . n_b; -(w . n_i) = c_b . n_i - c_i . n_i
            cnb = centre[t] @ nrm[b].T                                 # [T', B]: c_i . n_b
            cbn = centre[b] @ nrm[t].T                                 # [B, T']: c_b . n_i
            cos_j = np.where(flat[b, None],
                             np.maximum((cnb.T - cn_all[b, None]) * inv, 0.0), 1.0)
            cos_i = np.where(flat[None, t],
                             np.maximum((cbn - cn_all[None, t]) * inv, 0.0), 1.0)
            d2 = np.maximum(d, 0.5 * (radius[b, None] + radius[None, t])) ** 2
            form = self.area[None, t] * cos_j * cos_i / (np.pi * d2)
            form[b[:, None] == t[None, :]] = 0.0                       # not itself
            best[t] = np.maximum(best[t], form.max(axis=0))
        seen = best >= SEEN_SHARE
        self._seen = (key, seen)
        return seen

    def facing(self, cam_pos) -> np.ndarray:
        """bool per tile: the camera is in front of the tile's mean plane (or its mean normal is
        shorter than 0.9: curved, or cards of several sides). Inside a room every inner wall
        faces the camera, wherever it looks: F12 relights these every iteration, since the
        room's light arrives through their bounces (with a share of all tiles instead, window
        and glow lost 2.5x in relMSE)."""
        if self.geometry is None or cam_pos is None:
            return np.zeros(len(self.tiles), bool)
        centre, radius, normal = self.geometry
        to_cam = np.asarray(cam_pos, np.float64)[:3] - centre
        return ((normal * to_cam).sum(axis=1) > 0.0) | (np.linalg.norm(normal, axis=1) < 0.9)

    def choose(self, budget: int, frame: int, blend: float = 1.0, history: int = 1,
               **where) -> tuple:
        """(tile indices, blend per tile) for this frame: at most `budget` tiles by priority
        (all when budget <= 0 or >= the tile count). A tile's first update replaces (1), its
        next ones up to `history` take `blend` (one more bounce each, over-relaxed as F12's),
        then 1 / history (an exponential mean: the noise). Call commit() once they were relit.
        Why not a running mean from the first update: every update is one more bounce (its
        rays read the cache's last light), so a mean over them is a damped fixed-point
        iteration, x += (T(x) - x) / n, whose error shrinks by only 1 - (1 - rho) / n per
        update: in a room of bounce ratio rho ~0.6 it said "converged" (history updates) with
        the indirect light 22% short of F12's (bench/viewport_convergence.py, `imported`).
        Why then a mean: once the bounces have converged an update's change is its noise (16
        rays per 4x4 texels), and a tile relit every few redraws gives the probes' history
        only a few of its states to average. Not measured to matter yet: within 200 redraws
        the quality scenes end as close to F12 as with one more bounce forever (window 0.0109
        against 0.0107; thin and yard do not reach `history` updates per tile)."""
        n = len(self.tiles)
        if budget <= 0 or budget >= n:
            idx = np.arange(n)
        else:
            idx = np.argsort(-self.priority(frame, **where), kind="stable")[:budget]
            idx.sort()
        c, h = self.count[idx], max(int(history), 1)
        return idx, np.select([c == 0, c < h], [1.0, float(blend)], 1.0 / h)

    def commit(self, idx, frame: int):
        self.count[idx] += 1
        self.last[idx] = frame
        tx, ty = self.tiles[idx, 0], self.tiles[idx, 1]
        self.tile_frame[ty, tx] = frame

    def ages(self) -> np.ndarray:
        """float32 [tiles y, tiles x]: frames since each tile's last update, counted from the most
        recent update (0: relit in the last frame); -1 never since the reset or no card. For the
        update-heat debug view."""
        out = np.full((self.grid[1], self.grid[0]), -1.0, np.float32)
        if len(self.tiles):
            now = self.last.max()
            age = np.where(self.last >= 0, now - self.last, -1).astype(np.float32)
            out[self.tiles[:, 1], self.tiles[:, 0]] = age
        return out

    def converged(self, history: int, among=None) -> bool:
        """Every tile updated `history` times; with `among` (bool per tile: `seen`) those
        tiles, and every other tile lit at least once."""
        return self.least_count(among) >= max(int(history), 1)

    def least_count(self, among=None) -> int:
        """The fewest updates of a tile (of `among`'s tiles, 0 while any tile is unlit)."""
        if not len(self.count):
            return 1 << 30
        if among is None:
            return int(self.count.min())
        if (self.count == 0).any():
            return 0
        return int(self.count[among].min(initial=1 << 30))

    def page_table(self, idx, blend) -> np.ndarray:
        """float32 [1, K, 4] texels (tile x, tile y, blend, 0) for the GPU (sc_pages)."""
        out = np.zeros((1, max(len(idx), 1), 4), np.float32)
        out[0, :len(idx), :2] = self.tiles[idx]
        out[0, :len(idx), 2] = blend
        return out


def tile_geometry(schedule: PageSchedule, texel_card: np.ndarray, cards: np.ndarray,
                  objects: np.ndarray) -> tuple:
    """(centre [T, 3], radius [T], normal [T, 3]) in world space per tile of `schedule`: the box
    of its texels' card-plane points (depth: the middle of the card's depth range, the radius
    grows by half that range) and the mean of their normals (the opposite of each card's look
    axis). cards: card_packing's [rows, 4, 4]; objects: packing's [instances, 9, 4] (rows 0-3:
    world-to-local). Per (tile, card row) pair, not per texel: the texels a card has in a tile
    are the rectangle where its lighting rect meets the tile, their card-plane points a grid
    mapped affinely to the world, so their box is the box of its 4 corner texels and their
    normals one normal times their count (the same numbers as a loop over every texel, which
    took 0.26 s at 10 objects and 0.88 s at 1,000; tests/gpu/test_surface_cache_pages.py)."""
    n = len(schedule.tiles)
    if not n:
        return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    row = schedule.pair_row
    tile = np.repeat(np.arange(n), np.diff(np.r_[schedule.row_start, len(row)]))
    c = np.asarray(cards, np.float64)[row]
    inst, axis = c[:, 0, 0].astype(np.int64), c[:, 0, 1].astype(np.int64)
    lx, ly, w, h = c[:, 0, 2], c[:, 0, 3], c[:, 1, 2], c[:, 1, 3]
    tx = schedule.tiles[tile, 0].astype(np.float64) * TILE
    ty = schedule.tiles[tile, 1].astype(np.float64) * TILE
    x0, x1 = np.maximum(lx, tx), np.minimum(lx + w, tx + TILE) - 1.0    # texel columns
    y0, y1 = np.maximum(ly, ty), np.minimum(ly + h, ty + TILE) - 1.0    # texel rows
    count = (x1 - x0 + 1.0) * (y1 - y0 + 1.0)
    plane = np.array([PLANE[a] for a in range(6)])
    look = AXES[axis]                                     # one +-1 entry per row
    depth = 0.5 * (c[:, 3, 0] + c[:, 3, 1])
    w2l = np.array(objects, np.float64)[:, 0:4, :]        # [instances, 4, 4] row-major
    w2l[:, 3] = (0.0, 0.0, 0.0, 1.0)                      # as sc_object_w2l reads it
    l2w = np.linalg.pinv(w2l)                             # parked instances: singular
    pairs = np.arange(len(row))
    lo = np.full((len(row), 3), np.inf)
    hi = np.full((len(row), 3), -np.inf)
    for xs, ys in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):   # the 4 corner texels
        u = c[:, 2, 0] + (xs - lx + 0.5) / np.maximum(w, 1.0) * (c[:, 2, 2] - c[:, 2, 0])
        v = c[:, 2, 1] + (ys - ly + 0.5) / np.maximum(h, 1.0) * (c[:, 2, 3] - c[:, 2, 1])
        p = look * depth[:, None]                         # AXES[a] . p = depth
        p[pairs, plane[axis, 0]] = u
        p[pairs, plane[axis, 1]] = v
        pw = np.einsum("nij,nj->ni", l2w[inst, :3, :3], p) + l2w[inst, :3, 3]
        lo, hi = np.minimum(lo, pw), np.maximum(hi, pw)
    nw = np.einsum("nji,nj->ni", w2l[inst, :3, :3], -look)   # normals: transposed inverse
    nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-12)
    half = 0.5 * (c[:, 3, 1] - c[:, 3, 0])
    start = schedule.row_start                            # pairs are sorted by tile
    lo, hi = np.minimum.reduceat(lo, start), np.maximum.reduceat(hi, start)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * np.linalg.norm(hi - lo, axis=1) + np.maximum.reduceat(half, start)
    normal = np.add.reduceat(nw * count[:, None], start) / np.add.reduceat(count, start)[:, None]
    return centre, radius, normal


def tile_area(schedule: PageSchedule, texel_card: np.ndarray, cards: np.ndarray,
              objects: np.ndarray) -> np.ndarray:
    """float64 [T]: world m^2 of each tile's card texels: a texel of card row r covers its
    rect's size / its texel count, times its instance's scale (|det|^(2/3) of local-to-world)."""
    c = np.asarray(cards, np.float64)
    w2l = np.asarray(objects, np.float64)[:, 0:3, 0:3]
    scale = np.abs(np.linalg.det(w2l)) ** (-2.0 / 3.0) if len(w2l) else np.ones(0)
    scale = np.where(np.isfinite(scale), scale, 0.0)                   # parked: singular
    per_texel = ((c[:, 2, 2] - c[:, 2, 0]) / np.maximum(c[:, 1, 2], 1.0)
                 * (c[:, 2, 3] - c[:, 2, 1]) / np.maximum(c[:, 1, 3], 1.0)
                 * scale[c[:, 0, 0].astype(np.int64)])
    ys, xs = np.nonzero(texel_card >= 0)
    a = np.abs(per_texel[np.rint(texel_card[ys, xs]).astype(np.int64)])
    tw = schedule.grid[0]
    used = schedule.tiles[:, 1].astype(np.int64) * tw + schedule.tiles[:, 0]
    tile = np.searchsorted(used, (ys // TILE) * tw + xs // TILE)
    return np.bincount(tile, weights=a, minlength=len(schedule.tiles))


def _in_frustum(spheres: np.ndarray, view_proj: np.ndarray) -> np.ndarray:
    """bool per sphere (centre xyz, radius): not entirely outside one of the six clip planes."""
    m = view_proj
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    planes /= np.linalg.norm(planes[:, :3], axis=1, keepdims=True)
    dist = spheres[:, :3] @ planes[:, :3].T + planes[:, 3]
    return (dist >= -spheres[:, 3:4]).all(axis=1)
