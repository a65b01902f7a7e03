"""Cache round trip, validation of damaged caches, and bad mesh input: clear errors, nothing lost."""
import json
import os

import numpy as np
import pytest

import shapes
from lumen_addon.bake import BakeSettings, ObjectInput, SceneBakeError, bake_scene
from lumen_addon.cache import MANIFEST, CacheError, read_cache, write_cache
from lumen_addon.geometry import MeshError
from lumen_addon.materials import Material
from lumen_addon.sdf import BakeCancelled, bake_mesh_sdf


@pytest.fixture(scope="module")
def scene_bake():
    sv, sf = shapes.icosphere(0.5, 3)
    bv, bf = shapes.box()
    glow = Material(base_color=(0.9, 0.2, 0.1), emission_color=(1, 1, 1), emission_strength=3.0)
    objs = [ObjectInput("Sphere", sv, sf), ObjectInput("Sphere.001", sv, sf, np.diag([1.1, 1.1, 1.1, 1])),
            ObjectInput("Box", bv, bf, two_sided=True, materials=[glow])]
    return bake_scene(objs, BakeSettings(voxel_density=16))


def assert_same(a, b):
    assert a.settings == b.settings
    assert [(i.name, i.mesh) for i in a.instances] == [(i.name, i.mesh) for i in b.instances]
    for x, y in zip(a.instances, b.instances):
        assert np.array_equal(x.matrix_world, y.matrix_world)
    assert a.meshes.keys() == b.meshes.keys()
    for k in a.meshes:
        ma, mb = a.meshes[k], b.meshes[k]
        assert np.array_equal(ma.origin, mb.origin) and ma.two_sided == mb.two_sided
        for la, lb in zip(ma.mips, mb.mips, strict=True):
            assert la.voxel_size == lb.voxel_size and la.resolution == lb.resolution
            assert np.array_equal(la.indirection, lb.indirection)
            assert np.array_equal(la.bricks, lb.bricks)
    assert a.cards.keys() == b.cards.keys() and [i.cards for i in a.instances] == [i.cards for i in b.instances]
    for k in a.cards:
        assert a.cards[k].coverage == b.cards[k].coverage
        for ca, cb in zip(a.cards[k].cards, b.cards[k].cards, strict=True):
            assert (ca.axis, ca.resolution, ca.near, ca.far) == (cb.axis, cb.resolution, cb.near, cb.far)
            assert np.array_equal(ca.rect_min, cb.rect_min) and np.array_equal(ca.rect_max, cb.rect_max)
            for name in ("albedo", "normal", "depth", "emissive", "opacity"):
                assert np.array_equal(getattr(ca, name), getattr(cb, name)), name
    if a.atlas is not None:
        for name, layer in a.atlas.layers.items():
            assert np.array_equal(layer, b.atlas.layers[name])


def test_instances_share_one_bake(scene_bake):
    # Sphere.001 is 1.1x: within bake.sdf_scale's half octave of Sphere, so one SDF for both
    assert len(scene_bake.instances) == 3 and len(scene_bake.meshes) == 2
    assert scene_bake.stats()["unique_meshes"] == 2


def test_round_trip_identical(scene_bake, tmp_path):
    write_cache(tmp_path / "c", scene_bake)
    back = read_cache(tmp_path / "c")
    assert_same(scene_bake, back)
    # Samples from the read-back cache equal the original's.
    k = next(iter(back.meshes))
    p = np.random.default_rng(0).uniform(-0.6, 0.6, (500, 3))
    assert np.array_equal(back.meshes[k].sample(p), scene_bake.meshes[k].sample(p))
    assert json.loads((tmp_path / "c" / MANIFEST).read_text())["stats"]["objects"] == 3


def test_lower_texel_budget_recaptures_cards(scene_bake):
    sv, sf = shapes.icosphere(0.5, 3)
    objs = [ObjectInput("Sphere", sv, sf)]
    first = bake_scene(objs, BakeSettings(voxel_density=16))
    tight = bake_scene(objs, BakeSettings(voxel_density=16, texel_budget=1000), previous=first)
    assert tight.stats()["texels"] <= 1000 < first.stats()["texels"]
    assert any("budget" in msg for _, msg in tight.warnings)
    assert tight.reused == 1            # the SDF is not affected by card settings


def test_rebake_reuses_unchanged_meshes(scene_bake):
    sv, sf = shapes.icosphere(0.5, 3)
    again = bake_scene([ObjectInput("Sphere", sv, sf)], scene_bake.settings, previous=scene_bake)
    assert again.reused == 1
    moved = bake_scene([ObjectInput("Sphere", sv * 1.01, sf)], scene_bake.settings, previous=scene_bake)
    assert moved.reused == 0


def _damaged(tmp_path, scene_bake, damage):
    folder = tmp_path / "c"
    write_cache(folder, scene_bake)
    damage(folder)
    with pytest.raises(CacheError) as err:
        read_cache(folder)
    return str(err.value)


def test_truncated_or_missing_atlas_image(tmp_path, scene_bake):
    def cut(folder):
        exr = next(folder.glob("atlas-normal-*.exr"))
        exr.write_bytes(exr.read_bytes()[:200])
    assert "atlas-normal" in _damaged(tmp_path, scene_bake, cut)

    def gone(folder):
        next(folder.glob("atlas-depth-*.exr")).unlink()
    assert "atlas-depth" in _damaged(tmp_path / "2", scene_bake, gone)


def test_truncated_arrays(tmp_path, scene_bake):
    def cut(folder):
        npz = next(folder.glob("sdf-*.npz"))
        npz.write_bytes(npz.read_bytes()[:1000])
    msg = _damaged(tmp_path, scene_bake, cut)
    assert "sdf-" in msg and "truncated" in msg


def test_other_version(tmp_path, scene_bake):
    def bump(folder):
        m = json.loads((folder / MANIFEST).read_text())
        m["version"] = 99
        (folder / MANIFEST).write_text(json.dumps(m))
    assert "version 99" in _damaged(tmp_path, scene_bake, bump)


def test_not_a_cache(tmp_path):
    (tmp_path / "x").mkdir()
    with pytest.raises(CacheError, match="no cache manifest"):
        read_cache(tmp_path / "x")
    (tmp_path / "x" / MANIFEST).write_text("{not json")
    with pytest.raises(CacheError, match="not a Lumen GI cache"):
        read_cache(tmp_path / "x")
    (tmp_path / "x" / MANIFEST).write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(CacheError, match="not a Lumen GI cache"):
        read_cache(tmp_path / "x")


def test_shape_mismatch_is_caught(tmp_path, scene_bake):
    def lie(folder):
        m = json.loads((folder / MANIFEST).read_text())
        m["meshes"][0]["mips"][0]["bricks_kept"] += 1
        (folder / MANIFEST).write_text(json.dumps(m))
    assert "manifest says" in _damaged(tmp_path, scene_bake, lie)


def test_unwritable_folder_keeps_previous_cache(tmp_path, scene_bake):
    good = tmp_path / "good"
    write_cache(good, scene_bake)
    before = {p.name: p.read_bytes() for p in good.iterdir()}
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(CacheError, match="a_file"):
        write_cache(blocker / "cache", scene_bake)
    assert {p.name: p.read_bytes() for p in good.iterdir()} == before


def test_failed_write_leaves_previous_cache_readable(tmp_path, scene_bake, monkeypatch):
    folder = tmp_path / "c"
    write_cache(folder, scene_bake)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    real = os.replace

    def disk_full(src, dst):      # the manifest rename fails as on a full disk
        if str(dst).endswith(MANIFEST):
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", disk_full)
    sv, sf = shapes.icosphere(0.5, 2)
    other = bake_scene([ObjectInput("Other", sv, sf)], BakeSettings(voxel_density=8))
    with pytest.raises(CacheError, match="No space left"):
        write_cache(folder, other)
    monkeypatch.undo()
    assert_same(scene_bake, read_cache(folder))
    assert {p.name for p in folder.iterdir()} >= set(before)
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("vertices, triangles, message", [
    (np.zeros((3, 3)), np.zeros((0, 3), int), "no faces"),
    (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]), "NaN"),
    (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]]), "degenerate"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 5]]), "out of range"),
    (np.zeros((3, 2)), np.array([[0, 1, 2]]), "shape"),
])
def test_bad_meshes(vertices, triangles, message):
    with pytest.raises(MeshError, match=message):
        bake_mesh_sdf(vertices, triangles)


def test_bad_scene_names_every_bad_object():
    sv, sf = shapes.icosphere(0.5, 1)
    bad = sv.copy()
    bad[0] = np.inf
    with pytest.raises(SceneBakeError) as err:
        bake_scene([ObjectInput("Good", sv, sf), ObjectInput("Broken", bad, sf),
                    ObjectInput("Empty", sv, np.zeros((0, 3), int))])
    names = [n for n, _ in err.value.problems]
    assert names == ["Broken", "Empty"]
    with pytest.raises(SceneBakeError, match="no visible mesh"):
        bake_scene([])


def test_huge_resolution_is_clamped_not_hung():
    v, f = shapes.box()
    b = bake_scene([ObjectInput("Box", v, f, resolution_scale=1e6)], BakeSettings(voxel_density=1e4))
    m = next(iter(b.meshes.values()))
    assert max(m.mips[0].resolution) <= 126
    assert b.warnings and b.warnings[0][0] == "Box" and "clamped" in b.warnings[0][1]
    with pytest.raises(SceneBakeError, match="max resolution"):
        bake_scene([ObjectInput("Box", v, f)], BakeSettings(max_resolution=100000))
    with pytest.raises(SceneBakeError, match="voxel density"):
        bake_scene([ObjectInput("Box", v, f)], BakeSettings(voxel_density=float("nan")))


def test_cancel_from_progress():
    v, f = shapes.icosphere(0.5, 3)

    def stop(fraction, name):
        if fraction > 0.1:
            raise BakeCancelled()

    with pytest.raises(BakeCancelled):
        bake_scene([ObjectInput("S", v, f)], BakeSettings(voxel_density=40), progress=stop)


def test_write_never_touches_files_it_did_not_write(tmp_path, scene_bake):
    """Another tool's manifest is refused (nothing written); in our own cache folder, files that
    merely look like ours (atlas-*, sdf-*.npz) and any other file survive a re-write."""
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    files = {"manifest.json": b'{"tool": "someone else"}', "atlas-wood.png": b"wood",
             "sdf-font.npz": b"font", "notes.txt": b"notes"}
    for name, data in files.items():
        (foreign / name).write_bytes(data)
    with pytest.raises(CacheError, match="not written by Lumen GI"):
        write_cache(foreign, scene_bake)
    assert {p.name: p.read_bytes() for p in foreign.iterdir()} == files

    ours = tmp_path / "ours"
    write_cache(ours, scene_bake)
    first = json.loads((ours / MANIFEST).read_text())
    for name in ("atlas-wood.png", "sdf-font.npz", "notes.txt"):
        (ours / name).write_bytes(b"user file")
    # a different bake replaces our own files only
    sv, sf = shapes.icosphere(0.4, 2)
    other = bake_scene([ObjectInput("Other", sv, sf)], BakeSettings(voxel_density=12))
    write_cache(ours, other)
    for name in ("atlas-wood.png", "sdf-font.npz", "notes.txt"):
        assert (ours / name).read_bytes() == b"user file", name
    assert not (ours / first["sdf"]["file"]).exists(), "our own stale SDF file was kept"
    assert_same(other, read_cache(ours))


def test_crafted_manifest_cannot_direct_the_clean_up(tmp_path, scene_bake):
    """Our manifest format naming a path outside the folder: the clean-up deletes nothing there."""
    folder, victim = tmp_path / "c", tmp_path / "victim.npz"
    victim.write_bytes(b"keep me")
    write_cache(folder, scene_bake)
    m = json.loads((folder / MANIFEST).read_text())
    m["sdf"]["file"] = "../victim.npz"
    (folder / MANIFEST).write_text(json.dumps(m))
    write_cache(folder, scene_bake)
    assert victim.read_bytes() == b"keep me"


def test_cache_files_respect_the_umask(tmp_path, scene_bake):
    old = os.umask(0o022)
    try:
        write_cache(tmp_path / "c", scene_bake)
    finally:
        os.umask(old)
    modes = {p.name: p.stat().st_mode & 0o777 for p in (tmp_path / "c").iterdir()
             if not p.name.startswith(".")}
    assert modes and all(m == 0o644 for m in modes.values()), modes


WRITER = """
import sys
sys.path[:0] = [{root!r}, {core!r}]
import numpy as np
import shapes
from lumen_addon.bake import BakeSettings, ObjectInput, bake_scene
from lumen_addon.cache import write_cache
v, f = shapes.icosphere({radius}, 2)
bake = bake_scene([ObjectInput("W{n}", v, f)], BakeSettings(voxel_density=10))
for _ in range(4):
    write_cache({folder!r}, bake)
"""


def test_concurrent_writers_leave_a_complete_cache(tmp_path):
    """Two processes writing one folder at once (measured before: 5 of 6 trials left a manifest
    naming deleted files): every trial ends with a cache that reads back whole."""
    import subprocess
    import sys
    from pathlib import Path
    root = str(Path(__file__).resolve().parents[2])
    core = str(Path(__file__).resolve().parent)
    for trial in range(3):
        folder = str(tmp_path / f"c{trial}")
        procs = [subprocess.Popen([sys.executable, "-c", WRITER.format(
            root=root, core=core, radius=0.3 + 0.1 * n, n=n, folder=folder)]) for n in range(2)]
        assert [p.wait(timeout=300) for p in procs] == [0, 0]
        bake = read_cache(folder)           # raises CacheError if a named file is missing
        assert len(bake.instances) == 1


def test_loose_nan_vertex_is_ignored_with_a_warning_naming_the_object():
    """A NaN vertex that no face uses failed the bake ("Maximum allowed dimension exceeded", no
    object named); now it is ignored, the bake equals the clean mesh's and a warning names it."""
    v, f = shapes.box()
    loose = np.vstack([v, [[np.nan, 0.0, 0.0], [np.inf, 1.0, 2.0]]])
    bake = bake_scene([ObjectInput("Loose", loose, f)], BakeSettings(voxel_density=10))
    clean = bake_scene([ObjectInput("Clean", v, f)], BakeSettings(voxel_density=10))
    assert bake.warnings == [("Loose", "2 loose vertices (no face uses them) are NaN or infinite: "
                                       "ignored")]
    (a,), (b,) = bake.meshes.values(), clean.meshes.values()
    p = np.random.default_rng(1).uniform(-0.7, 0.7, (400, 3))
    assert np.array_equal(a.sample(p), b.sample(p))
    (ca,), (cb,) = bake.cards.values(), clean.cards.values()
    assert len(ca.cards) == len(cb.cards) and ca.coverage == cb.coverage


def test_objects_under_min_card_size_get_no_cards(tmp_path):
    """With Min Card Size 10 cm a pebble (8 cm) gets no cards and its mesh's cards are never
    captured; the same mesh scaled to 40 cm, an emissive pebble and the default (0) keep theirs; the cache round-trips
    the "no cards" key, and the estimate leaves the pebbles' texels out."""
    from lumen_addon.bake import NO_CARDS
    from lumen_addon.estimate import MeshSize, estimate

    pv, pf = shapes.icosphere(0.04, 1)
    glow = Material(emission_color=(1, 1, 1), emission_strength=2.0)
    objs = [ObjectInput("Pebble", pv, pf), ObjectInput("Pebble.001", pv, pf, shapes.matrix((0.2, 0, 0))),
            ObjectInput("Rock", pv, pf, shapes.matrix((1, 0, 0), scale=5.0)),
            ObjectInput("Ember", pv, pf, shapes.matrix((0, 1, 0)), materials=[glow])]
    bake = bake_scene(objs, BakeSettings(voxel_density=16, min_card_size=0.1))
    cards = {i.name: i.cards for i in bake.instances}
    assert cards["Pebble"] == cards["Pebble.001"] == NO_CARDS
    assert cards["Rock"] != NO_CARDS and cards["Ember"] not in (NO_CARDS, cards["Rock"])
    assert set(bake.cards) == {cards["Rock"], cards["Ember"]}
    write_cache(tmp_path / "c", bake)
    assert_same(bake, read_cache(tmp_path / "c"))
    every = bake_scene(objs[:1], BakeSettings(voxel_density=16))        # the default: 0
    assert every.instances[0].cards != NO_CARDS and len(every.cards) == 1
    small = [MeshSize(triangles=len(pf), extent=(0.08, 0.08, 0.08), world_scale=1.0)]
    assert estimate(small, BakeSettings(min_card_size=0.1)).texels == 0
    assert estimate(small, BakeSettings()).texels > 0
    # an emitter keeps its cards under Min Card Size, in the estimate as in the bake
    ember = [MeshSize(triangles=len(pf), extent=(0.08, 0.08, 0.08), world_scale=1.0, emits=True)]
    assert estimate(ember, BakeSettings(min_card_size=0.1)).texels \
        == estimate(ember, BakeSettings()).texels > 0
