"""Geometry that used to fool the bake, through `lumen.bake` in real Blender (issue 11): a cube
whose faces were all reversed in Edit Mode, and a cube whose vertices sit 1e7 m from its object's
origin. Read back from the cache written to disk."""
from blender_runner import blender  # noqa: F401  (fixture)

SNIPPET = """
import bmesh
from mathutils import Matrix
from lumen_gi.lumen_addon.cache import read_cache
from lumen_gi.lumen_addon.cards import AXES
scene = empty_scene(voxel_density=8.0, cache_dir={cache!r})
flipped = cube("Inside Out", size=1.0)
bm = bmesh.new()
bm.from_mesh(flipped.data)
bmesh.ops.reverse_faces(bm, faces=bm.faces[:])       # Mesh > Normals > Flip
bm.to_mesh(flipped.data)
bm.free()
# Blender's coordinates are float32 (1 m apart at 1e7 m): a 4 m cube keeps its shape there.
far = cube("Far", size=4.0)
far.data.transform(Matrix.Translation((1e7, 0.0, 0.0)))
far.location = (10.0 - 1e7, 0.0, 0.0)
result, error = bake()
back = read_cache({cache!r})
cubes = {{"Inside Out": (np.zeros(3), 0.5), "Far": (np.array([1e7, 0.0, 0.0]), 2.0)}}
out = {{}}
for inst in back.instances:
    m, mc = back.meshes[inst.mesh], back.cards[inst.cards]
    centre, half = cubes[inst.name]
    # Signs against the exact box SDF, where it is more than a voxel from the surface.
    p = np.random.default_rng(0).uniform(-2.0 * half, 2.0 * half, (4000, 3))
    exact = np.linalg.norm(np.maximum(np.abs(p) - half, 0), axis=1) + np.minimum((np.abs(p) - half).max(axis=1), 0)
    sure = np.abs(exact) > m.voxel_size
    wrong = float(np.mean((m.sample(p + centre) < 0)[sure] != (exact < 0)[sure]))
    # Cards look at the outside: near planes outside the cube, normals back at the card.
    front = max(c.near - float(AXES[c.axis] @ centre) for c in mc.cards)
    facing = all(np.allclose(c.normal[c.opacity > 0], -AXES[c.axis], atol=1e-3) for c in mc.cards)
    out[inst.name] = dict(wrong=wrong, front=front + half, cards=len(mc.cards), coverage=mc.coverage,
                          facing=bool(facing))
emit(result=result, error=error, out=out)
"""


def test_inside_out_and_far_from_origin_cubes(blender, tmp_path):
    res = blender(SNIPPET.format(cache=str(tmp_path / "cache")))
    r = res.result
    assert r["result"] == ["FINISHED"] and r["error"] is None, res.explain()
    warnings = [line for line in res.stdout.splitlines() if line.startswith("Warning: ")]
    assert [w for w in warnings if w.startswith("Warning: Inside Out: 12 faces were inside-out")], warnings
    assert not [w for w in warnings if w.startswith("Warning: Far")], warnings
    for name, o in r["out"].items():
        assert o["wrong"] == 0.0, (name, o)
        assert o["cards"] == 6 and o["coverage"] >= 0.99 and o["facing"], (name, o)
        assert o["front"] <= 1e-3, (name, o)      # every card's near plane on or outside a face
