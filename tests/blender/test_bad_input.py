"""Bad scenes and settings through `lumen.bake`: a clear ERROR naming the culprit, no crash,
and the cache written by an earlier good bake stays byte-for-byte as it was."""
import pytest

from blender_runner import blender  # noqa: F401  (fixture)

# Bake a good scene first, keep a fingerprint of its cache, then run the test's `setup` (which
# breaks something) and bake again. The subprocess exiting 0 is the "no crash" check.
TEMPLATE = """
from lumen_gi.lumen_addon.cache import read_cache
scene = empty_scene(cache_dir={cache!r})
box = cube("Box")
good = bake()
before, stats_before = snapshot({cache!r}), scene_stats(scene)
{setup}
result, error = bake()
after = snapshot({cache!r})
back = read_cache({cache!r})
stats_after = scene_stats(scene)
emit(good=good, result=result, error=error, unchanged=before == after,
     stats_kept=all(stats_before[k] == stats_after[k] for k in stats_before if k != "status"),
     status=scene.lumen.last_bake.status, objects=[i.name for i in back.instances],
     mip0=[m.mips[0].resolution for m in back.meshes.values()],
     max_resolution=scene.lumen.bake.max_resolution)
"""


def run_case(blender, tmp_path, setup):
    cache = tmp_path / "cache"
    res = blender(TEMPLATE.format(cache=str(cache), setup=setup))
    r = res.result
    assert r["good"] == [["FINISHED"], None], res.explain()
    return r, res


def assert_refused(r, *words):
    assert r["result"] is None, r        # bpy.ops raised: the operator reported an ERROR
    assert r["error"].startswith("Error: Lumen bake failed"), r["error"]
    for w in words:
        assert w in r["error"], (w, r["error"])
    assert r["unchanged"], "a failed bake touched the previous cache"
    assert r["stats_kept"], "a failed bake changed the stats of the cache on disk"
    assert r["status"].startswith("Bake failed"), r["status"]
    assert r["objects"] == ["Box"]       # the earlier cache still reads back


@pytest.mark.parametrize("setup, words", [
    pytest.param("for o in list(bpy.data.objects): bpy.data.objects.remove(o)",
                 ["no visible mesh objects"], id="empty-scene"),
    pytest.param("set_nan_vertex(cube('NaNCube', location=(3, 0, 0)))", ["NaNCube", "NaN"],
                 id="nan-vertices"),
    pytest.param("flat = cube('Flat', location=(6, 0, 0)); "
                 "flat.data.vertices.foreach_set('co', [0.0] * 24)",
                 ["Flat", "degenerate"], id="all-faces-degenerate"),
    pytest.param("flat = cube('Painted', location=(6, 0, 0)); "
                 "image_texture(mat := principled('Paint'), bpy.data.images.new('t', 4, 4)); "
                 "flat.data.materials.append(mat); "
                 "flat.data.vertices.foreach_set('co', [0.0] * 24)",
                 ["Painted", "degenerate"], id="zero-area-mesh-with-textured-material"),
])
def test_bad_scene_is_refused_and_previous_cache_kept(blender, tmp_path, setup, words):
    r, _ = run_case(blender, tmp_path, setup)
    assert_refused(r, *words)


def test_huge_resolution_request_is_clamped_with_a_warning(blender, tmp_path):
    r, res = run_case(blender, tmp_path, "scene.lumen.bake.voxel_density = 1e9")
    assert r["result"] == ["FINISHED"] and r["error"] is None
    assert "Warning: Box: resolution" in res.stdout and "clamped" in res.stdout
    assert max(max(m) for m in r["mip0"]) <= r["max_resolution"]
    assert r["status"].startswith("Baked 1 objects")


def test_unwritable_cache_folder_is_reported_and_nothing_changes(blender, tmp_path):
    # Runs as root in CI, where chmod does not stop writes: a folder *inside a regular file*
    # cannot be created by anyone.
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    r, _ = run_case(blender, tmp_path, f"scene.lumen.bake.cache_dir = {str(afile / 'cache')!r}")
    assert_refused(r, str(afile / "cache"))
    assert afile.read_text() == "not a folder"


def test_objects_without_faces_are_left_out_and_the_rest_bakes(blender, tmp_path):
    # a vertex-only helper and a geometry-nodes scatter, whose own mesh is empty and whose
    # instances are the surface: the whole bake was refused ("mesh has no faces")
    setup = """
loose_vertices('LooseVerts')
geometry_nodes_scatter('Scatter', keep_plane=False).location = (4, 0, 0)
"""
    r, _ = run_case(blender, tmp_path, setup)
    assert r["result"] == ["FINISHED"] and r["error"] is None, r
    assert "Box" in r["objects"] and "LooseVerts" not in r["objects"], r["objects"]
    scattered = [n for n in r["objects"] if n.startswith("Scatter/")]
    assert len(scattered) == 4, r["objects"]        # one icosphere per corner of the plane
    assert "Scatter" not in r["objects"]
