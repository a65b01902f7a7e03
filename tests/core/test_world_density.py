"""Voxel density is per metre of world size (bake.sdf_scale): a small mesh scaled up in the scene,
as imported scans often are (file units), bakes at the scene's density, not its file's.

The case that found it: the Stanford bunny OBJ (15 cm) scaled 6.4x in bench/quality.py's
`imported` scene had 32 cm voxels, 3 across the bunny; its shadow cones' half-voxel margin made
a black ellipse 16 cm wide around its base. Here: an open-bottomed box (a scan with no bottom)
standing on the floor plane z = 0, 16 cm in its file, 6.4x in the scene.
"""
import numpy as np

import shapes
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene, sdf_scale

SCALE = 6.4
HALF = 0.08          # local half size: 1.02 m in the scene


def open_box():
    """shapes.box without its two bottom (z = -HALF) faces: 8 boundary edges, a square hole."""
    v, f = shapes.box((HALF, HALF, HALF))
    return v, f[~np.all(v[f][:, :, 2] < 0, axis=1)]


def standing(scale):
    """World matrix: scaled, standing on z = 0."""
    m = np.diag([scale, scale, scale, 1.0])
    m[2, 3] = HALF * scale
    return m


def world_sdf(bake, inst, points):
    """The instance's field at world points, in metres (the baked field is in local units)."""
    m = np.asarray(inst.matrix_world)
    s = np.linalg.norm(m[:3, 0])
    local = (points - m[:3, 3]) / s
    return bake.meshes[inst.mesh].sample(local) * s


def test_scaled_open_mesh_bakes_at_world_density():
    v, f = open_box()
    bake = bake_scene([ObjectInput("Scan", v, f, standing(SCALE))], BakeSettings(voxel_density=20))
    (inst,) = bake.instances
    h_world = bake.meshes[inst.mesh].mips[0].voxel_size * SCALE
    # 20 voxels per world metre up to the half-octave rounding (6.4 -> 2^2.5): 5.66 cm; it was
    # 32 cm (20 per local metre), 3 voxels across the box.
    assert abs(h_world - SCALE / (20 * 2 ** 2.5)) < 1e-9, h_world
    # The floor beside the box, 5 to 30 cm from its wall: outside (positive) and the true
    # distance to the wall within half a voxel; the shadow cones' margin is half a voxel.
    wall = HALF * SCALE
    gap = np.linspace(0.05, 0.3, 6)
    # floor points (z = 0) out from the middle of each side
    pts = []
    for a in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
        d = np.array([np.cos(a), np.sin(a), 0.0])
        pts += [d * (wall + g) for g in gap]
    pts = np.array(pts)
    d = world_sdf(bake, inst, pts)
    true = np.tile(gap, 4)
    assert (d > 0).all(), d
    assert np.abs(d - true).max() < 0.5 * h_world, np.abs(d - true).max()
    # The open bottom is capped (geometry's winding rule): inside the box, 10 cm above the floor,
    # is inside; under the floor below the hole (the floor's own solid) the sign does not matter.
    inner = np.array([[x, y, 0.1] for x in (-0.3, 0.0, 0.3) for y in (-0.3, 0.0, 0.3)])
    assert (world_sdf(bake, inst, inner) < 0).all()


def test_instances_share_a_bake_within_half_an_octave():
    """Linked duplicates at similar scales share one SDF; one scaled 4x apart bakes apart, at
    its own density (its cards were already per scale)."""
    v, f = open_box()
    objs = [ObjectInput("A", v, f, standing(1.0)), ObjectInput("B", v, f, standing(1.15)),
            ObjectInput("C", v, f, standing(4.0))]
    bake = bake_scene(objs, BakeSettings(voxel_density=20))
    a, b, c = bake.instances
    assert a.mesh == b.mesh != c.mesh and len(bake.meshes) == 2
    assert bake.meshes[c.mesh].mips[0].voxel_size == bake.meshes[a.mesh].mips[0].voxel_size / 4


def test_sdf_scale_rounds_to_half_octaves():
    assert sdf_scale(np.eye(4)) == 1.0
    assert sdf_scale(np.diag([1.15, 1.0, 1.0, 1.0])) == 1.0          # largest axis, rounded
    assert sdf_scale(np.diag([6.4, 6.4, 6.4, 1.0])) == 2 ** 2.5
    assert sdf_scale(np.diag([0.0, 0.0, 0.0, 1.0])) == 1.0            # singular: no rescale


def test_open_scan_has_no_cards_for_its_inside():
    """An open-bottomed box's backs face its enclosed inside (capped by the SDF): not surface, so
    the cards are a closed box's six; an open sheet's back stays surface (both its sides)."""
    from lumen_addon import cards as C

    v, f = open_box()
    s, _, _ = C.prepare(v, f, None, None, None, [])
    assert not s.both.any()
    assert len(C.place_cards(s, max_cards=32)) == 6
    quad_v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    quad_f = np.array([[0, 1, 2], [0, 2, 3]])
    s, _, _ = C.prepare(quad_v, quad_f, None, None, None, [])
    assert s.both.all()
