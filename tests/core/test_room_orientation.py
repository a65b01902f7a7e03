"""A room of single-sided walls facing in (an imported OBJ's room) is a room when the scene is in
it, and an inside-out object when it is empty: bake_scene decides with the other objects' centres
(geometry.orient_triangles inside_points), and the bake key follows that context."""
import numpy as np

import shapes
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene

HALF = (2.0, 1.5, 1.3)


def room():
    v, f = shapes.box(HALF)
    return v, f[:, [0, 2, 1]]                     # every face turned to face into the room


def test_a_room_with_something_in_it_keeps_its_walls_facing_in():
    rv, rf = room()
    bv, bf = shapes.box((0.3, 0.3, 0.3))
    settings = BakeSettings(voxel_density=6.0)
    bake = bake_scene([ObjectInput("Room", rv, rf),
                       ObjectInput("Box", bv, bf, np.diag([1.0, 1.0, 1.0, 1.0]))], settings)
    room_sdf = bake.meshes[next(i.mesh for i in bake.instances if i.name == "Room")]
    inside = np.array([[0.0, 0.0, 0.9], [1.2, -0.8, 0.0], [-1.5, 1.0, -0.8]])
    assert (room_sdf.sample(inside) > 0).all()                  # free space in the room
    assert not any(name == "Room" and "flipped" in note for name, note in bake.warnings)


def test_an_empty_inward_shell_is_an_inside_out_object():
    rv, rf = room()
    bake = bake_scene([ObjectInput("Shell", rv, rf)], BakeSettings(voxel_density=6.0))
    sdf = bake.meshes[bake.instances[0].mesh]
    assert sdf.sample(np.array([[0.0, 0.0, 0.0]]))[0] < 0      # flipped: solid inside
    assert any(name == "Shell" and "flipped" in note for name, note in bake.warnings)


def test_the_bake_key_follows_the_context():
    rv, rf = room()
    bv, bf = shapes.box((0.3, 0.3, 0.3))
    settings = BakeSettings(voxel_density=6.0)
    empty = bake_scene([ObjectInput("Room", rv, rf)], settings)
    furnished = bake_scene([ObjectInput("Room", rv, rf), ObjectInput("Box", bv, bf)], settings,
                           previous=empty)
    assert empty.instances[0].mesh != furnished.instances[0].mesh   # not reused as flipped
