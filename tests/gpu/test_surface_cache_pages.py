"""The surface-cache update budget (gpu_shaders/surface_cache_pages.py), exactly, no bpy: tiles
and their card rows, the budget, the priority order (never lit, visible, near, old) and that every
tile is refreshed within the frames the budget implies."""
import numpy as np

from gpu_shaders.surface_cache_pages import SEEN_SHARE, TILE, PageSchedule, tile_area, tile_geometry


def atlas():
    """A 100 x 70 lighting atlas (4 x 3 tiles): card row r fills tile column r (rows 0-3), each
    row on its own instance; tile (3, 2) holds no card."""
    tc = np.full((70, 100), -1.0)
    for r in range(4):
        tc[:, r * TILE:min((r + 1) * TILE, 100)] = r
    tc[64:, 96:] = -1                                # tile (3, 2) is empty
    return tc, np.arange(4)


def test_tiles_and_rows():
    s = PageSchedule(*atlas())
    assert s.grid == (4, 3)
    assert len(s) == 11                              # 12 tiles, one without a card
    assert [tuple(t) for t in s.tiles[:4]] == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert list(s.row_instance[s.row_start[:4]]) == [0, 1, 2, 3]


def test_budget_priority_and_round_robin():
    s = PageSchedule(*atlas())
    idx, blend = s.choose(0, frame=0, blend=1.5)     # no budget: everything
    assert len(idx) == 11 and np.allclose(blend, 1.0)  # first update of each: replace
    s.commit(idx, 0)
    idx, blend = s.choose(4, frame=1, blend=1.5, history=2)
    assert len(idx) == 4 and np.allclose(blend, 1.5)  # then the blend asked (one more bounce)
    # an instance in view and near the camera wins over equally old tiles
    spheres = np.array([[0, 0, 0, 1], [0, 0, 0, 1], [100, 0, 0, 1], [0, 0, 50, 1]], float)
    view_proj = np.diag([0.1, 0.1, -0.1, 1.0])       # the box |x|, |y|, |z| <= 10 is in view
    score = s.priority(1, instance_spheres=spheres, view_proj=view_proj, cam_pos=(0, 0, 0))
    cols = s.tiles[:, 0]
    assert score[cols == 0].min() > score[cols == 2].max()     # visible beats outside the view
    assert score[cols == 1].min() > score[cols == 3].max()     # near beats far (both unseen)
    # with a budget of 4 of 11 tiles, every tile is refreshed within ceil(11 / 4) = 3 frames
    s.reset()
    seen = np.zeros(len(s), int)
    for frame in range(3):
        idx, _ = s.choose(4, frame, instance_spheres=spheres, view_proj=view_proj,
                          cam_pos=(0, 0, 0))
        assert len(idx) == 4 or frame == 2
        s.commit(idx, frame)
        seen[idx] += 1
    assert (seen >= 1).all(), seen
    assert not s.converged(8)


def test_blends_bounce_then_average():
    """Viewport tiles: replace, then `blend` (one more bounce) until `history` updates, then the
    exponential mean 1 / history."""
    s = PageSchedule(*atlas())
    for frame, want in enumerate((1.0, 1.5, 1.5, 1 / 3, 1 / 3)):
        idx, blend = s.choose(0, frame, blend=1.5, history=3)
        assert np.allclose(blend, want), (frame, blend)
        s.commit(idx, frame)


def test_never_lit_tiles_come_first_after_a_reset():
    s = PageSchedule(*atlas())
    s.commit(np.arange(6), 0)
    idx, blend = s.choose(5, frame=1, blend=1.5)
    assert set(idx) == set(range(6, 11)) and np.allclose(blend, 1.0)
    table = s.page_table(idx, blend)
    assert table.shape == (1, 5, 4) and np.array_equal(table[0, :, :2], s.tiles[idx])
    s.commit(idx, 1)
    assert s.tile_frame[s.tiles[idx[0], 1], s.tiles[idx[0], 0]] == 1


def test_ages_for_the_heat_view():
    s = PageSchedule(*atlas())
    assert (s.ages() == -1).all()                    # never relit (and the empty tile)
    s.commit(np.array([0, 1]), 5)
    s.commit(np.array([1]), 7)
    a = s.ages()
    assert a[0, 0] == 2 and a[0, 1] == 0 and a[0, 2] == -1 and a[2, 3] == -1


def ground_and_underside():
    """Two cards of one 64 m x 32 m slab at z = 0 on instance 0 (identity transform), each 64 x 32
    lighting texels (1 m per texel: 2 x 1 tiles each): row 0 looks down (-Z: sees the top, whose
    normal is +Z), row 1 looks up (+Z: the underside, normal -Z). Lighting atlas 64 x 64."""
    tc = np.full((64, 64), -1.0)
    tc[:32, :] = 0
    tc[32:, :] = 1
    cards = np.zeros((2, 4, 4), np.float32)
    for row, axis in ((0, 5), (1, 4)):
        cards[row, 0] = (0, axis, 0, 32 * row)
        cards[row, 1] = (0, 0, 64, 32)
        cards[row, 2] = (-32, -16, 32, 16)
        cards[row, 3] = (-0.1, 0.1, 0, 0) if axis == 4 else (-0.1, 0.1, 0, 0)
    objects = np.zeros((1, 9, 4), np.float32)
    objects[0, 0:4] = np.eye(4)
    return tc, cards, objects


def test_tile_geometry_and_render_priority():
    tc, cards, objects = ground_and_underside()
    s = PageSchedule(tc, np.zeros(2))
    assert len(s) == 4                               # 2 x 2 tiles of 32 x 32 texels
    centre, radius, normal = tile_geometry(s, tc, cards, objects)
    # tile (0, 0): the top's texels x in [-32, 0] m, y in [-16, 16] m
    assert np.allclose(centre[0], (-16.5, 0.0, 0.0), atol=0.6), centre[0]
    assert np.allclose(normal[:2], (0, 0, 1)) and np.allclose(normal[2:], (0, 0, -1))
    assert np.allclose(radius, 0.5 * np.hypot(31, 31) + 0.1, atol=1e-6)
    # the instance moved by (1, 2, 3) and turned 90 degrees about x (world-to-local: the inverse)
    turn = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], float)
    move = np.eye(4)
    move[:3, 3] = (1, 2, 3)
    moved = objects.copy()
    moved[0, 0:4] = np.linalg.inv(move @ turn)
    c2, r2, n2 = tile_geometry(s, tc, cards, moved)
    assert np.allclose(c2, centre[:, [0, 2, 1]] * (1, -1, 1) + (1, 2, 3), atol=1e-5)
    assert np.allclose(n2[:2], (0, -1, 0), atol=1e-6) and np.allclose(r2, radius)
    s.geometry = (centre, radius, normal)
    # a camera 10 m above the top's x > 0 half, looking down: that tile first; the underside
    # (facing away) after the top's far half, the near underside before the far; never-lit tiles
    # in the same order, before any lit
    cam = (16.0, 0.0, 10.0)
    view_proj = np.diag([1 / 40, 1 / 40, -1 / 40, 1.0])   # |x|, |y|, |z| <= 40 in view
    assert list(s.facing(cam)) == [True, True, False, False]
    # the first iteration: every tile (never lit); then (no tile areas: the top, facing the
    # camera, every time) the never-lit underside tile and of the others a quarter
    assert list(s.choose_render(0.25, 0, view_proj=view_proj, cam_pos=cam)) == [0, 1, 2, 3]
    s.commit(np.array([0, 1, 3]), 0)
    assert list(s.choose_render(0.25, 1, view_proj=view_proj, cam_pos=cam)) == [0, 1, 2, 3]
    s.commit(np.arange(4), 0)
    score = s.render_priority(1, view_proj=view_proj, cam_pos=cam)
    assert score[1] > score[0] > score[2] and score[0] > score[3]
    s.commit(np.array([0, 1, 2]), 1)
    assert list(s.choose_render(0.25, 2, view_proj=view_proj, cam_pos=cam)) == [0, 1, 3]
    assert len(s.choose_render(1.0, 2)) == 4


def test_tile_area():
    tc, cards, objects = ground_and_underside()
    s = PageSchedule(tc, np.zeros(2))
    assert np.allclose(tile_area(s, tc, cards, objects), 1024.0)   # 32 x 32 texels of 1 m^2
    scaled = objects.copy()
    scaled[0, 0:4] = np.linalg.inv(np.diag([2.0, 2.0, 2.0, 1.0]))  # instance scale 2
    assert np.allclose(tile_area(s, tc, cards, scaled), 4096.0)


def test_seen_tiles_and_the_render_share():
    """A wall facing the camera on a ground: the ground next to the wall is read by the wall's
    rays (seen), the ground 20 m away is visible but no visible tile's rays reach it (a flat
    ground's tiles do not see each other), nor the wall's back. F12 relights the seen tiles
    every iteration and a share of the others by priority."""
    tc = np.zeros((TILE, 4 * TILE))
    for r in range(4):
        tc[:, r * TILE:(r + 1) * TILE] = r
    s = PageSchedule(tc, np.arange(4))
    centre = np.array([[0, 0, 1], [0, -1, 0], [0, -20, 0], [0, 0.01, 1]], float)
    normal = np.array([[0, -1, 0], [0, 0, 1], [0, 0, 1], [0, 1, 0]], float)
    s.geometry = (centre, np.full(4, 1.1), normal)
    s.area = np.full(4, 2.56)                          # 32 x 32 texels at 20 per metre
    cam = (0.0, -30.0, 10.0)
    assert list(s.facing(cam)) == [True, True, True, False]
    # wall -> near ground: 2.56 cos45 cos45 / (pi 2) = 0.204; -> far ground: ~1e-4
    assert SEEN_SHARE == 0.02
    assert list(s.seen(cam)) == [True, True, False, False]
    assert list(s.choose_render(0.5, 0, cam_pos=cam)) == [0, 1, 2, 3]   # never lit: all
    s.commit(np.arange(4), 0)
    # the seen tiles, and of the other two one (ceil(0.5 x 2)): the visible far ground
    assert list(s.choose_render(0.5, 1, cam_pos=cam)) == [0, 1, 2]
    s.commit(np.array([0, 1, 2]), 1)
    assert list(s.choose_render(0.0, 2, cam_pos=cam)) == [0, 1]        # no share: seen only
    # a wall 1 m in front of the far ground makes it seen
    centre2 = np.vstack([centre, [[0, -21, 1]]])
    normal2 = np.vstack([normal, [[0, 1, 0]]])
    tc2 = np.zeros((TILE, 5 * TILE))
    for r in range(5):
        tc2[:, r * TILE:(r + 1) * TILE] = r
    s2 = PageSchedule(tc2, np.arange(5))
    s2.geometry, s2.area = (centre2, np.full(5, 1.1), normal2), np.full(5, 2.56)
    cam2 = (0.0, -10.0, 10.0)                          # sees the far ground and its wall's face
    assert list(s2.facing(cam2)) == [True, True, True, False, True]
    assert list(s2.seen(cam2)) == [True, True, True, False, True]


def test_the_still_viewport_waits_only_for_the_tiles_the_image_reads():
    """With `seen` known, the budget goes round the seen tiles (SEEN_WEIGHT, no frustum or
    distance weights: equally often), and converged / least_count count only them once every
    tile is lit: 4 seen of 11 tiles, budget 2, history 3 -> converged within 6 frames after
    the first full pass, while the unseen tiles stay behind."""
    s = PageSchedule(*atlas())
    seen = np.zeros(len(s), bool)
    seen[[0, 3, 5, 9]] = True
    assert s.least_count(seen) == 0                  # unlit tiles: nothing counts yet
    idx, _ = s.choose(0, frame=0)
    s.commit(idx, 0)                                 # every tile lit once
    assert s.least_count(seen) == 1 and s.least_count() == 1
    spheres = np.array([[0, 0, 0, 1], [0, 0, 0, 1], [100, 0, 0, 1], [0, 0, 50, 1]], float)
    view_proj = np.diag([0.1, 0.1, -0.1, 1.0])
    for frame in range(1, 7):
        idx, _ = s.choose(2, frame, history=3, instance_spheres=spheres, view_proj=view_proj,
                          cam_pos=(0, 0, 0), seen=seen)
        assert seen[idx].all(), (frame, idx)         # only the tiles the image reads
        s.commit(idx, frame)
    assert s.least_count(seen) == 4                  # 12 updates round the 4: 3 more each
    assert s.converged(3, seen) and not s.converged(3)
    assert s.least_count() == 1


def texel_geometry(schedule, texel_card, cards, objects):
    """Brute force for tile_geometry: every texel's world point and normal, then per tile."""
    from gpu_shaders.card_packing import AXES, PLANE
    ys, xs = np.nonzero(texel_card >= 0)
    row = np.rint(texel_card[ys, xs]).astype(np.int64)
    c = np.asarray(cards, np.float64)[row]
    inst, axis = c[:, 0, 0].astype(np.int64), c[:, 0, 1].astype(np.int64)
    u = c[:, 2, 0] + (xs - c[:, 0, 2] + 0.5) / c[:, 1, 2] * (c[:, 2, 2] - c[:, 2, 0])
    v = c[:, 2, 1] + (ys - c[:, 0, 3] + 0.5) / c[:, 1, 3] * (c[:, 2, 3] - c[:, 2, 1])
    look = AXES[axis]
    p = look * (0.5 * (c[:, 3, 0] + c[:, 3, 1]))[:, None]
    plane = np.array([PLANE[a] for a in range(6)])
    p[np.arange(len(row)), plane[axis, 0]] = u
    p[np.arange(len(row)), plane[axis, 1]] = v
    w2l = np.array(objects, np.float64)[:, 0:4, :]
    w2l[:, 3] = (0.0, 0.0, 0.0, 1.0)
    l2w = np.linalg.inv(w2l)
    pw = np.einsum("nij,nj->ni", l2w[inst, :3, :3], p) + l2w[inst, :3, 3]
    nw = np.einsum("nji,nj->ni", w2l[inst, :3, :3], -look)
    nw /= np.linalg.norm(nw, axis=1, keepdims=True)
    tw = schedule.grid[0]
    tile = np.searchsorted(schedule.tiles[:, 1] * tw + schedule.tiles[:, 0], (ys // TILE) * tw + xs // TILE)
    centre, radius, normal = [], [], []
    for t in range(len(schedule.tiles)):
        m = tile == t
        lo, hi = pw[m].min(0), pw[m].max(0)
        centre.append(0.5 * (lo + hi))
        radius.append(0.5 * np.linalg.norm(hi - lo) + (0.5 * (c[m, 3, 1] - c[m, 3, 0])).max())
        normal.append(nw[m].mean(0))
    return np.array(centre), np.array(radius), np.array(normal)


def test_tile_geometry_equals_the_texel_brute_force():
    """Cards of random sizes across tile borders, on instances moved, turned and scaled:
    tile_geometry (per tile and card row, from corner texels) equals a loop over every texel."""
    rng = np.random.default_rng(7)
    tc = np.full((100, 130), -1.0)
    rows, n_inst = [], 5
    for gy in range(5):
        for gx in range(6):
            w, h = rng.integers(1, 21, 2)
            lx, ly = gx * 21 + rng.integers(0, 21 - w + 1), gy * 20 + rng.integers(0, 20 - h + 1)
            lo = rng.uniform(-1, 0, 2)
            rows.append([(rng.integers(n_inst), rng.integers(6), lx, ly), (0, 0, w, h),
                         (*lo, *(lo + rng.uniform(0.1, 2, 2))), (rng.uniform(-1, 0), rng.uniform(0, 1), 0, 0)])
            tc[ly:ly + h, lx:lx + w] = len(rows) - 1
    cards = np.array(rows, np.float64)
    objects = np.zeros((n_inst, 9, 4))
    for i in range(n_inst):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        l2w = np.eye(4)
        l2w[:3, :3] = q * rng.uniform(0.5, 2.0, 3)
        l2w[:3, 3] = rng.uniform(-5, 5, 3)
        objects[i, 0:4] = np.linalg.inv(l2w)
    s = PageSchedule(tc, cards[:, 0, 0])
    got = tile_geometry(s, tc, cards, objects)
    want = texel_geometry(s, tc, cards, objects)
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-9, atol=1e-9)


def test_render_cap_follows_the_image_not_the_card_area():
    """choose_render with cap: every never-lit tile whatever the cap (an unlit tile reads
    black), then of the tiles the view reads at most `cap` in all by render_priority (age,
    visibility, distance), none of the rest; a cap at or above the tile count changes nothing."""
    tc, cards, objects = ground_and_underside()
    s = PageSchedule(tc, np.zeros(2))
    s.geometry = tile_geometry(s, tc, cards, objects)
    cam = (16.0, 0.0, 10.0)
    view_proj = np.diag([1 / 40, 1 / 40, -1 / 40, 1.0])
    where = dict(view_proj=view_proj, cam_pos=cam)
    assert list(s.choose_render(1.0, 0, cap=1, **where)) == [0, 1, 2, 3]     # never lit: all
    s.commit(np.arange(4), 0)
    s.commit(np.array([1]), 5)                       # tile 1 (facing, nearer) updated since
    # render_priority: age x weight / (1 + distance / 10 m): tile 0 (34 m) 6 x 0.23 > tile 1
    # (10 m) 1 x 0.5, so the far tile, left behind, goes first
    assert list(s.choose_render(1.0, 6, cap=1, **where)) == [0]
    assert list(s.choose_render(0.25, 6, cap=2, **where)) == [0, 1]
    assert list(s.choose_render(1.0, 6, cap=4, **where)) == [0, 1, 2, 3]
    s.count[3] = 0                                   # a tile not lit yet: in, above the cap
    assert list(s.choose_render(1.0, 6, cap=1, **where)) == [3]
    assert list(s.choose_render(1.0, 6, cap=2, **where)) == [0, 3]
