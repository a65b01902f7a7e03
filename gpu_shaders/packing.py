"""Pack a scene bake's mip-0 mesh SDFs into the arrays the GPU textures are made of (no bpy, no gpu).

Three arrays, all uploaded as they are by `resources.py` (x fastest, C order of the shapes below):

- `atlas`: uint8 [az*8, ay*8, ax*8], every kept brick of every unique mesh, brick `s` of the
  scene at brick cell `(s % ax, (s // ax) % ay, s // (ax*ay))` of a grid of 8^3 blocks; the
  sample `(x, y, z)` of a brick is texel `8 * cell + (x, y, z)`. Codes as in the cache.
- `indirection`: int32 [rows, width], one linear table for all meshes: mesh brick `(bx, by, bz)`
  is entry `offset + bx + gx * (by + gy * bz)`, texel `(i % width, i // width)`; its value is the
  scene brick slot (mesh slot + the mesh's first slot) or -1 / -2 (not stored, outside / inside).
- `objects`: float32 [instances, OBJECT_TEXELS, 4], one row of RGBA texels per instance:
  texels 0-3 the rows of the world-to-local 4x4 matrix; 4 = (origin.xyz, voxel size);
  5 = (brick grid xyz, band); 6 = (bounds_min.xyz, indirection offset);
  7 = (bounds_max.xyz, distance scale: local distances times this are world lower bounds,
  the smallest singular value of the local-to-world 3x3); 8 = (world centre of the mesh bounds,
  radius of a world sphere around them grown by half a voxel): sdf_scene skips an object whose
  sphere is farther than the nearest distance found so far. Exact, because sdf_visit
  (sdf_lib.glsl) takes an object's value as the larger of its sample and two lower bounds of
  its true distance, to this sphere and to its bounds box (less half a voxel: a two-sided mesh
  stores distance minus half a voxel): inside the SDF volume a sample far from the surface reads
  the clamped band, less than the bounds' distance, which once made the sphere hold the whole
  volume (1.5 m around a 0.25 m icosphere at 8 voxels/m: every neighbour was visited at every
  sample). The object grid (object_grid.py) lists objects by the same bounds; 9 = (thin-wall
  margin in voxels, 0, 0, 0): `thin_voxels`, what the shadow cones (light_lib.glsl) add to
  this object's surfaces.

Integers stored in float texels (grid, offsets) are exact below 2^24; packing checks that.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

BRICK = 8
OBJECT_TEXELS = 10
THIN_VOXELS = 0.5                # light_lib.glsl's thin-wall rule: occluders half a voxel thicker
# A thick mesh's margin: the trilinear field reads a right-angled convex edge up to 0.3 voxel
# away (samples half a voxel either side: (0.71 + 0.5 + 0.5 - 0.5) / 4), so silhouettes shrink
# by that much without it. tests/gpu/test_direct_light.py (box on a floor against Cycles, relMSE
# sun / point / spot / area): margin 0.5: 0.0024 / 0.0054 / 0.0038 / 0.0070; 0: 0.0494 (shadow
# edge pixels lit) / 0.0062 / 0.0026 / 0.0026; 0.25: 0.0010 / 0.0012 / 0.0010 / 0.0030.
# That rounding depends on where the edges fall between samples (0 on a sample, 0.3 midway; 0.25
# is its mean over random placements), so each bake measures its own (edge_voxels); this is the
# fallback for bakes without the measurement.
EDGE_VOXELS = 0.25
MAX_BRICKS_PER_AXIS = 256        # 2048 texels: the smallest 3D texture limit of GL 4.5 drivers
PARKED = 1e30                    # bounding-sphere centre of an instance left out (singular transform)
INDIRECTION_WIDTH = 4096
FLOAT_EXACT = 1 << 24


@dataclass
class PackedScene:
    atlas: np.ndarray                # uint8 [az*8, ay*8, ax*8]
    atlas_bricks: tuple              # (ax, ay, az) brick cells per axis
    indirection: np.ndarray          # int32 [rows, width]
    objects: np.ndarray              # float32 [instances, OBJECT_TEXELS, 4]
    mesh_keys: list                  # unique meshes in packing order
    brick_offset: dict               # mesh key -> first scene brick slot
    indirection_offset: dict         # mesh key -> first indirection entry
    instance_names: list = field(default_factory=list)
    bricks: int = 0                  # kept bricks of all meshes (atlas cells used)

    @property
    def atlas_size(self) -> tuple:
        """(width, height, depth) texels of the atlas texture."""
        return tuple(int(n) * BRICK for n in self.atlas_bricks)


def atlas_grid(n_bricks: int) -> tuple:
    """Brick cells (ax, ay, az) of an atlas holding n_bricks: near-cubic, at most 256 per axis."""
    n = max(int(n_bricks), 1)
    side = min(MAX_BRICKS_PER_AXIS, max(1, math.ceil(round(n ** (1.0 / 3.0), 9))))
    while side ** 3 < n and side < MAX_BRICKS_PER_AXIS:
        side += 1
    az = -(-n // (side * side))
    if az > MAX_BRICKS_PER_AXIS:
        raise ValueError(f"{n} bricks do not fit a {MAX_BRICKS_PER_AXIS}^3-brick atlas")
    return side, side, az


def brick_cell(slot, grid) -> np.ndarray:
    """Atlas brick cell(s) (x, y, z) of scene brick slot(s) for an atlas of `grid` cells."""
    s = np.asarray(slot, np.int64)
    ax, ay, _ = grid
    return np.stack([s % ax, (s // ax) % ay, s // (ax * ay)], axis=-1)


def pack_atlas(brick_arrays, grid) -> np.ndarray:
    """uint8 [az*8, ay*8, ax*8] atlas of the concatenated bricks ([slot, x, y, z] each)."""
    ax, ay, az = grid
    cells = ax * ay * az
    parts = [np.asarray(b, np.uint8).reshape(-1, BRICK, BRICK, BRICK) for b in brick_arrays]
    allb = np.concatenate(parts) if parts else np.zeros((0, BRICK, BRICK, BRICK), np.uint8)
    if len(allb) > cells:
        raise ValueError(f"{len(allb)} bricks do not fit {grid}")
    full = np.zeros((cells, BRICK, BRICK, BRICK), np.uint8)
    full[:len(allb)] = allb
    # slot = bx + ax * (by + ay * bz) -> [bz, by, bx, x, y, z] -> [bz, z, by, y, bx, x]
    full = full.reshape(az, ay, ax, BRICK, BRICK, BRICK).transpose(0, 5, 1, 4, 2, 3)
    return np.ascontiguousarray(full.reshape(az * BRICK, ay * BRICK, ax * BRICK))


def local_to_world_scale(matrix_world) -> float:
    """Smallest singular value of the 3x3 part: |local distance| * this <= world distance."""
    return float(np.linalg.svd(np.asarray(matrix_world, np.float64)[:3, :3], compute_uv=False).min())


def edge_voxels(sdf, mip: int = 0) -> float:
    """A thick mesh's shadow margin: the field's measured rounding of its convex edges
    (lumen_addon.sdf.edge_rounding, stored with the bake), at most EDGE_VOXELS; EDGE_VOXELS when
    the bake has none or the mesh has no sharp convex edge.
    Why at most: the cones' penumbra lies wholly outside the edge they graze (k d / t is 0 there),
    which already darkens every shadow edge by half a penumbra; compensating the rounding beyond
    the quarter voxel (edges midway between samples read 0.30) adds to that: bench/quality.py's
    cornell, all of whose edges read 0.30, went from bias -1.7% to -2.1% and relMSE 0.0081 to
    0.0085 with the full measured margin. Below it the measurement is what the field does:
    the window room's walls hold their edges on samples (0.01), and the fixed quarter voxel cut
    its sun patch by 7% (bias -8.3% -> -4.1%)."""
    measured = getattr(sdf, "edge_voxels", None) or []
    value = measured[mip] if mip < len(measured) else None
    return EDGE_VOXELS if value is None else float(min(max(value, 0.0), EDGE_VOXELS))


def thin_voxels(sdf, mip: int = 0) -> float:
    """The thin-wall margin of mesh `sdf` in voxels: THIN_VOXELS unless the field shows no
    surface thinner than a voxel, then EDGE_VOXELS.

    A wall thinner than a voxel has no sample half a voxel inside it: the trilinear field over
    it stays above zero, so shadow cones count occluders half a voxel thicker to be stopped by
    it. Where every surface has depth, the field crosses zero at the surface and the margin
    only shrinks openings: half a voxel off each side of a window (5 cm voxels, a 1 m window:
    the sun patch 19% too dark, bench/bias_by_bounce.py). What a thick mesh keeps is the
    trilinear field's rounding of its convex edges, as measured at the bake (edge_voxels). Test, per brick, every sample just
    outside a surface (0 <= d < 0.6 voxel; the brick's border samples, whose neighbourhood it
    cuts, are not tested): by a surface with depth one of its 26 neighbours (1 to sqrt(3)
    voxels away, one within 35 degrees of any direction) lies at least 0.8 voxel lower; across
    a wall of thickness T the field falls by at most 2 d - 1 + T < 0.8 voxel when T < 0.6
    voxel, and at least 1.6 voxels of depth are needed for the fall. More than 1% of such
    samples without it (or none at all, or a two-sided mesh) keep the margin. Memoised on the
    mesh."""
    memo = getattr(sdf, "_thin_voxels", None)
    if memo is not None and memo[0] == mip:
        return memo[1]
    m = sdf.mips[mip]
    thin = THIN_VOXELS
    if not sdf.two_sided and len(m.bricks):
        v = (np.asarray(m.bricks, np.float32) - 127.5) / 127.5 * (m.band / m.voxel_size)
        c = v[:, 1:-1, 1:-1, 1:-1]
        low = np.full(c.shape, np.inf, np.float32)
        n = BRICK - 1
        for dx in (0, 1, 2):
            for dy in (0, 1, 2):
                for dz in (0, 1, 2):
                    if (dx, dy, dz) != (1, 1, 1):
                        np.minimum(low, v[:, dx:dx + n - 1, dy:dy + n - 1, dz:dz + n - 1], out=low)
        near = (c >= 0.0) & (c < 0.6)
        shallow = near & (low > c - 0.8)
        if near.any() and shallow.sum() <= 0.01 * near.sum():
            thin = edge_voxels(sdf, mip)
    try:
        sdf._thin_voxels = (mip, thin)
    except AttributeError:
        pass
    return thin


def object_row(world_to_local, origin, voxel_size, brick_grid, band, bounds_min, bounds_max,
               indirection_offset, distance_scale, thin=THIN_VOXELS) -> np.ndarray:
    row = np.zeros((OBJECT_TEXELS, 4), np.float64)
    row[0:4] = np.asarray(world_to_local, np.float64)
    row[4] = (*origin, voxel_size)
    row[5] = (*brick_grid, band)
    row[6] = (*bounds_min, indirection_offset)
    row[7] = (*bounds_max, distance_scale)
    l2w = np.linalg.inv(np.asarray(world_to_local, np.float64))
    # the sphere holds the mesh bounds grown by half a voxel (a two-sided mesh stores its
    # distance minus half a voxel), not the SDF volume: sdf_visit never lets a value fall below
    # the bounds' distance (see the module docstring), so nothing farther can be nearer
    lo = np.asarray(bounds_min, np.float64) - 0.5 * voxel_size
    hi = np.asarray(bounds_max, np.float64) + 0.5 * voxel_size
    centre = l2w[:3, :3] @ ((lo + hi) / 2) + l2w[:3, 3]
    sigma_max = float(np.linalg.svd(l2w[:3, :3], compute_uv=False).max())
    row[8] = (*centre, sigma_max * float(np.linalg.norm(hi - lo)) / 2 * (1 + 1e-5) + 1e-6)
    row[9] = (thin, 0.0, 0.0, 0.0)
    return row.astype(np.float32)


def singular(matrix_world) -> bool:
    """True for a transform the SDF scene cannot invert: non-finite, or a 3x3 part with a zero
    (or nearly zero) scale, e.g. an object scaled to 0 (Blender draws nothing for it)."""
    mw = np.asarray(matrix_world, np.float64)
    if mw.shape != (4, 4):
        return True
    return bool(singular_many(mw[None])[0])


def singular_many(matrices) -> np.ndarray:
    """singular() of every matrix of float [n, 4, 4] at once (bool [n]): one batched SVD, not one
    per instance (a sync among 1,000 objects spent 15 ms on the loop)."""
    mw = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    bad = ~np.isfinite(mw).all(axis=(1, 2))
    s = np.linalg.svd(np.where(bad[:, None, None], 0.0, mw)[:, :3, :3], compute_uv=False)
    return bad | (s.min(axis=1) <= 1e-9 * np.maximum(s.max(axis=1), 1e-30))


def instance_row(sdf, matrix_world, indirection_offset: int, mip: int = 0) -> np.ndarray:
    """The object-table row of one instance of mesh `sdf`. A singular transform gets a parked
    row: identity placement and a bounding sphere 1e30 m away, which sdf_scene always skips, so
    the instance casts and bounces nothing (as Blender shows nothing of it) and the rows of the
    other instances keep their indices."""
    m = sdf.mips[mip]
    mw = np.asarray(matrix_world, np.float64)
    if singular(mw):
        row = object_row(np.eye(4), sdf.origin, m.voxel_size, m.brick_grid, m.band,
                         sdf.bounds_min, sdf.bounds_max, indirection_offset, 1.0)
        row[8] = (PARKED, PARKED, PARKED, 0.0)
        return row
    return object_row(np.linalg.inv(mw), sdf.origin, m.voxel_size, m.brick_grid, m.band,
                      sdf.bounds_min, sdf.bounds_max, indirection_offset, local_to_world_scale(mw),
                      thin_voxels(sdf, mip))


def pack_scene(meshes: dict, instances, mip: int = 0, indirection_width: int = INDIRECTION_WIDTH) -> PackedScene:
    """Pack `meshes` (key -> lumen_addon.sdf.MeshSDF) and `instances` (objects with `.name`,
    `.mesh` (a key) and `.matrix_world`, e.g. lumen_addon.bake.Instance) for the GPU.

    Only meshes some instance uses are packed, in order of first use.
    """
    instances = list(instances)
    keys = list(dict.fromkeys(inst.mesh for inst in instances))
    missing = [k for k in keys if k not in meshes]
    if missing:
        raise KeyError(f"instances name meshes the bake does not hold: {missing}")
    brick_offset, ind_offset, ind_parts, brick_parts = {}, {}, [], []
    nb = ni = 0
    for key in keys:
        m = meshes[key].mips[mip]
        ind = np.asarray(m.indirection, np.int32)
        brick_offset[key], ind_offset[key] = nb, ni
        glob = np.where(ind >= 0, ind + nb, ind)
        ind_parts.append(glob.transpose(2, 1, 0).reshape(-1))      # x fastest
        brick_parts.append(m.bricks)
        nb += len(m.bricks)
        ni += ind.size
    if nb >= FLOAT_EXACT or ni >= FLOAT_EXACT:
        raise ValueError(f"{nb} bricks / {ni} indirection entries: beyond exact float integers")
    grid = atlas_grid(nb)
    atlas = pack_atlas(brick_parts, grid)
    width = int(max(1, min(indirection_width, ni)))
    rows = max(1, -(-ni // width))
    table = np.full(rows * width, -1, np.int32)
    if ni:
        table[:ni] = np.concatenate(ind_parts)
    objects = [instance_row(meshes[inst.mesh], inst.matrix_world, ind_offset[inst.mesh], mip)
               for inst in instances]
    objs = np.stack(objects) if objects else np.zeros((0, OBJECT_TEXELS, 4), np.float32)
    return PackedScene(atlas, grid, table.reshape(rows, width), objs, keys, brick_offset, ind_offset,
                       [inst.name for inst in instances], nb)


def pack_bake(bake, mip: int = 0) -> PackedScene:
    """pack_scene for a lumen_addon.bake.SceneBake (from bake_scene or cache.read_cache)."""
    return pack_scene(bake.meshes, bake.instances, mip)


ROWS_PER_LINE = 1024     # row tables: rows of K texels, this many rows a texture line


def row_table(rows, pad=None) -> np.ndarray:
    """float32 [lines, min(n, ROWS_PER_LINE) * K, 4]: the table rows [n, K, 4] laid out
    ROWS_PER_LINE rows a line (row r at line r // 1024, texels (r % 1024) K .. + K - 1; GLSL:
    row_table_lib.glsl's row_texel). Why: as one column n texels high, a table past the GPU's
    largest texture side (16,384 on llvmpipe) failed to upload, and with it the render (5,000
    scattered pebbles' cards). The last line is filled with `pad` rows [K, 4] (zeros without)."""
    rows = np.asarray(rows, np.float32)
    n, k = rows.shape[0], rows.shape[1]
    per = max(min(n, ROWS_PER_LINE), 1)
    lines = max(-(-n // per), 1)
    out = np.zeros((lines * per, k, 4), np.float32)
    out[:n] = rows
    if pad is not None:
        out[n:] = pad
    return out.reshape(lines, per * k, 4)
